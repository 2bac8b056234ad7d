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
  // Key of this image's entry in the features cache (photo SHA-256 + options
  // fingerprint); matching finds the descriptors by it. Empty for keypoints that
  // did not come from extract_features().
  std::string features_key;
};

enum class TwoViewModel { none, essential, fundamental, homography };

// Geometrically verified correspondences between two images of one layer.
struct PairMatches {
  int image_a = -1;  // index into the layer's image list
  int image_b = -1;
  std::vector<std::pair<int, int>> matches;  // keypoint index in a, in b (inliers only)
  TwoViewModel model = TwoViewModel::none;
  // How many of the verified matches a single homography also explains (same
  // threshold). A ratio homography_inliers / matches.size() near 1 means a planar
  // scene or a pure rotation: a poor initial pair for SfM. 0 when not computed.
  int homography_inliers = 0;
};

// A coded target (ArUco / AprilTag) found in one image.
struct TargetDetection {
  int id = -1;                          // dictionary id
  Eigen::Vector2d centre;               // pixels, sub-pixel, original photo
  std::vector<Eigen::Vector2d> corners; // 4 corners, pixels
};

}  // namespace strata
