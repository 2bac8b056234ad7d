#pragma once
// A synthetic layer with known truth for the sfm and georef tests (COLMAP's
// SynthesizeDataset in spirit): a gently rough ground of about 4 x 3 m, cameras
// 1.6-2.4 m above it looking down and oblique with varied roll, keypoints projected
// with the true (off-centre, distorted) intrinsics plus Gaussian noise, verified
// pair matches with a fraction of wrong matches, and surveyed markers.
#include "features/types.hpp"
#include "geometry/reconstruction.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace strata::test {

struct SceneMarker {
  std::string name;
  Eigen::Vector2d en;  // metres, site frame; the height comes from the ground
  bool control = true;
};

struct SceneOptions {
  int cameras = 16;
  int points = 2000;
  double noise_px = 0.3;          // pixels, standard deviation per axis
  double outlier_fraction = 0.03; // wrong matches added per pair, fraction of its matches
  double focal_prior_error = 0.03;  // relative error of the EXIF focal prior
  double marker_noise_px = 0.2;   // pixels
  unsigned seed = 7;
  // The true lens: radial (a mild barrel), brown (a wide DSLR zoom: strong barrel,
  // decentring) or fisheye (an action camera, about 150 degrees across the diagonal).
  CameraModel lens = CameraModel::radial;
  std::vector<SceneMarker> markers = {
      {"C1", {-1.5, -1.1}, true}, {"C2", {1.6, -1.0}, true}, {"C3", {0.2, 1.2}, true},
      {"C4", {-1.3, 1.0}, true},  {"K1", {0.1, -0.1}, false}, {"K2", {1.1, 0.6}, false}};
};

struct SyntheticScene {
  Intrinsics truth;                       // true intrinsics of the single camera
  std::vector<Pose> poses;                // true poses, site frame
  std::vector<Eigen::Vector3d> points;    // true points, site frame
  std::vector<CameraGroup> groups;        // the initial guess given to SfM
  std::vector<ImageInput> images;
  std::vector<ImageKeypoints> keypoints;
  std::vector<std::vector<int>> point_of_keypoint;  // [image][keypoint] -> true point
  std::vector<PairMatches> matches;
  std::vector<MarkerConstraint> markers;  // true positions, sigma 2 mm
  std::vector<MarkerObservation> marker_observations;

  std::vector<Eigen::Vector3d> centres() const;
  // The truth as a Reconstruction (tracks from the keypoints of each true point).
  Reconstruction truth_reconstruction() const;
};

double ground_height(double e, double n);  // metres
SyntheticScene make_scene(const SceneOptions& options);

}  // namespace strata::test
