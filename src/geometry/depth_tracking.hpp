#pragma once
// Registration of a hand-held depth camera's frames (docs/range.md, "Registration of
// depth sequences"), Eigen only:
//
// 1. Frame to model (as KinectFusion, Newcombe et al. 2011, with the point-to-plane
//    ICP of geometry/icp.hpp in place of its projective association): the first
//    frame keeps the pose it is given (the device's recorded one, or the identity:
//    it fixes the sequence's frame); every later frame starts from the previous
//    frame's registered pose moved by a step (the motion measured by the colour
//    frames' features, or the one the device recorded; else the previous step again),
//    and is fitted to the model of every frame registered before it (their points,
//    thinned, with normals; geometry/icp.hpp GrowingModel). A fit from the step that
//    did not converge or kept much less of the frame within the gate than the last
//    frames' fits did is not trusted: constant velocity and no motion are tried too.
// 2. Loop closure: the last frame is fitted to the model of the first frames alone
//    (the sequence ends where it began). The correction it needs is the drift
//    accumulated round the loop; it is spread along the sequence in proportion to
//    the frame's index (the drift of tracking grows with the path), as a rigid
//    motion about the camera path's centroid.
// 3. Re-registration: every frame is fitted again to the model of all frames, a
//    fixed number of rounds, each round from the poses of the previous one.
#include "geometry/icp.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <optional>
#include <vector>

namespace strata {

struct DepthTrackingOptions {
  double model_voxel_m = 0.015;    // metres: the model thinned to one point a cube (the frames come thinned)
  double normal_radius_m = 0.045;  // metres: neighbours of a model normal (3 model voxels)
  double loop_share = 0.15;        // the loop is closed on the model of this first share of the frames
  int min_loop_frames = 3;         // and of at least this many
  double min_loop_inlier_share = 0.30;  // the last frame's fit on them must keep this share, else no loop
  int refine_rounds = 2;           // rounds of re-registration against the model of all frames (0..10)
  // ICP for depth frames: their noise (k z^2: 3-9 mm at 1.5-2.5 m) sets the Huber
  // threshold and the smallest gate, about one to two sigmas.
  IcpOptions icp = [] {
    IcpOptions o;
    o.max_correspondence_m = 0.10;
    o.min_correspondence_m = 0.02;
    o.huber_m = 0.01;
    return o;
  }();
  void validate() const;  // throws InputError naming the field
};

// What a frame's tracking fit started from: the step given, the previous step again
// (constant velocity) or no motion.
enum class TrackingStart { none, step, constant_velocity, no_motion };

struct DepthTrackingSummary {
  std::vector<Eigen::Isometry3d> tracked;  // camera -> site frame after frame-to-model tracking
  std::vector<TrackingStart> started;      // each frame's (frame 0: none)
  std::vector<IcpSummary> tracking_fit;    // the fit of each frame while tracking (frame 0: none, identity)
  bool loop_closed = false;
  IcpSummary loop_fit;                     // the last frame on the first frames' model
  int loop_frames = 0;                     // frames in that model
  double loop_correction_m = 0;            // how far the correction moved the last camera, metres
  double loop_correction_rad = 0;          // and turned it, radians
  std::vector<Eigen::Isometry3d> poses;    // camera -> site frame, final (after loop closure and rounds)
  std::vector<IcpSummary> fit;             // each frame's fit in the last round (tracking_fit without rounds)
};

// `frames[i]`: frame i's points in its camera frame (metres, thinned); `first`: frame
// 0's pose (camera -> the sequence's frame); `steps[i]`, i >= 1: the motion of frame i
// relative to frame i - 1 (camera i -> camera i - 1) that starts its fit, or empty for
// the constant-velocity guess (the step before it again; frame 1: no motion);
// `steps[0]` is not used. At least 2 frames.
DepthTrackingSummary track_depth_sequence(const std::vector<std::vector<Eigen::Vector3d>>& frames,
                                          const Eigen::Isometry3d& first,
                                          const std::vector<std::optional<Eigen::Isometry3d>>& steps,
                                          const DepthTrackingOptions& options);

// The same started from the device's recorded poses (camera -> site frame): frame 0
// at recorded[0], the steps between consecutive recorded poses.
DepthTrackingSummary track_depth_sequence(const std::vector<std::vector<Eigen::Vector3d>>& frames,
                                          const std::vector<Eigen::Isometry3d>& recorded,
                                          const DepthTrackingOptions& options);

}  // namespace strata
