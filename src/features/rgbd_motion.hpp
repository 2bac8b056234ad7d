#pragma once
// The motion of a hand-held RGB-D camera between two frames from its colour images
// (docs/range.md, "Registration of depth sequences"), as Almeida et al. and the RGB-D
// mapping systems start their tracking (Henry et al. 2012, Endres et al. 2014): ORB
// features (Rublee et al. 2011) in each colour frame, matched by Hamming distance
// with Lowe's ratio test and a cross-check, each keypoint lifted to 3D through its
// depth frame and the pinhole intrinsics, and a rigid motion fitted by SVD (Umeyama)
// inside RANSAC with a gate from the depth noise k z^2, then least squares on the
// inliers (geometry/similarity.hpp fit_rigid_ransac). No OpenCV types here.
#include "geometry/similarity.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <filesystem>
#include <vector>

namespace strata {

// A depth camera with its colour frames registered to the depth pixels.
struct RgbdCamera {
  int width = 0, height = 0;  // pixels
  double fx = 0, fy = 0;      // pixels
  double cx = 0, cy = 0;      // pixels; (0, 0) the centre of the top-left pixel
  double depth_scale_m = 0.001;  // metres per unit of the depth image
  double noise_k = 0.0015;       // 1/m: one sigma of a depth is noise_k z^2
};

struct RgbdFeatureOptions {
  // ORB keypoints kept per frame (strongest first). 5000 rather than 2000: across a
  // corner turned between two frames few match (the synthetic 24-frame wide loop's
  // 53-degree corner: 4 pairs agreeing, wrongly, of 195 mutual matches at 2000; 17 of
  // 398 at 5000; docs/range.md, "Depth sequences, measured").
  int max_features = 5000;
  int fast_threshold = 10;        // ORB's FAST threshold, grey levels: soil is low in contrast (OpenCV: 20)
  double ratio = 0.8;             // Lowe's ratio test on the two nearest Hamming distances
  double pixel_sigma = 1.0;       // pixels: a keypoint's position, one sigma, at the finest pyramid level
  double max_depth_m = 3.0;       // metres: farther keypoints are left out (noise k z^2 past 1 cm)
  double max_depth_step_m = 0.03; // metres: a keypoint whose 3 x 3 depths span more sits on an edge
  double gate_sigmas = 3.0;       // a match is an inlier within this many sigmas of both points' noise
  int min_inliers = 20;           // fewer: no motion (a blurred, dark or textureless frame)
  RigidRansacOptions ransac;
  void validate() const;  // throws InputError naming the field
};

// One frame's keypoints that have a depth.
struct RgbdFeatures {
  std::vector<Eigen::Vector2d> pixels;      // pixels, (0, 0) the top-left pixel's centre
  std::vector<Eigen::Vector3d> points;      // camera frame (x right, y down, z forward), metres
  std::vector<double> sigma_m;              // each point's noise, one sigma, metres
  std::vector<std::uint8_t> descriptors;    // 32 bytes a keypoint (ORB), in the order of points
  int keypoints = 0;                        // detected, with or without a depth
};

// `grey`: the colour frame in 8-bit grey, row-major width x height; `depth`: the depth
// frame's values (x depth_scale_m metres; 0 = none), the same pixels.
RgbdFeatures extract_rgbd_features(const std::vector<std::uint8_t>& grey, const std::vector<std::uint16_t>& depth,
                                   const RgbdCamera& camera, const RgbdFeatureOptions& options);

// A colour PNG (grey, RGB or RGBA, 8 bits) as 8-bit grey. Throws IoError naming the
// file when it cannot be read, InputError when its size is not width x height.
std::vector<std::uint8_t> read_grey_frame(const std::filesystem::path& file, int width, int height);

struct RgbdMotion {
  bool found = false;
  Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();  // frame b's camera -> frame a's camera
  int matches = 0;   // after the ratio test and the cross-check
  int inliers = 0;   // of the final fit
  double rms_m = 0;  // 3D residual RMS of the inliers, metres
};

// The motion of frame b relative to frame a; `found` is false with fewer than
// min_inliers matches agreeing on one rigid motion.
RgbdMotion rgbd_relative_motion(const RgbdFeatures& a, const RgbdFeatures& b, const RgbdFeatureOptions& options);

}  // namespace strata
