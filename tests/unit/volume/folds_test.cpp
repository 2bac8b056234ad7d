// The solids checked against the voxel model where height fields fold
// (check_folds): a square pit with vertical walls, with and without a cave
// undercut into one wall. A height field cannot see the cave (the lip above it
// hides it); the layer's level set can. The level sets are written here as a
// fused surface.vdb would be: signed distances (> 0 in the air) clamped to the
// truncation, active (observed) only within the narrow band.
#include "core/error.hpp"
#include "dense/dense.hpp"
#include "support/level_set_fixture.hpp"
#include "volume/volume.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>

namespace strata {
namespace {

namespace fs = std::filesystem;

// A 1.2 x 1.2 m grid of 1 cm cells; voxels of 5 mm with a band of 4 voxels, as
// the fusion's defaults give at this ground sampling.
constexpr double kCell = 0.01;
constexpr int kN = 120;
constexpr double kVoxel = 0.005;
constexpr double kTrunc = 4 * kVoxel;

// The pit: x, y in [0.4, 0.8], 0.2 m deep from the flat ground z = 0. The cave:
// under the east wall, about 3 cm in and 3 cm high at the pit's floor, along the wall.
constexpr double kPit0 = 0.4, kPit1 = 0.8, kPitDepth = 0.2;
constexpr double kCaveIn = 0.0325, kCaveHigh = 0.0285;  // off the voxel lattice

// Signed distance to an axis-aligned box, > 0 outside.
double box_distance(double x, double y, double z, const double lo[3], const double hi[3]) {
  const double p[3] = {x, y, z};
  double outside = 0, inside = -1e9;
  for (int a = 0; a < 3; ++a) {
    const double d = std::max(lo[a] - p[a], p[a] - hi[a]);
    outside += std::max(d, 0.0) * std::max(d, 0.0);
    inside = std::max(inside, d);
  }
  return outside > 0 ? std::sqrt(outside) : inside;
}

// The ground after the pit (and the cave) were dug: > 0 in the air.
double dug_ground(double x, double y, double z, bool cave) {
  const double pit_lo[3] = {kPit0, kPit0, -kPitDepth}, pit_hi[3] = {kPit1, kPit1, 1.0};
  const double cave_lo[3] = {kPit1 - 0.05, kPit0, -kPitDepth}, cave_hi[3] = {kPit1 + kCaveIn, kPit1, -kPitDepth + kCaveHigh};
  double air = box_distance(x, y, z, pit_lo, pit_hi);
  if (cave) air = std::min(air, box_distance(x, y, z, cave_lo, cave_hi));
  return std::max(z, -air);
}

void write_ground(const fs::path& path, const std::function<double(double, double, double)>& sdf) {
  const double side = kN * kCell;
  test::write_level_set(path, sdf, {-0.01, -0.01, -0.3}, {side + 0.01, side + 0.01, 0.06}, kVoxel, kTrunc,
                        Eigen::Vector3d::Zero());
}

// Height fields as the DTM of each level set gives them (the uppermost ground).
LayerSurface layer(const std::string& name, const std::string& unit, const fs::path& vdb) {
  LayerSurface l;
  l.layer = name;
  l.unit = unit;
  l.z = sample_top_surface(vdb, RasterGrid::from_south_west_centre(0.5 * kCell, 0.5 * kCell, kCell, kN, kN));
  l.z.sigma.assign(l.z.z.size(), 0.001);
  l.noise_m = 0.001;
  return l;
}

struct Checked {
  UnitMeasures measures;
  double height_field_m3 = 0;  // the solid before the check
};

Checked run(bool cave, const fs::path& dir) {
  fs::create_directories(dir);
  const fs::path top = dir / "L1.vdb", bottom = dir / "L2.vdb";
  write_ground(top, [](double, double, double z) { return z; });
  write_ground(bottom, [cave](double x, double y, double z) { return dug_ground(x, y, z, cave); });
  const std::vector<LayerSurface> layers{layer("L1", "A", top), layer("L2", "B", bottom)};
  const VolumeOptions options;
  std::vector<UnitSolid> solids = build_unit_solids(layers, options);
  EXPECT_EQ(solids.size(), 1u);
  if (solids.empty()) return {};
  Checked out;
  out.height_field_m3 = solids[0].measures.volume_m3;
  check_folds(solids, layers, {{"L1", top}, {"L2", bottom}}, options);
  out.measures = solids[0].measures;
  const UnitMeasures& m = out.measures;
  std::printf("%s: height fields %.6f m3, after the check %.6f m3; fold area %.3f m2, difference %+.6f m3, "
              "interval [%.6f, %.6f]\n",
              cave ? "cave" : "no cave", out.height_field_m3, m.volume_m3, m.fold_area_m2, m.fold_difference_m3(),
              m.interval_low_m3, m.interval_high_m3);
  return out;
}

const double kPitVolume = (kPit1 - kPit0) * (kPit1 - kPit0) * kPitDepth;  // 0.032 m3
const double kCaveVolume = kCaveIn * (kPit1 - kPit0) * kCaveHigh;           // 0.000371 m3

TEST(VolumeFolds, AVerticalWalledPitIsLeftAsTheHeightFieldsSay) {
  const Checked c = run(false, fs::path(testing::TempDir()) / "folds_plain");
  const UnitMeasures& m = c.measures;
  ASSERT_TRUE(m.fold_checked);
  EXPECT_NEAR(c.height_field_m3, kPitVolume, 0.002 * kPitVolume);
  // The walls and a band around them were checked, the floor's middle was not.
  EXPECT_GT(m.fold_area_m2, 4 * (kPit1 - kPit0) * 0.05);
  EXPECT_LT(m.fold_area_m2, (kPit1 - kPit0 + 0.2) * (kPit1 - kPit0 + 0.2));
  // Nothing folds: the voxel model agrees within a tenth of the cave below.
  EXPECT_LT(std::abs(m.fold_difference_m3()), 0.1 * kCaveVolume);
  EXPECT_NEAR(m.volume_m3, kPitVolume, 0.002 * kPitVolume);
}

TEST(VolumeFolds, ACaveUnderAWallIsAddedFromTheVoxelModel) {
  const Checked c = run(true, fs::path(testing::TempDir()) / "folds_cave");
  const UnitMeasures& m = c.measures;
  ASSERT_TRUE(m.fold_checked);
  // The height fields miss the cave: the lip above it is flat ground to them.
  EXPECT_NEAR(c.height_field_m3, kPitVolume, 0.002 * kPitVolume);
  // The voxel model finds it, to a tenth of its volume.
  EXPECT_NEAR(m.fold_difference_m3(), kCaveVolume, 0.1 * kCaveVolume);
  EXPECT_NEAR(m.volume_m3, kPitVolume + kCaveVolume, 0.1 * kCaveVolume);
  EXPECT_NEAR(m.fold_sigma_m3, 0.5 * std::abs(m.fold_difference_m3()), 1e-12);
  // The interval holds the truth and says where the doubt lies.
  EXPECT_LE(m.interval_low_m3, kPitVolume + kCaveVolume);
  EXPECT_GE(m.interval_high_m3, kPitVolume + kCaveVolume);
  EXPECT_GE(m.volume_sigma_m3, m.fold_sigma_m3);
}

TEST(VolumeFolds, ALayerWithoutAVoxelModelIsLeftUnchecked) {
  const fs::path dir = fs::path(testing::TempDir()) / "folds_raster";
  fs::create_directories(dir);
  const fs::path top = dir / "L1.vdb", bottom = dir / "L2.vdb";
  write_ground(top, [](double, double, double z) { return z; });
  write_ground(bottom, [](double x, double y, double z) { return dug_ground(x, y, z, true); });
  const std::vector<LayerSurface> layers{layer("L1", "A", top), layer("L2", "B", bottom)};
  std::vector<UnitSolid> solids = build_unit_solids(layers, VolumeOptions{});
  ASSERT_EQ(solids.size(), 1u);
  const double before = solids[0].measures.volume_m3;
  check_folds(solids, layers, {{"L1", top}}, VolumeOptions{});  // L2 came as a raster
  EXPECT_FALSE(solids[0].measures.fold_checked);
  EXPECT_EQ(solids[0].measures.volume_m3, before);
}

TEST(VolumeFolds, BadFoldOptionsAreRefused) {
  VolumeOptions o;
  o.fold_slope_deg = 90;
  EXPECT_THROW(o.validate(), InputError);
  o = VolumeOptions{};
  o.fold_reach_m = -0.01;
  EXPECT_THROW(o.validate(), InputError);
}

}  // namespace
}  // namespace strata
