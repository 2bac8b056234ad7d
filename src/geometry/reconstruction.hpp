#pragma once
// The plain result of aligning one layer (OpenMVG SfM_Data / COLMAP Reconstruction
// in spirit): calibrated camera groups, posed images and sparse points.
// Coordinates: site frame (metres) once georeferenced, otherwise an arbitrary
// local frame (see `georeferenced`).
#include "geometry/camera.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace strata {

// Photos of one physical camera at one focal setting share intrinsics
// (self-calibrated together).
struct CameraGroup {
  Intrinsics intrinsics;
  bool focal_from_exif = false;  // prior focal known from EXIF + sensor width
  // A known calibration (strata camera set, an imported calibration file, or another
  // layer's): the intrinsics start from it; `calibration_fixed` holds them constant in
  // every adjustment.
  bool calibration_known = false;
  bool calibration_fixed = false;
  // Where the lens model and the starting intrinsics came from, for the quality report
  // (e.g. "default", "exif", "option", "calibration").
  std::string calibration_source = "default";
};

struct ImageInput {
  std::string name;
  int group = 0;  // index into the camera groups
};

struct RegisteredImage {
  std::string name;
  int group = 0;
  bool registered = false;
  Pose pose;  // valid when registered
};

struct TrackElement {
  int image = -1;     // index into images
  int keypoint = -1;  // index into that image's keypoints
};

struct SparsePoint {
  Eigen::Vector3d X;                    // metres, reconstruction frame
  std::vector<TrackElement> track;
  Eigen::Matrix<std::uint8_t, 3, 1> colour = {128, 128, 128};
  double error_px = 0;                  // mean reprojection error over the track
};

// A surveyed marker as used by the alignment: world position in the site frame.
struct MarkerConstraint {
  std::string name;
  Eigen::Vector3d position;     // metres, site frame
  Eigen::Vector3d sigma;        // metres, per axis (E, N, Z)
  bool control = true;          // check markers never drive the solution
};

// An image observation of a marker (detected coded target or entered by hand).
struct MarkerObservation {
  std::string marker;
  int image = -1;               // index into images
  Eigen::Vector2d pixel;        // original photo pixels
  // pixels: this observation's own standard deviation in the adjustment (a marker's
  // dispersion seen from this photo); 0 = BundleOptions::marker_sigma_px.
  double sigma_px = 0;
};

struct Reconstruction {
  std::vector<CameraGroup> groups;
  std::vector<RegisteredImage> images;
  std::vector<SparsePoint> points;
  bool georeferenced = false;
};

}  // namespace strata
