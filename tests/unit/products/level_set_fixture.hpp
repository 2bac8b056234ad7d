#pragma once
// Test fixture: a narrow-band level set (.vdb, grid "surface", as the dense stage
// writes it) of the region below an analytic height field z = h(x, y), site frame.
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

}  // namespace strata::test
