// Finds in place against an analytic label model: which unit's solid holds each
// point, its distance to the recorded unit's solid, and the conflict rule; the
// shell search checked against a brute-force scan of every voxel.
#include "volume/finds.hpp"

#include "core/error.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

namespace strata {
namespace {

// Distances are sums of a few centimetre-scale terms in double: far below this.
constexpr double kDistanceTol = 1e-9;  // metres

const Eigen::Vector3d kOrigin(734000, 4174000, 1450);

// 40^3 voxels of 1 cm from the site frame's origin: unit 101 (label 7) above
// z = 0.2 m, unit 102 (label 9) below it where x < 0.3 m, nothing elsewhere.
// Unit 103 (label 11) is known but has no voxel.
LabelVolume model() {
  LabelVolume v;
  v.voxel_size_m = 0.01;
  v.min_centre = Eigen::Vector3d::Constant(0.005);
  v.nx = v.ny = v.nz = 40;
  v.site_origin = kOrigin;
  v.crs = "EPSG:32636";
  v.units = {{7, "101"}, {9, "102"}, {11, "103"}};
  v.labels.assign(std::size_t(v.nx) * v.ny * v.nz, 0);
  for (int k = 0; k < v.nz; ++k)
    for (int j = 0; j < v.ny; ++j)
      for (int i = 0; i < v.nx; ++i)
        v.labels[(std::size_t(k) * v.ny + j) * v.nx + i] = k >= 20 ? 7 : i < 30 ? 9 : 0;
  return v;
}

FindRecord find(const std::string& id, const std::string& unit, const Eigen::Vector3d& site_frame) {
  FindRecord f;
  f.id = id;
  f.unit = unit;
  f.position = kOrigin + site_frame;
  return f;
}

TEST(FindPlacement, GeometricUnitDistanceAndConflict) {
  const std::vector<FindRecord> finds = {
      find("inside", "101", {0.1, 0.1, 0.3}),         // in its recorded unit
      find("below", "101", {0.1, 0.1, 0.15}),         // 5 cm down in 102
      find("at_boundary", "101", {0.1, 0.1, 0.195}),  // 5 mm down in 102: within tolerance
      find("beside", "102", {0.35, 0.1, 0.1}),        // in no solid, 5 cm from 102
      find("above", "101", {0.1, 0.1, 0.5}),          // 10 cm above the model
      find("no_solid_in_101", "103", {0.1, 0.1, 0.3}),
      find("no_solid_anywhere", "103", {0.35, 0.1, 0.1}),
  };
  const FindsCheck c = place_finds(model(), finds, {});
  EXPECT_NEAR(c.tolerance_m, 0.01 + kFindSurveyError, 1e-15);  // one voxel + survey error
  ASSERT_EQ(c.finds.size(), finds.size());
  auto expect = [&](std::size_t i, std::optional<std::string> geometric, std::optional<double> distance, bool conflict) {
    const FindPlacement& p = c.finds[i];
    EXPECT_EQ(p.geometric_unit, geometric) << p.find.id;
    ASSERT_EQ(p.distance_m.has_value(), distance.has_value()) << p.find.id;
    if (distance) {
      EXPECT_NEAR(*p.distance_m, *distance, kDistanceTol) << p.find.id;
    }
    EXPECT_EQ(p.conflict, conflict) << p.find.id;
  };
  expect(0, "101", 0.0, false);
  expect(1, "102", 0.05, true);
  expect(2, "102", 0.005, false);
  expect(3, std::nullopt, 0.05, true);
  expect(4, std::nullopt, 0.5 - 0.4, true);
  // A recorded unit without a solid is contradicted only by a point in another's.
  expect(5, "101", std::nullopt, true);
  expect(6, std::nullopt, std::nullopt, false);
  EXPECT_EQ(c.conflicts(), 4);

  FindCheckOptions wide;
  wide.tolerance_m = 0.06;
  const FindsCheck w = place_finds(model(), finds, wide);
  EXPECT_FALSE(w.finds[1].conflict);
  EXPECT_FALSE(w.finds[3].conflict);
  EXPECT_TRUE(w.finds[4].conflict);
  FindCheckOptions bad;
  bad.tolerance_m = -1;
  EXPECT_THROW(place_finds(model(), finds, bad), InputError);
}

TEST(FindPlacement, ShellSearchAgreesWithABruteForceScan) {
  const LabelVolume v = model();
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> coord(-0.2, 0.6);  // inside and around the block
  for (int n = 0; n < 200; ++n) {
    const Eigen::Vector3d p(coord(rng), coord(rng), coord(rng));
    for (const auto& [label, unit] : std::map<std::int32_t, std::string>{{7, "101"}, {9, "102"}}) {
      double brute = std::numeric_limits<double>::infinity();
      for (int k = 0; k < v.nz; ++k)
        for (int j = 0; j < v.ny; ++j)
          for (int i = 0; i < v.nx; ++i) {
            if (v.at(i, j, k) != label) continue;
            double d2 = 0;
            for (int a = 0; a < 3; ++a) {
              const double c = v.min_centre[a] + v.voxel_size_m * (a == 0 ? i : a == 1 ? j : k);
              const double d = std::max(std::abs(p[a] - c) - 0.5 * v.voxel_size_m, 0.0);
              d2 += d * d;
            }
            brute = std::min(brute, std::sqrt(d2));
          }
      const FindsCheck c = place_finds(v, {find("p", unit, p)}, {});
      ASSERT_TRUE(c.finds[0].distance_m);
      EXPECT_NEAR(*c.finds[0].distance_m, brute, kDistanceTol) << unit << " at " << p.transpose();
    }
  }
}

}  // namespace
}  // namespace strata
