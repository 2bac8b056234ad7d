#pragma once
// Test fixture: narrow-band level sets (.vdb, grid "surface", as the dense stage
// writes it) of analytic ground, site frame: below a height field z = h(x, y), or
// any solid given by its signed distance (an overhang, a cave).
#include <Eigen/Core>

#include <filesystem>
#include <functional>

namespace strata::test {

// Signed distance approximated by z - h(x, y) (exact for flat ground, within
// (1 - cos slope) elsewhere), clamped to +-truncation; active voxels in
// [x0, x1] x [y0, y1] where |z - h| < truncation.
void write_height_field_level_set(const std::filesystem::path& vdb, const std::function<double(double, double)>& h,
                                  double x0, double y0, double x1, double y1, double voxel_m, double truncation_m,
                                  const Eigen::Vector3d& site_origin);

// The ground where sdf(x, y, z) < 0 (> 0 in the air), sampled at every voxel of the
// box [lo, hi]; active (observed) where |sdf| < truncation, as fusion leaves it.
void write_level_set(const std::filesystem::path& vdb, const std::function<double(double, double, double)>& sdf,
                     const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, double voxel_m, double truncation_m,
                     const Eigen::Vector3d& site_origin);

}  // namespace strata::test
