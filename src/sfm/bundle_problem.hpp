#pragma once
// Internal to sfm/ (and georef/ through bundle_adjust): the flat parameter layout that
// the Ceres solve works on. Both the incremental mapper (local and global BA) and
// bundle_adjust() on a Reconstruction fill one of these.
#include "sfm/bundle_adjustment.hpp"
#include "sfm/cost_functions.hpp"

#include <Eigen/Core>

#include <array>
#include <vector>

namespace strata::sfm_detail {

using IntrinsicsBlock = std::array<double, kIntrinsicsSize>;

struct BaCamera {
  std::array<double, kPoseSize> pose{};  // {angle-axis world -> camera, t in metres}
  int group = 0;
  bool variable = true;  // false: held constant (a neighbour in a local adjustment)
};

struct BaObservation {
  int camera = -1;
  int point = -1;
  Eigen::Vector2d pixel;
  bool marker = false;  // weighed with marker_sigma_px instead of keypoint_sigma_px
  double sigma_px = 0;  // pixels, > 0: this observation's own sigma (markers)
};

struct BaPrior {
  int point = -1;
  Eigen::Vector3d position;  // metres
  Eigen::Vector3d sigma;     // metres per axis
};

struct BaProblem {
  std::vector<IntrinsicsBlock> intrinsics;  // per camera group
  std::vector<CameraModel> models;          // per camera group: the lens model of the block
  std::vector<char> intrinsics_fixed;       // per camera group: a known, fixed calibration
  std::vector<BaCamera> cameras;
  std::vector<Eigen::Vector3d> points;
  std::vector<char> point_variable;  // per point
  std::vector<BaObservation> observations;
  std::vector<BaPrior> priors;
  bool refine_intrinsics = true;  // master switch, combined with options.refine
  // Datum of an unreferenced problem: this camera's pose is fixed and one
  // translation component of the second camera (which changes with scale) too.
  int gauge_camera = -1;
  int gauge_scale_camera = -1;
  int gauge_scale_axis = 0;
};

IntrinsicsBlock to_block(const Intrinsics& k);
// Appends one camera group (its block, lens model and fixed flag) to the problem.
void add_group(BaProblem& problem, const Intrinsics& k, bool calibration_fixed);
// The block entries an adjustment holds constant for this model and refinement:
// those the model does not have, and those `refine` leaves out. Sorted.
std::vector<int> constant_intrinsics(const IntrinsicsRefinement& refine, CameraModel model);
void from_block(const IntrinsicsBlock& b, Intrinsics& k);
std::array<double, kPoseSize> to_block(const Pose& pose);
Pose pose_from_block(const std::array<double, kPoseSize>& b);

// Chooses the gauge of an unreferenced problem from two variable cameras a, b:
// the translation component of b that changes most under a scaling about a's centre.
void set_gauge(BaProblem& problem, int a, int b);

// Solves in place. Observations whose point or camera is constant and that touch no
// variable block are skipped.
BundleSummary solve_bundle(const BundleOptions& options, BaProblem& problem);

// Keypoint reprojection error of one observation, pixels.
double reprojection_error_px(const BaProblem& problem, const BaObservation& obs);

}  // namespace strata::sfm_detail
