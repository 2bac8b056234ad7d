// strata: the command-line front end. Thin by design: parse, validate, call the
// library, map errors to exit codes.
#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "core/error.hpp"
#include "core/log.hpp"
#include "core/progress.hpp"
#include "core/resources.hpp"
#include "core/signals.hpp"

#include <fmt/format.h>

#include <cstdio>
#include <filesystem>
#include <new>

int main(int argc, char** argv) {
  CLI::App app{
      "strata: photographs of each excavated layer -> a georeferenced, measured,\n"
      "volumetric record of the excavation.\n\n"
      "A project is a folder: project.gpkg (the database, opens in QGIS), media/\n"
      "(original photos, never modified), cache/ and products/.\n\n"
      "Typical session:\n"
      "  strata init site --crs EPSG:32636\n"
      "  strata unit add site 101 --type deposit\n"
      "  strata relation add site 101 above 102\n"
      "  strata layer add site L101 --unit 101\n"
      "  strata import photos site --layer L101 photos/*.jpg\n"
      "  strata import markers site survey.csv\n"
      "  strata info site\n"
      "  strata serve site --open           (the same from a browser: the field station)\n",
      "strata"};
  app.set_version_flag("--version", "strata 0.1.0");
  app.require_subcommand(1);
  bool quiet = false, verbose = false;
  int threads = 0;
  double wait_s = 0;
  app.add_flag("-q,--quiet", quiet, "only warnings and errors on stderr");
  app.add_flag("-v,--verbose", verbose, "debug messages on stderr");
  app.add_option("--threads", threads,
                 "most threads to run at once, 0 = every core (default); fewer keep a field laptop "
                 "responsive. The sparse result does not depend on it (tests/integration/threads_test.cpp)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--wait", wait_s,
                 "when another strata command is changing the project, wait up to this many seconds for "
                 "it to end instead of stopping at once (default 0). Reading commands never wait")
      ->check(CLI::NonNegativeNumber);
  strata::cli::set_invocation(argc, argv);
  app.parse_complete_callback([&] {
    strata::cli::set_lock_wait(wait_s);
    if (quiet) strata::log::set_level(strata::log::Level::warning);
    if (verbose) strata::log::set_level(strata::log::Level::debug);
    strata::set_thread_limit(threads);
  });

  strata::cli::register_project_commands(app);
  strata::cli::register_stratigraphy_commands(app);
  strata::cli::register_import_commands(app);
  strata::cli::register_camera_commands(app);
  strata::cli::register_synth_command(app);
  strata::cli::register_registration_commands(app);
  strata::cli::register_process_commands(app);
  strata::cli::register_export_commands(app);
  strata::cli::register_products_commands(app);
  strata::cli::register_volume_commands(app);
  strata::cli::register_finds_command(app);
  strata::cli::register_report_command(app);
  strata::cli::register_serve_command(app);
  strata::cli::guard_paths(app);

  strata::install_cancel_handler();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const strata::Cancelled& e) {
    fmt::print(stderr, "strata: {}; the project is unchanged by the interrupted step\n", e.what());
    return 130;
  } catch (const strata::Error& e) {
    fmt::print(stderr, "strata: error: {}\n", e.what());
    return 1;
  } catch (const std::filesystem::filesystem_error& e) {
    // A path that the checks at the door could not foresee (a folder removed or
    // made unreadable meanwhile): a fault of the surroundings, said in one line.
    fmt::print(stderr, "strata: error: {}: {}\n", e.path1().string(), e.code().message());
    return 1;
  } catch (const std::bad_alloc&) {
    fmt::print(stderr,
               "strata: error: out of memory: the command asked for more memory than this machine gives it; the "
               "project is unchanged (a smaller --cell, --step or --voxel-size asks for more)\n");
    return 1;
  } catch (const std::exception& e) {
    fmt::print(stderr, "strata: internal error: {}\n", e.what());
    return 70;
  }
  return 0;
}
