#include "cli/common.hpp"

#include "core/door.hpp"
#include "core/error.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <optional>
#include <sstream>

namespace strata::cli {
namespace {

std::vector<std::string> invocation;  // argv without the program's path
double lock_wait_s = 0;               // --wait

}  // namespace

void set_invocation(int argc, char** argv) { invocation.assign(argv + std::min(argc, 1), argv + argc); }
void set_lock_wait(double seconds) { lock_wait_s = seconds; }

ProjectLock lock_project(const std::string& dir) {
  ProjectLockOptions o;
  o.wait_s = lock_wait_s;
  o.command = "strata";
  for (const auto& arg : invocation) {
    if (arg == dir) continue;  // the folder is the lock's own place
    o.command += arg.find_first_of(" \t'\"") == std::string::npos ? " " + arg : " '" + arg + "'";
  }
  return ProjectLock(dir, o);
}

namespace {

enum class PathKind { project, new_project, input_file, input_folder, output_file, output_folder, output_either, named_file };

// The kind of path an option takes, from its name (see common.hpp); nullopt: not a path.
std::optional<PathKind> path_kind(const CLI::App& command, const CLI::Option& option) {
  const std::string name = option.get_name().empty() ? option.get_name(true, false) : option.get_name();
  const std::string help = option.get_description();
  if (name == "DIR") return command.get_name() == "init" || command.get_name() == "synth" ? PathKind::new_project : PathKind::project;
  if (name == "FILE" || name == "FRAME") return PathKind::input_file;
  if (name == "OUT") return PathKind::output_folder;
  if (name == "--out") {
    if (help.rfind("output folder", 0) == 0) return PathKind::output_folder;
    return help.find("or folder") != std::string::npos ? PathKind::output_either : PathKind::output_file;
  }
  if (name == "--outline" || name == "--check-outline" || name == "--intrinsics" || name == "--targets")
    return PathKind::input_file;
  if (name == "--colour") return PathKind::input_folder;
  if (name == "--surface" || name == "--footprint") return PathKind::named_file;
  return std::nullopt;
}

void check_path(PathKind kind, const std::string& option, const std::string& value) {
  switch (kind) {
    case PathKind::project: door::input_folder(value, "project folder"); break;
    case PathKind::new_project: door::output_folder(value, "project folder"); break;
    case PathKind::input_file: door::input_file(value, option); break;
    case PathKind::input_folder: door::input_folder(value, option); break;
    case PathKind::output_file: door::output_file(value, option); break;
    case PathKind::output_folder: door::output_folder(value, option); break;
    case PathKind::output_either: {
      std::error_code ec;
      if (std::filesystem::is_directory(value, ec)) door::output_folder(value, option);
      else door::output_file(value, option);
      break;
    }
    case PathKind::named_file: {
      const auto eq = value.find('=');
      if (eq == std::string::npos || eq == 0 || eq + 1 == value.size())
        throw InputError(fmt::format("{}: '{}' is not NAME=FILE", option, value));
      door::input_file(value.substr(eq + 1), fmt::format("{} of {}", option, value.substr(0, eq)));
      break;
    }
  }
}

}  // namespace

void guard_paths(CLI::App& app) {
  for (CLI::App* command : app.get_subcommands([](CLI::App*) { return true; })) {
    for (CLI::Option* option : command->get_options()) {
      const auto kind = path_kind(*command, *option);
      if (!kind) continue;
      // A positional is named by its help ("finds CSV"), an option by its flag.
      std::string shown = option->get_name();
      if (shown.empty() || shown == option->get_name(true, false)) {
        shown = option->get_description().substr(0, option->get_description().find(" ("));
      }
      option->check(CLI::Validator(
          [kind, shown](std::string& value) {
            check_path(*kind, shown, value);
            return std::string();
          },
          "", "door"));
    }
    guard_paths(*command);
  }
}

std::vector<double> parse_numbers(const std::string& text, std::size_t count, const std::string& option) {
  std::vector<double> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    char* end = nullptr;
    const double v = std::strtod(item.c_str(), &end);
    if (item.empty() || *end != '\0' || !std::isfinite(v)) {
      throw InputError(fmt::format("{}: '{}' is not a number (in '{}')", option, item, text));
    }
    out.push_back(v);
  }
  if (out.size() != count) {
    throw InputError(fmt::format("{}: expected {} comma-separated numbers, got '{}'", option, count, text));
  }
  return out;
}

Eigen::Vector3d parse_vector3(const std::string& text, const std::string& option) {
  const auto v = parse_numbers(text, 3, option);
  return {v[0], v[1], v[2]};
}

}  // namespace strata::cli
