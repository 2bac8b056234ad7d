#pragma once
// A simulated hand-held depth camera (RGB-D) sequence of each recorded surface
// (internal to strata_synthetic; docs/range.md, "Synthetic depth sequences").
//
// The camera is carried once round the trench just outside its edge, looking down
// into it, with a hand's wobble in position and aim. Each pixel's ray is cast
// against the same height field the photos are rendered from (render.hpp cast_ray),
// its depth along the optical axis gets Gaussian noise of sigma = k z^2 (structured
// light and stereo depth cameras: Khoshelham & Elberink 2012) and is quantised to
// whole millimetres as the 16-bit PNG stores it. Beside the true poses, the poses a
// device's own tracking would record: the true relative motion from frame to frame
// with a small error composed at every step, a random walk that drifts.
#include "synthetic/scene.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <vector>

namespace strata::synthetic {

// Camera -> site frame, x_site = pose * x_camera; camera axes x right, y down, z
// forward (the convention of geometry/camera.hpp).
struct DepthFramePlan {
  Eigen::Isometry3d true_pose = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d recorded_pose = Eigen::Isometry3d::Identity();  // with the tracking's drift
};

// `options.depth.frames` poses along one loop round the trench (the last frame just
// short of the first, so the sequence closes on itself). Deterministic for a seed.
std::vector<DepthFramePlan> plan_depth_sequence(const Scene& scene, int layer, std::uint64_t seed);

struct DepthFrame {
  std::vector<std::uint16_t> depth_mm;  // row-major width x height, 0 = no return
  std::vector<std::uint8_t> rgb;        // row-major, 3 bytes a pixel, sRGB (unlit albedo, the marker prints on it)
  std::int64_t valid = 0;               // pixels with a depth
};

// Renders one frame from `pose` (camera -> site frame). Deterministic for a seed,
// whatever the thread count.
DepthFrame render_depth_frame(const Scene& scene, int layer, const Eigen::Isometry3d& pose, std::uint64_t seed);

}  // namespace strata::synthetic
