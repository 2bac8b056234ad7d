#include "products/hillshade.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <numbers>

namespace strata {

std::vector<float> hillshade(const HeightGrid& g) {
  constexpr double kAzimuth = 315 * std::numbers::pi / 180, kAltitude = 45 * std::numbers::pi / 180;
  const double sun_e = std::cos(kAltitude) * std::sin(kAzimuth), sun_n = std::cos(kAltitude) * std::cos(kAzimuth),
               sun_up = std::sin(kAltitude);
  const auto at = [&](int row, int col) { return std::size_t(row) * std::size_t(g.width) + std::size_t(col); };
  std::vector<float> shade(std::size_t(std::max(0, g.width)) * std::size_t(std::max(0, g.height)), NAN);
  for (int row = 0; row < g.height; ++row) {
    for (int col = 0; col < g.width; ++col) {
      if (!g.valid[at(row, col)]) continue;
      const double centre = g.z[at(row, col)];
      const auto z = [&](int r, int c) {
        if (r < 0 || c < 0 || r >= g.height || c >= g.width || !g.valid[at(r, c)]) return centre;
        return double(g.z[at(r, c)]);
      };
      // Horn: a b c / d e f / g h i, the first row the northern one.
      const double a = z(row - 1, col - 1), b = z(row - 1, col), c = z(row - 1, col + 1);
      const double d = z(row, col - 1), f = z(row, col + 1);
      const double gg = z(row + 1, col - 1), h = z(row + 1, col), i = z(row + 1, col + 1);
      const double dz_de = ((c + 2 * f + i) - (a + 2 * d + gg)) / (8 * g.cell_e);
      const double dz_dn = ((a + 2 * b + c) - (gg + 2 * h + i)) / (8 * g.cell_n);
      const double norm = std::sqrt(dz_de * dz_de + dz_dn * dz_dn + 1);
      shade[at(row, col)] = float(std::max(0.0, (-dz_de * sun_e - dz_dn * sun_n + sun_up) / norm));
    }
  }
  return shade;
}

}  // namespace strata
