#pragma once
// Plain data passed from the features stage to structure from motion.
// No OpenCV types here: sfm/ and later stages include this header.
#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace strata {

// Keypoints of one image, in pixels of the ORIGINAL (full-size, distorted) photo,
// (0,0) = centre of the top-left pixel. Descriptors live in the features cache.
struct ImageKeypoints {
  std::string image;                       // image name (unique within a layer)
  std::vector<Eigen::Vector2d> points;     // pixels
  std::vector<float> scales;               // keypoint size in pixels (optional, may be empty)
  std::vector<std::uint8_t> colours;       // RGB triplets per keypoint (optional, may be empty)
};

enum class TwoViewModel { none, essential, fundamental, homography };

// Geometrically verified correspondences between two images of one layer.
struct PairMatches {
  int image_a = -1;  // index into the layer's image list
  int image_b = -1;
  std::vector<std::pair<int, int>> matches;  // keypoint index in a, in b (inliers only)
  TwoViewModel model = TwoViewModel::none;
};

// A coded target (ArUco / AprilTag) found in one image.
struct TargetDetection {
  int id = -1;                          // dictionary id
  Eigen::Vector2d centre;               // pixels, sub-pixel, original photo
  std::vector<Eigen::Vector2d> corners; // 4 corners, pixels
};

}  // namespace strata
