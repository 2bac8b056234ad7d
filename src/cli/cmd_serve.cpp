// strata serve: the field station (src/server).
#include "cli/commands.hpp"
#include "server/server.hpp"

#include <memory>
#include <string>

namespace strata::cli {

void register_serve_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "serve",
      "the field station: serve the project's pages and JSON API to a browser (a phone, a tablet,\n"
      "a laptop) at the trench edge. Units, relations and the Harris matrix; layers, their photos\n"
      "uploaded from the browser, processing followed live and its verdict; markers; finds.\n"
      "The same controllers as the command line do the work, under the same project lock: a\n"
      "writer that meets another (a 'strata process' in a terminal) is told who holds it.\n"
      "Answers only on the loopback address until the project has accounts. Ctrl-C stops it;\n"
      "a running job is stopped (its step rolled back) and resumed at the next start.\n"
      "docs/field_station.md says how to use it, docs/api.md what the API offers.");
  auto dir = std::make_shared<std::string>();
  auto options = std::make_shared<ServeOptions>();
  auto role = std::make_shared<std::string>("director");
  auto upload_mb = std::make_shared<std::size_t>(options->max_upload_bytes >> 20);
  cmd->add_option("DIR", *dir, "project folder")->required();
  cmd->add_option("--listen", options->listen,
                  "HOST:PORT to answer on (default 127.0.0.1:8720; port 0: any free port, printed)");
  cmd->add_flag("--open", options->open_browser, "open the site page in this machine's browser");
  cmd->add_option("--max-upload-mb", *upload_mb, "largest photo an upload may carry, MB (default 256)")
      ->check(CLI::Range(1, 4096));
  cmd->add_option("--http-threads", options->threads,
                  "requests served at once; each page following a job's progress holds one (default 32)")
      ->check(CLI::Range(4, 1024));
  cmd->add_option("--role", *role,
                  "what every caller may do until the project has accounts: director (default: all), "
                  "supervisor (process, no accounts), recorder (add photos, units, relations, finds) or "
                  "viewer (read only: a screen shown to visitors)")
      ->check(CLI::IsMember({"viewer", "recorder", "supervisor", "director"}));
  cmd->footer("Example: strata serve site --open");
  cmd->callback([=] {
    ServeOptions o = *options;
    o.max_upload_bytes = *upload_mb << 20;
    o.role = parse_role(*role);
    serve(*dir, o);
  });
}

}  // namespace strata::cli
