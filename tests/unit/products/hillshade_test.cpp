// The one hillshade of the report and the map tiles against planes whose shading is
// known in closed form.
#include "products/hillshade.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace strata {
namespace {

// float shades of closed-form values.
constexpr float kShadeTol = 1e-5f;

struct Plane {
  int w = 5, h = 4;
  std::vector<float> z;
  std::vector<std::uint8_t> valid;
  // z = a * east + b * north, cells of 0.5 m; row 0 is the northern one.
  Plane(double a, double b) : z(std::size_t(w * h)), valid(std::size_t(w * h), 1) {
    for (int r = 0; r < h; ++r)
      for (int c = 0; c < w; ++c) z[std::size_t(r * w + c)] = float(a * 0.5 * c + b * 0.5 * (h - 1 - r));
  }
  std::vector<float> shade() const { return hillshade({w, h, 0.5, 0.5, z.data(), valid.data()}); }
};

TEST(Hillshade, LevelGroundIsLitAtTheSunsAltitude) {
  const Plane p(0, 0);
  for (float v : p.shade()) EXPECT_NEAR(v, std::sin(45 * std::numbers::pi / 180), kShadeTol);
}

TEST(Hillshade, ASlopeFacingTheSunIsFullyLitAndOneFacingAwayIsDark) {
  // The sun at azimuth 315, altitude 45: direction (-0.5, 0.5, 0.7071). A plane whose
  // normal is that direction rises to the south-east with slope 1 along (1,-1)/sqrt(2).
  const double k = 0.5 / 0.7071067811865476;
  const Plane facing(k, -k);
  const auto lit = facing.shade();
  EXPECT_NEAR(lit[7], 1.0f, kShadeTol) << "an interior cell";
  EXPECT_FALSE(std::isnan(lit[0])) << "a corner is shaded too, its own height standing in for the missing neighbours";
  const Plane away(-3, 3);  // steep, rising to the north-west: its normal points away from the sun
  EXPECT_NEAR(away.shade()[7], 0.0f, kShadeTol);
}

TEST(Hillshade, ACellWithoutHeightHasNoShade) {
  Plane p(0.2, 0.1);
  p.valid[7] = 0;
  const auto s = p.shade();
  EXPECT_TRUE(std::isnan(s[7]));
  EXPECT_FALSE(std::isnan(s[6])) << "its neighbour is shaded with its own height in its place";
}

}  // namespace
}  // namespace strata
