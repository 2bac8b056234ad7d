#include "importers/photos/sensor_database.hpp"

#include <algorithm>
#include <cctype>
#include <map>
#include <sstream>
#include <string_view>
#include <utility>
#include <vector>

namespace strata {
namespace importers {
const std::vector<std::pair<std::string_view, std::string_view>>& sensor_files();
}

namespace {

std::string key(const std::string& s) {
  std::string out;
  bool space = false;
  for (unsigned char c : s) {
    if (std::isspace(c) || c == '\0') {
      space = !out.empty();
      continue;
    }
    if (space) out += ' ';
    space = false;
    out += char(std::tolower(c));
  }
  return out;
}

const std::map<std::string, double>& by_model() {
  static const std::map<std::string, double> table = [] {
    std::map<std::string, double> t;
    for (const auto& [name, text] : importers::sensor_files()) {
      std::istringstream in{std::string(text)};
      std::string line;
      while (std::getline(in, line)) {
        if (line.empty() || line[0] == '#') continue;
        const auto c1 = line.find(','), c2 = line.rfind(',');
        if (c1 == std::string::npos || c2 == c1) continue;
        t[key(line.substr(c1 + 1, c2 - c1 - 1))] = std::stod(line.substr(c2 + 1));
      }
    }
    return t;
  }();
  return table;
}

}  // namespace

std::optional<double> lookup_sensor_width_mm(const std::string& make, const std::string& model) {
  const auto& t = by_model();
  auto it = t.find(key(model));
  if (it != t.end()) return it->second;
  // Some cameras repeat the make in the model, some do not.
  it = t.find(key(make + " " + model));
  if (it != t.end()) return it->second;
  return std::nullopt;
}

}  // namespace strata
