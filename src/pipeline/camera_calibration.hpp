#pragma once
// Known camera calibrations in the alignment: `strata camera set` (values, or another
// layer's solved intrinsics) and the use of a stored calibration when a layer's
// camera groups are formed. The storage is project/calibration_records.hpp; the
// file importers are importers/calibration/.
#include "core/cache_key.hpp"
#include "project/calibration_records.hpp"
#include "project/project.hpp"
#include "geometry/reconstruction.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace strata {

// What `strata camera set` was given. Either values (focal_px and what follows) or
// from_layer, never both.
struct CameraSetOptions {
  std::string camera;                             // camera id or the name of one of its photos
  std::optional<double> focal_px;                 // pixels: fx, and fy unless fy_px
  std::optional<double> fy_px;                    // pixels
  std::optional<Eigen::Vector2d> principal_point; // pixels, (0,0) = centre of the top-left pixel;
                                                  // default the image centre
  CameraModel model = CameraModel::radial;
  std::vector<double> k;  // radial terms: radial k1,k2; brown k1,k2[,k3]; fisheye k1,k2[,k3[,k4]]
  std::vector<double> p;  // tangential p1,p2 (OpenCV's order), brown only
  std::string from_layer; // reuse the solved intrinsics of this layer's alignment
  bool fixed = false;     // hold constant in every adjustment (else a starting value)

  // Refuses what needs no project to refuse (one line naming the option and value);
  // the principal point is checked against the camera's size by set_camera_calibration.
  void validate() const;
};

struct CameraSetSummary {
  CalibrationRecord record;  // as stored
  bool replaced = false;     // the camera had a calibration before
};

// Validates, then stores the camera's calibration in one transaction; a refusal
// leaves the project unchanged.
CameraSetSummary set_camera_calibration(Project& project, const CameraSetOptions& options);
// False when the camera had no calibration.
bool clear_camera_calibration(Project& project, const std::string& camera);

// The intrinsics a layer's stored alignment solved for a camera. InputError when the
// layer has no alignment or its alignment has no photo of that camera.
Intrinsics solved_intrinsics(Database& db, const std::string& layer, std::int64_t camera_id);

// Camera group initialisation: when the camera has a known calibration, the group
// starts from it (calibration_known; calibration_fixed as stored; calibration_source
// "calibration: <source>"). Returns false, leaving the group as it is, otherwise.
bool apply_known_calibration(Database& db, std::int64_t camera_id, CameraGroup& group);

// Adds the stored calibrations of the cameras of these photos to the alignment's
// inputs key: setting, changing or clearing one reruns the alignment.
void add_known_calibrations(CacheKey& key, Database& db, const std::vector<ImageRecord>& images);

// Self-calibration that can be trusted: the solved intrinsics of each camera group
// against what was known before (the EXIF focal with the sensor width, a calibration
// set or imported, another layer's). A focal length more than `focal_tolerance` away
// from the EXIF prior, or a distortion that moves the image corner more than
// `corner_tolerance_px` from a known calibration's, is a finding: a wrong sensor width,
// a zoom changed between photos, or a block the adjustment bent into the lens.
struct CalibrationCheckOptions {
  double focal_tolerance = 0.05;      // unitless, |f - f_prior| / f_prior
  double corner_tolerance_px = 10.0;  // pixels, at the image corner
};

struct CalibrationCheck {
  int group = 0;
  std::string source;             // what the prior was: "exif", "calibration: ..."
  double focal_px = 0;            // solved
  double prior_focal_px = 0;      // 0: no prior
  double focal_change = 0;        // unitless, (f - f_prior) / f_prior
  double corner_shift_px = 0;     // pixels: solved minus prior distortion at the image corner
  std::string finding;            // empty: consistent
};

// `before[g]` is the group as it entered the alignment, `after[g]` as solved.
std::vector<CalibrationCheck> check_self_calibration(const std::vector<CameraGroup>& before,
                                                     const std::vector<CameraGroup>& after,
                                                     const CalibrationCheckOptions& options = {});

}  // namespace strata
