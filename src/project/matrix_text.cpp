#include "project/matrix_text.hpp"

#include "core/error.hpp"

#include <fmt/format.h>

#include <sstream>

namespace strata {

std::string matrix_text(const Eigen::Matrix4d& m) {
  std::string out;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) out += fmt::format("{}{:.17g}", out.empty() ? "" : " ", m(r, c));
  return out;
}

Eigen::Matrix4d parse_matrix_text(const std::string& text, const std::string& what) {
  std::istringstream in(text);
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c)
      if (!(in >> m(r, c))) throw IoError(fmt::format("{} is damaged: '{}'", what, text));
  return m;
}

}  // namespace strata
