#include "cli/common.hpp"

#include "core/error.hpp"

#include <cmath>
#include <cstdlib>
#include <sstream>

namespace strata::cli {

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
