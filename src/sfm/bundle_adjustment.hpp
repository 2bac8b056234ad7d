#pragma once
// Bundle adjustment with self-calibration and surveyed marker constraints (Ceres,
// behind this header: only Eigen and the plain structs of reconstruction.hpp here).
//
// Minimises, over camera poses, shared intrinsics of each CameraGroup, sparse points
// and control-marker positions,
//   sum_obs rho(|pi(cam, X) - x|^2 / s_kp^2)            keypoint reprojections
// + sum_mobs rho(|pi(cam, M) - m|^2 / s_m^2)            marker reprojections
// + sum_control sum_axis ((M_a - S_a) / sigma_a)^2       survey priors
// (Triggs et al. 2000, "Bundle adjustment, a modern synthesis"; the marker terms make
// it a combined adjustment of photos and survey, as in classical aerotriangulation).
// Check markers never enter the cost.
#include "features/types.hpp"
#include "geometry/reconstruction.hpp"

#include <cstddef>
#include <string>
#include <vector>

namespace strata {

enum class RobustLoss { none, huber, cauchy };

// Which intrinsics are estimated; the others stay at their current values.
// One focal f is estimated with fy = f * aspect, aspect fixed at the group's
// initial fy/fx unless `aspect_ratio` is set. A coefficient is estimated only when
// the group's lens model has it (geometry/camera.hpp):
//   radial   f, pp, k1, k2
//   brown    f, pp, k1, k2, k3, p1, p2
//   fisheye  f, pp, k1, k2, k3, k4
struct IntrinsicsRefinement {
  bool focal = true;
  bool principal_point = true;
  bool k1 = true;
  bool k2 = true;
  bool aspect_ratio = false;
  bool k3 = true;          // brown, fisheye
  bool k4 = true;          // fisheye
  bool tangential = true;  // p1, p2 (brown)
};

struct BundleOptions {
  RobustLoss loss = RobustLoss::cauchy;  // on keypoint reprojections
  // pixels: reprojection residuals beyond about this size are down-weighted.
  double loss_scale_px = 1.0;
  // On marker reprojections. None by default: a robust loss would let a marker whose
  // survey disagrees with the photos detach from its rays (the loss flattens) instead
  // of weighing survey and photos by their sigmas; the per-marker residual table is
  // where a wrong click shows.
  RobustLoss marker_loss = RobustLoss::none;
  // pixels: standard deviation of a keypoint position; weighs the reprojection
  // residuals against the marker priors (which are in metres / sigma).
  double keypoint_sigma_px = 1.0;
  // pixels: standard deviation of a marker observation (coded-target centre or a
  // hand-placed click).
  double marker_sigma_px = 1.0;
  IntrinsicsRefinement refine;
  int max_iterations = 100;
  // Ceres convergence tolerances (relative, unitless).
  double function_tolerance = 1e-8;
  double gradient_tolerance = 1e-12;
  double parameter_tolerance = 1e-8;
  // No thread count: the adjustment runs on one thread so that its sums, and so the
  // products, are the same bit for bit on every run (bundle_adjustment.cpp).

  // Throws InputError naming the first invalid field.
  void validate() const;
};

struct BundleSummary {
  int iterations = 0;
  bool converged = false;          // Ceres reported convergence (not just "usable")
  double initial_cost = 0;         // Ceres cost (1/2 sum of squared weighted residuals)
  double final_cost = 0;
  double rmse_px = 0;              // keypoint reprojection RMSE after the adjustment
  std::size_t observations = 0;    // keypoint observations in the problem
  std::size_t marker_observations = 0;
  std::size_t control_markers = 0; // markers with a survey prior in the problem
  bool gauge_fixed = false;        // true when no control markers fix the datum
  double seconds = 0;
  std::string message;             // Ceres' one-line report
};

// Adjusts every registered image, every point and the intrinsics of each group in
// place. Control markers that are seen in at least one registered image enter with
// their survey prior; check markers are ignored. Without any control marker the
// datum is fixed (first registered pose, plus one translation component of a second
// image for the scale). Reconstruction::georeferenced is left unchanged.
// `keypoints[i]` belongs to rec.images[i].
BundleSummary bundle_adjust(const BundleOptions& options, Reconstruction& rec,
                            const std::vector<ImageKeypoints>& keypoints,
                            const std::vector<MarkerConstraint>& markers = {},
                            const std::vector<MarkerObservation>& observations = {});

}  // namespace strata
