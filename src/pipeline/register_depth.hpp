#pragma once
// The registration controller of RGB-D depth sequences (docs/range.md, "Registration
// of depth sequences"): each sequence of a layer read from media/, its frames
// back-projected and thinned, tracked frame to model from the poses the device
// recorded, closed on its first frames and re-registered against the model of all
// its frames (geometry/depth_tracking.hpp). Every frame is fitted and checked before
// anything is written; then all are stored in one transaction, or none.
#include "geometry/depth_tracking.hpp"
#include "project/depth_records.hpp"
#include "project/project.hpp"

#include <optional>
#include <string>
#include <vector>

namespace strata {

struct DepthRegistrationOptions {
  std::optional<std::string> sequence;  // one sequence by name; default every sequence of the layer
  double frame_voxel_m = 0.015;   // metres: each frame thinned to one point a cube, in its camera frame
  double max_depth_m = 3.0;       // metres: farther pixels are left out of the registration (noise k z^2
                                  // grows past 1 cm there); the fusion still uses them, weighted down
  // Refusals, per frame, of the last fit: the share of its thinned points kept as
  // inliers, and the inliers' RMS over the noise expected at the frame's median depth
  // (k z^2, times sqrt(2): the model is made of such points too).
  double min_inlier_share = 0.30;
  double max_rms_ratio = 3.0;
  DepthTrackingOptions tracking;
  void validate() const;  // throws InputError naming the field
};

struct DepthFrameResult {
  DepthFrameRecord frame;                                     // as stored after the registration
  Eigen::Matrix4d recorded = Eigen::Matrix4d::Identity();     // the device's pose
  Eigen::Matrix4d tracked = Eigen::Matrix4d::Identity();      // after frame-to-model tracking
  Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();         // final: camera -> site frame
  IcpSummary fit;                                             // the last fit of the frame
  double median_depth_m = 0;
  std::size_t points_used = 0;                                // thinned
};

struct DepthSequenceResult {
  DepthSequenceRecord sequence;
  std::vector<DepthFrameResult> frames;
  bool loop_closed = false;
  int loop_frames = 0;
  double loop_inlier_share = 0;
  double loop_correction_m = 0;
  double loop_correction_rad = 0;
  double seconds = 0;
};

struct DepthRegistrationSummary {
  std::string layer;
  std::vector<DepthSequenceResult> sequences;
};

// Registers the layer's depth sequences (or options.sequence) and stores every frame's
// pose, box and fit. Throws InputError, the database unchanged, when the layer has no
// sequence, a sequence has no recorded poses, or any frame's fit fails its checks
// (the message names the frame and what to do).
DepthRegistrationSummary register_layer_depth(Project& project, const std::string& layer,
                                              const DepthRegistrationOptions& options);

}  // namespace strata
