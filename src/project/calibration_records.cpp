#include "project/calibration_records.hpp"

#include "core/time.hpp"
#include "core/error.hpp"

#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <ctime>
#include <set>

namespace strata {
namespace {

constexpr const char* kCalibrationSelect =
    "SELECT c.camera_id, c.model, c.fx, c.fy, c.cx, c.cy, c.k1, c.k2, c.k3, c.k4, c.p1, c.p2, "
    "c.fixed, c.source, c.set_at, cam.width, cam.height FROM camera_calibrations c JOIN cameras cam "
    "ON cam.id = c.camera_id ";

CalibrationRecord read_calibration(const Statement& st) {
  CalibrationRecord c;
  c.camera_id = st.get_int(0);
  Intrinsics& k = c.intrinsics;
  const auto model = camera_model_from_string(st.get_text(1));
  STRATA_CHECK(model.has_value(), "camera_calibrations.model '{}' passed the CHECK", st.get_text(1));
  k.model = *model;
  k.fx = st.get_double(2);
  k.fy = st.get_double(3);
  k.cx = st.get_double(4);
  k.cy = st.get_double(5);
  k.k1 = st.get_double(6);
  k.k2 = st.get_double(7);
  k.k3 = st.get_double(8);
  k.k4 = st.get_double(9);
  k.p1 = st.get_double(10);
  k.p2 = st.get_double(11);
  c.fixed = st.get_int(12) != 0;
  c.source = st.get_text(13);
  c.set_at = st.get_text(14);
  k.width = int(st.get_int(15));
  k.height = int(st.get_int(16));
  return c;
}

void require_finite(double v, const char* field, const std::string& what) {
  if (!std::isfinite(v)) throw InputError(fmt::format("{}: {} = {} is not a finite number", what, field, v));
}

// A coefficient the model does not have must be zero (a silent drop would change the lens).
void require_unused_zero(double v, const char* field, CameraModel model, const std::string& what) {
  if (v != 0.0) {
    throw InputError(fmt::format("{}: {} = {} but the {} model has no {} (radial: k1, k2; brown: k1-k3, "
                                 "p1, p2; fisheye: k1-k4)",
                                 what, field, v, to_string(model), field));
  }
}

}  // namespace

void validate_calibration(const Intrinsics& k, const std::string& what) {
  STRATA_CHECK(k.width > 0 && k.height > 0, "calibration without an image size");
  const std::pair<const char*, double> values[] = {{"fx", k.fx}, {"fy", k.fy}, {"cx", k.cx}, {"cy", k.cy},
                                                   {"k1", k.k1}, {"k2", k.k2}, {"k3", k.k3}, {"k4", k.k4},
                                                   {"p1", k.p1}, {"p2", k.p2}};
  for (const auto& [field, v] : values) require_finite(v, field, what);
  if (k.fx <= 0) throw InputError(fmt::format("{}: focal length fx = {} px must be positive", what, k.fx));
  if (k.fy <= 0) throw InputError(fmt::format("{}: focal length fy = {} px must be positive", what, k.fy));
  // Pixel centres run from 0 to size-1; the image area from -0.5 to size-0.5.
  if (k.cx < -0.5 || k.cx > k.width - 0.5) {
    throw InputError(fmt::format("{}: principal point cx = {} px is outside the {} px wide image", what, k.cx,
                                 k.width));
  }
  if (k.cy < -0.5 || k.cy > k.height - 0.5) {
    throw InputError(fmt::format("{}: principal point cy = {} px is outside the {} px high image", what,
                                 k.cy, k.height));
  }
  switch (k.model) {
    case CameraModel::radial:
      require_unused_zero(k.k3, "k3", k.model, what);
      require_unused_zero(k.k4, "k4", k.model, what);
      require_unused_zero(k.p1, "p1", k.model, what);
      require_unused_zero(k.p2, "p2", k.model, what);
      break;
    case CameraModel::brown:
      require_unused_zero(k.k4, "k4", k.model, what);
      break;
    case CameraModel::fisheye:
      require_unused_zero(k.p1, "p1", k.model, what);
      require_unused_zero(k.p2, "p2", k.model, what);
      break;
  }
}

void upsert_calibration(Database& db, CalibrationRecord c) {
  const auto cam = find_camera(db, c.camera_id);
  STRATA_CHECK(cam.has_value(), "calibration of camera {} which does not exist", c.camera_id);
  STRATA_CHECK(c.intrinsics.width == cam->width && c.intrinsics.height == cam->height,
               "calibration for {}x{} stored on a {}x{} camera", c.intrinsics.width, c.intrinsics.height,
               cam->width, cam->height);
  validate_calibration(c.intrinsics, fmt::format("camera {}", c.camera_id));
  if (c.set_at.empty()) c.set_at = utc_now_iso();
  const Intrinsics& k = c.intrinsics;
  db.prepare(
        "INSERT OR REPLACE INTO camera_calibrations(camera_id, model, fx, fy, cx, cy, k1, k2, k3, k4, p1, "
        "p2, fixed, source, set_at) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)")
      .bind_all(c.camera_id, to_string(k.model), k.fx, k.fy, k.cx, k.cy, k.k1, k.k2, k.k3, k.k4, k.p1, k.p2,
                c.fixed ? 1 : 0, c.source, c.set_at)
      .run();
}

std::optional<CalibrationRecord> find_calibration(Database& db, std::int64_t camera_id) {
  auto st = db.prepare(std::string(kCalibrationSelect) + "WHERE c.camera_id = ?");
  st.bind(1, camera_id);
  if (!st.step()) return std::nullopt;
  return read_calibration(st);
}

std::vector<CalibrationRecord> list_calibrations(Database& db) {
  auto st = db.prepare(std::string(kCalibrationSelect) + "ORDER BY c.camera_id");
  std::vector<CalibrationRecord> out;
  while (st.step()) out.push_back(read_calibration(st));
  return out;
}

bool delete_calibration(Database& db, std::int64_t camera_id) {
  db.prepare("DELETE FROM camera_calibrations WHERE camera_id = ?").bind_all(camera_id).run();
  return db.changes() > 0;
}

std::vector<CameraRecord> list_cameras(Database& db) {
  std::vector<CameraRecord> out;
  auto st = db.prepare("SELECT id FROM cameras ORDER BY id");
  while (st.step()) out.push_back(*find_camera(db, st.get_int(0)));
  return out;
}

CameraRecord resolve_camera(Database& db, const std::string& reference) {
  // All digits: a camera id.
  if (!reference.empty() && reference.find_first_not_of("0123456789") == std::string::npos) {
    if (auto cam = find_camera(db, std::stoll(reference))) return *cam;
  }
  const auto images = find_images_by_name(db, reference);
  if (images.empty()) {
    throw InputError(fmt::format("camera '{}': no camera with that id and no photo of that name (see "
                                 "'strata camera list')", reference));
  }
  std::set<std::int64_t> ids;
  for (const auto& im : images) {
    if (!im.camera_id) {
      throw InputError(fmt::format("camera '{}': that photo has no camera row (re-import it)", reference));
    }
    ids.insert(*im.camera_id);
  }
  if (ids.size() > 1) {
    std::string list;
    for (auto id : ids) list += (list.empty() ? "" : ", ") + std::to_string(id);
    throw InputError(fmt::format("camera '{}': photos of that name in several layers were taken with "
                                 "different cameras ({}); give the camera id", reference, list));
  }
  return *find_camera(db, *ids.begin());
}

}  // namespace strata
