#pragma once
// Points an instrument measured in its own frame, named like the surveyed markers (a
// scanner's targets; the marker centres a depth sequence saw), placed on the markers
// (docs/range.md, "On surveyed targets"): a similarity fitted robustly to the pairs
// (geometry/similarity.hpp fit_similarity_robust: blunders left out), its scale
// checked against 1 (the instrument measures in metres), then the rigid motion fitted
// to the inliers. Internal to the pipeline: register_scans and register_depth.
#include "project/project.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace strata {

struct NamedPoint {
  std::string name;       // the marker it measures
  Eigen::Vector3d local;  // metres, the instrument's frame
};

// The points paired with the surveyed markers of the same name (site frame); names
// without a marker go to `unmatched`.
struct MarkerPairs {
  std::vector<std::string> names;
  std::vector<Eigen::Vector3d> local, site;
  double largest_marker_sigma_m = 0;
  std::vector<std::string> unmatched;
};
MarkerPairs pair_with_markers(Project& project, const std::vector<NamedPoint>& points);

struct MarkerFitOptions {
  double point_sigma_m = 0.002;   // metres: a measured point, one sigma
  // A pair is an inlier within gate_sigmas x sqrt(point sigma^2 + the largest marker
  // sigma^2 of the pairs), and never less than min_gate_m.
  double gate_sigmas = 3.0;
  double min_gate_m = 0.005;
  // A fitted scale further from 1 than this means other units or mismatched names.
  double max_scale_error = 0.005;
};

struct TargetResidual {
  std::string name;
  double residual_m = 0;  // |pose(local) - surveyed|, metres
  bool inlier = false;
};

struct MarkerFit {
  Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();  // instrument frame -> site frame
  double scale = 1;                                    // of the robust similarity: a check; the pose is rigid
  double gate_m = 0;
  double rms_m = 0;                                    // over the inliers
  std::size_t inliers = 0;
  std::vector<TargetResidual> targets;                 // every pair, in order
  // First-order pose sigmas from the inliers' RMS: translation rms / sqrt(n) at their
  // centroid, rotation rms / sqrt(sum of squared distances to it).
  double sigma_translation_m = 0;
  double sigma_rotation_rad = 0;
};

// At least 3 pairs. Throws InputError when no 3 pairs agree or the scale is off; the
// messages start with `subject` ("register.scan: S1.ply") and name `source` ("the
// targets of S1.csv") and end "Nothing was changed".
MarkerFit fit_on_markers(const MarkerPairs& pairs, const MarkerFitOptions& options, const std::string& subject,
                         const std::string& source);

}  // namespace strata
