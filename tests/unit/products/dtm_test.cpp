// DTM from a level set of a known analytic surface.
#include "support/level_set_fixture.hpp"
#include "products/dtm.hpp"
#include "support/test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

namespace strata {
namespace {

const Eigen::Vector3d kOrigin(734000.0, 4174000.0, 1450.0);
constexpr double kVoxel = 0.005;        // metres, level-set voxel
constexpr double kCell = 0.01;          // metres, DTM cell
// Trilinear zero crossing of a 5 mm level set of a gently curved surface: a
// fraction of a millimetre; 1 mm leaves room for the z - h distance approximation.
constexpr double kMedianTolerance = 0.001;  // metres
constexpr double kMaxTolerance = 0.003;     // metres

double analytic(double x, double y) { return 0.08 * std::sin(2.0 * x) * std::cos(1.5 * y) + 0.02 * x; }

TEST(Dtm, FromLevelSetOfAnalyticSurface) {
  test::ScratchDir dir("products_dtm_levelset");
  const auto vdb = dir / "surface.vdb";
  test::write_height_field_level_set(vdb, analytic, -0.6, -0.4, 0.6, 0.4, kVoxel, 4 * kVoxel, kOrigin);
  DtmOptions o;
  o.cell_m = kCell;
  const Dtm dtm = build_dtm(vdb, o);
  // Grid edges on whole cells of the site frame.
  EXPECT_NEAR(std::remainder(dtm.grid.x_min, kCell), 0.0, 1e-9);
  EXPECT_NEAR(std::remainder(dtm.grid.y_max, kCell), 0.0, 1e-9);
  EXPECT_LE(dtm.grid.x_min, -0.6 + 1e-9);
  EXPECT_GE(dtm.grid.x_max(), 0.6 - 1e-9);
  std::vector<double> err;
  for (int r = 0; r < dtm.grid.height; ++r) {
    for (int c = 0; c < dtm.grid.width; ++c) {
      if (!dtm.valid(c, r)) continue;
      err.push_back(std::abs(dtm.at(c, r) - analytic(dtm.grid.x_centre(c), dtm.grid.y_centre(r))));
    }
  }
  ASSERT_GT(err.size(), std::size_t(0.8 * 120 * 80));  // nearly all cells of the 1.2 x 0.8 m box
  std::sort(err.begin(), err.end());
  EXPECT_LT(err[err.size() / 2], kMedianTolerance);
  EXPECT_LT(err.back(), kMaxTolerance);
  // North-up: the first row is the northern edge (y_max), heights follow y.
  const int c = dtm.grid.width / 2;
  EXPECT_NEAR(dtm.at(c, 5), analytic(dtm.grid.x_centre(c), dtm.grid.y_centre(5)), kMaxTolerance);
}

TEST(Dtm, Statistics) {
  Dtm d;
  d.grid = {0, 1, 0.5, 2, 2};
  d.z = {1.f, 2.f, std::nanf(""), 3.f};
  const DtmStatistics s = dtm_statistics(d, 100.0);
  EXPECT_EQ(s.valid_cells, 3u);
  EXPECT_DOUBLE_EQ(s.min, 101.0);
  EXPECT_DOUBLE_EQ(s.max, 103.0);
  EXPECT_DOUBLE_EQ(s.mean, 102.0);
  EXPECT_DOUBLE_EQ(s.area_m2, 0.75);
}

}  // namespace
}  // namespace strata
