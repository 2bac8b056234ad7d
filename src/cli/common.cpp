#include "cli/common.hpp"

#include "core/error.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
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
