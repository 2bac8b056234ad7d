#pragma once
// Known camera calibrations (schema 6, table camera_calibrations) and the lookup of
// a camera by the reference a user types: its id from `strata camera list`, or the
// name of one of its photos. Callers own the transaction.
#include "geometry/camera.hpp"
#include "project/database.hpp"
#include "project/records.hpp"

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace strata {

struct CalibrationRecord {
  std::int64_t camera_id = 0;
  // The camera's image size and its calibration in strata's conventions (pixels,
  // (0,0) = centre of the top-left pixel; OpenCV's tangential order).
  Intrinsics intrinsics;
  bool fixed = false;   // held constant in every adjustment, else a starting value
  std::string source;   // "camera set", "file cal.yml (opencv)", "layer L7"
  std::string set_at;   // ISO 8601 UTC; filled by upsert_calibration
};

// Refuses values no lens has, with one line naming the field and the value:
// non-finite numbers, a focal length <= 0, a principal point outside the image
// (pixel centres -0.5 .. size-0.5), coefficients the model does not have (radial:
// k1, k2; brown: k1..k3, p1, p2; fisheye: k1..k4). `what` starts the message
// (e.g. "camera 2" or "importer.calibration.opencv: cal.yml").
void validate_calibration(const Intrinsics& k, const std::string& what);

// Inserts or replaces the camera's calibration; validates it first.
void upsert_calibration(Database& db, CalibrationRecord c);
std::optional<CalibrationRecord> find_calibration(Database& db, std::int64_t camera_id);
std::vector<CalibrationRecord> list_calibrations(Database& db);
// False when the camera had none.
bool delete_calibration(Database& db, std::int64_t camera_id);

std::vector<CameraRecord> list_cameras(Database& db);
// "3" -> camera 3; "IMG_0042.JPG" -> the camera of that photo (every layer's photo of
// that name must share one camera). InputError naming the reference otherwise.
CameraRecord resolve_camera(Database& db, const std::string& reference);

}  // namespace strata
