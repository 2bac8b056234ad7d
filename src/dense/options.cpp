// Validation of DenseOptions, once, before any work (Ceres Options::IsValid style).
#include "core/error.hpp"
#include "dense/dense.hpp"

#include <fmt/format.h>

#include <cmath>
#include <string_view>

namespace strata {
namespace {

void require(bool ok, std::string_view field, std::string_view why) {
  if (!ok) throw InputError(fmt::format("dense options: {} {}", field, why));
}

}  // namespace

double PatchMatchOptions::smoothing_m(double gsd_m) const {
  return (2 * window_radius + 1) * gsd_m / std::sqrt(12.0);
}

void DenseOptions::validate() const {
  require(views.max_neighbours >= 1 && views.max_neighbours <= 16, "views.max_neighbours",
          "must be in [1, 16]");
  require(views.min_shared_points >= 1, "views.min_shared_points", "must be at least 1");
  require(views.min_angle_deg >= 0 && views.min_angle_deg < views.max_angle_deg &&
              views.max_angle_deg <= 90,
          "views.min_angle_deg/max_angle_deg", "must satisfy 0 <= min < max <= 90 degrees");
  require(views.reference_cover >= 0 && views.reference_cover <= 16, "views.reference_cover",
          "must be in [0, 16] (0 = every image with source views)");

  const double s = patch_match.scale;
  require(s == 0 || s == 1.0 || s == 0.5 || s == 0.25, "patch_match.scale",
          "must be 1, 0.5, 0.25 or 0 (from patch_match.target_gsd_m)");
  require(patch_match.target_gsd_m > 0 && std::isfinite(patch_match.target_gsd_m),
          "patch_match.target_gsd_m", "must be positive metres");
  require(patch_match.window_radius >= 1 && patch_match.window_radius <= 15,
          "patch_match.window_radius", "must be in [1, 15] pixels");
  require(patch_match.window_step >= 1 && patch_match.window_step <= patch_match.window_radius,
          "patch_match.window_step", "must be in [1, window_radius]");
  require(patch_match.bilateral_sigma_colour >= 0 && patch_match.bilateral_sigma_colour <= 10,
          "patch_match.bilateral_sigma_colour", "must be in [0, 10] (0 = plain NCC)");
  require(patch_match.iterations >= 1 && patch_match.iterations <= 20, "patch_match.iterations",
          "must be in [1, 20]");
  require(patch_match.fine_iterations >= 1 && patch_match.fine_iterations <= patch_match.iterations,
          "patch_match.fine_iterations", "must be in [1, iterations]");
  require(patch_match.best_k >= 1 && patch_match.best_k <= views.max_neighbours,
          "patch_match.best_k", "must be in [1, views.max_neighbours]");
  require(patch_match.max_cost > 0 && patch_match.max_cost <= 2, "patch_match.max_cost",
          "must be in (0, 2]");
  require(patch_match.depth_margin >= 0 && patch_match.depth_margin <= 2,
          "patch_match.depth_margin", "must be in [0, 2]");
  require(patch_match.max_normal_angle_deg > 0 && patch_match.max_normal_angle_deg < 90,
          "patch_match.max_normal_angle_deg", "must be in (0, 90) degrees");

  require(consistency.min_consistent_views >= 0, "consistency.min_consistent_views",
          "must be >= 0");
  require(consistency.max_reprojection_px > 0, "consistency.max_reprojection_px",
          "must be positive");
  require(consistency.max_relative_depth > 0 && consistency.max_relative_depth < 1,
          "consistency.max_relative_depth", "must be in (0, 1)");
  require(consistency.max_free_space_violations >= 0, "consistency.max_free_space_violations",
          "must be >= 0 (0 = no free-space test)");
  require(consistency.free_space_margin > 0 && consistency.free_space_margin < 1,
          "consistency.free_space_margin", "must be in (0, 1)");

  require(fusion.voxel_size_m >= 0 && std::isfinite(fusion.voxel_size_m), "fusion.voxel_size_m",
          "must be >= 0 metres (0 = from the GSD)");
  require(fusion.voxel_gsd_factor > 0, "fusion.voxel_gsd_factor", "must be positive");
  require(fusion.min_voxel_size_m > 0 && fusion.min_voxel_size_m <= fusion.max_voxel_size_m,
          "fusion.min_voxel_size_m/max_voxel_size_m", "must satisfy 0 < min <= max metres");
  require(fusion.truncation_voxels >= 2 && fusion.truncation_voxels <= 20,
          "fusion.truncation_voxels", "must be in [2, 20] voxels");
  require(fusion.min_weight >= 0, "fusion.min_weight", "must be >= 0");
  require(fusion.min_component_fraction >= 0 && fusion.min_component_fraction < 1,
          "fusion.min_component_fraction", "must be in [0, 1)");

  require(fusion.photo_depth_sigma_gsd > 0 && std::isfinite(fusion.photo_depth_sigma_gsd),
          "fusion.photo_depth_sigma_gsd", "must be positive (depth-map GSDs)");

  require(mesh.adaptivity >= 0 && mesh.adaptivity <= 1, "mesh.adaptivity", "must be in [0, 1]");
  require(mesh.min_point_weight >= 0 && std::isfinite(mesh.min_point_weight), "mesh.min_point_weight",
          "must be >= 0");
  require(mesh.min_point_observations >= 0 && std::isfinite(mesh.min_point_observations),
          "mesh.min_point_observations", "must be >= 0");
  require(quality.cell_size_m > 0, "quality.cell_size_m", "must be positive metres");
  require(quality.area.empty() || quality.area.size() >= 3, "quality.area",
          "must be empty or a polygon of at least 3 vertices");
  require(threads >= 1 && threads <= 256, "threads", "must be in [1, 256]");
}

}  // namespace strata
