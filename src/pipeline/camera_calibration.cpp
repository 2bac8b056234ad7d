#include "pipeline/camera_calibration.hpp"

#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/log.hpp"
#include "pipeline/alignment_store.hpp"

#include <fmt/format.h>

#include <cmath>
#include <set>

namespace strata {
namespace {

// How many --k values each model takes (the rest are 0).
struct RadialTermCount {
  std::size_t min, max;
};
RadialTermCount radial_terms(CameraModel model) {
  switch (model) {
    case CameraModel::radial:
      return {2, 2};
    case CameraModel::brown:
      return {2, 3};
    case CameraModel::fisheye:
      return {2, 4};
  }
  return {2, 2};
}

std::string join(const std::vector<double>& v) {
  std::string out;
  for (double x : v) out += (out.empty() ? "" : ",") + fmt::format("{}", x);
  return out;
}

Intrinsics intrinsics_from_values(const CameraSetOptions& o, const CameraRecord& camera) {
  Intrinsics k;
  k.width = camera.width;
  k.height = camera.height;
  k.model = o.model;
  k.fx = *o.focal_px;
  k.fy = o.fy_px.value_or(*o.focal_px);
  k.cx = o.principal_point ? o.principal_point->x() : (camera.width - 1) / 2.0;
  k.cy = o.principal_point ? o.principal_point->y() : (camera.height - 1) / 2.0;
  double* radial[] = {&k.k1, &k.k2, &k.k3, &k.k4};
  for (std::size_t i = 0; i < o.k.size(); ++i) *radial[i] = o.k[i];
  if (!o.p.empty()) {
    k.p1 = o.p[0];
    k.p2 = o.p[1];
  }
  return k;
}

void check_principal_point(const Eigen::Vector2d& pp, const CameraRecord& camera) {
  if (pp.x() < -0.5 || pp.x() > camera.width - 0.5 || pp.y() < -0.5 || pp.y() > camera.height - 0.5) {
    throw InputError(fmt::format("--pp: {},{} is outside camera {}'s {}x{} px image (pixel centres 0..{}, "
                                 "0..{})",
                                 pp.x(), pp.y(), camera.id, camera.width, camera.height, camera.width - 1,
                                 camera.height - 1));
  }
}

}  // namespace

void CameraSetOptions::validate() const {
  if (camera.empty()) throw InputError("CAMERA: empty; give a camera id (strata camera list) or a photo name");
  if (!from_layer.empty()) {
    if (focal_px || fy_px || principal_point || !k.empty() || !p.empty()) {
      throw InputError("--from-layer: takes the layer's solved intrinsics; give it without --focal-px, --fy, "
                       "--pp, --k or --p");
    }
    return;
  }
  if (!focal_px) throw InputError("--focal-px: required (or --from-layer LAYER)");
  if (!std::isfinite(*focal_px) || *focal_px <= 0) {
    throw InputError(fmt::format("--focal-px: {} is not a positive focal length in pixels", *focal_px));
  }
  if (fy_px && (!std::isfinite(*fy_px) || *fy_px <= 0)) {
    throw InputError(fmt::format("--fy: {} is not a positive focal length in pixels", *fy_px));
  }
  if (principal_point && !principal_point->allFinite()) {
    throw InputError(fmt::format("--pp: {},{} is not a pair of finite numbers", principal_point->x(),
                                 principal_point->y()));
  }
  const RadialTermCount n = radial_terms(model);
  if (!k.empty() && (k.size() < n.min || k.size() > n.max)) {
    throw InputError(fmt::format("--k: the {} model takes {} coefficients (k1,k2{}), got {} ({})",
                                 to_string(model), n.min == n.max ? fmt::format("{}", n.min)
                                                                  : fmt::format("{} to {}", n.min, n.max),
                                 model == CameraModel::brown ? "[,k3]"
                                 : model == CameraModel::fisheye ? "[,k3[,k4]]" : "",
                                 k.size(), join(k)));
  }
  for (double v : k) {
    if (!std::isfinite(v)) throw InputError(fmt::format("--k: {} is not a finite number", join(k)));
  }
  if (!p.empty()) {
    if (model != CameraModel::brown) {
      throw InputError(fmt::format("--p: the {} model has no tangential terms; use --model brown",
                                   to_string(model)));
    }
    if (p.size() != 2) throw InputError(fmt::format("--p: expected 2 coefficients (p1,p2), got {}", join(p)));
    for (double v : p) {
      if (!std::isfinite(v)) throw InputError(fmt::format("--p: {} is not a finite number", join(p)));
    }
  }
}

Intrinsics solved_intrinsics(Database& db, const std::string& layer_name, std::int64_t camera_id) {
  const LayerRecord layer = require_layer(db, layer_name);
  const auto stored = load_alignment(db, layer);
  if (!stored) {
    throw InputError(fmt::format("--from-layer: layer {} has no alignment yet; run 'strata process DIR --layer "
                                 "{} --until sparse' first",
                                 layer.name, layer.name));
  }
  std::string cameras;
  for (std::size_t g = 0; g < stored->camera_ids.size(); ++g) {
    if (stored->camera_ids[g] == camera_id) return stored->rec.groups[g].intrinsics;
    cameras += (cameras.empty() ? "" : ", ") + std::to_string(stored->camera_ids[g]);
  }
  throw InputError(fmt::format("--from-layer: layer {}'s alignment has no photos of camera {} (its cameras: {})",
                               layer.name, camera_id, cameras.empty() ? "none" : cameras));
}

CameraSetSummary set_camera_calibration(Project& project, const CameraSetOptions& options) {
  options.validate();
  Database& db = project.db();
  const CameraRecord camera = resolve_camera(db, options.camera);
  CalibrationRecord record;
  record.camera_id = camera.id;
  record.fixed = options.fixed;
  if (!options.from_layer.empty()) {
    record.intrinsics = solved_intrinsics(db, options.from_layer, camera.id);
    record.source = fmt::format("layer {}", options.from_layer);
    // A solved camera has the camera's size by construction; refuse rather than carry
    // a mismatch into the table.
    STRATA_CHECK(record.intrinsics.width == camera.width && record.intrinsics.height == camera.height,
                 "layer {} solved camera {} at {}x{}, the camera is {}x{}", options.from_layer, camera.id,
                 record.intrinsics.width, record.intrinsics.height, camera.width, camera.height);
  } else {
    if (options.principal_point) check_principal_point(*options.principal_point, camera);
    record.intrinsics = intrinsics_from_values(options, camera);
    record.source = "camera set";
  }
  validate_calibration(record.intrinsics, fmt::format("camera {}", camera.id));
  CameraSetSummary s;
  Transaction tx(db);
  s.replaced = find_calibration(db, camera.id).has_value();
  upsert_calibration(db, record);
  s.record = *find_calibration(db, camera.id);
  fault::point("camera.set.before_commit");
  tx.commit();
  return s;
}

bool clear_camera_calibration(Project& project, const std::string& camera_ref) {
  Database& db = project.db();
  const CameraRecord camera = resolve_camera(db, camera_ref);
  Transaction tx(db);
  const bool removed = delete_calibration(db, camera.id);
  tx.commit();
  return removed;
}

bool apply_known_calibration(Database& db, std::int64_t camera_id, CameraGroup& group) {
  const auto c = find_calibration(db, camera_id);
  if (!c) return false;
  // The photos of a camera row have its size (images and cameras are written together).
  STRATA_CHECK(c->intrinsics.width == group.intrinsics.width && c->intrinsics.height == group.intrinsics.height,
               "camera {} calibrated at {}x{}, its photos are {}x{}", camera_id, c->intrinsics.width,
               c->intrinsics.height, group.intrinsics.width, group.intrinsics.height);
  group.intrinsics = c->intrinsics;
  group.calibration_known = true;
  group.calibration_fixed = c->fixed;
  group.calibration_source = "calibration: " + c->source;
  log::info("camera {}: known calibration ({}), {}: {} f {:.2f},{:.2f} px", camera_id, c->source,
            c->fixed ? "held fixed" : "refined from it", to_string(c->intrinsics.model), c->intrinsics.fx,
            c->intrinsics.fy);
  return true;
}

void add_known_calibrations(CacheKey& key, Database& db, const std::vector<ImageRecord>& images) {
  std::set<std::int64_t> cameras;
  for (const auto& im : images) {
    if (im.camera_id) cameras.insert(*im.camera_id);
  }
  // The source and date do not change the result and stay out.
  for (std::int64_t id : cameras) {
    if (const auto c = find_calibration(db, id)) key.add(id).add(c->intrinsics).add(c->fixed);
  }
}

namespace {

// Where the image corner lands under `k` relative to the pinhole, pixels.
Eigen::Vector2d corner_offset_px(const Intrinsics& k) {
  const Eigen::Vector2d corner(k.width - 1.0, k.height - 1.0);
  const Eigen::Vector2d xn((corner.x() - k.cx) / k.fx, (corner.y() - k.cy) / k.fy);
  const Eigen::Vector2d d = k.distort(xn) - xn;
  return {d.x() * k.fx, d.y() * k.fy};
}

}  // namespace

std::vector<CalibrationCheck> check_self_calibration(const std::vector<CameraGroup>& before,
                                                     const std::vector<CameraGroup>& after,
                                                     const CalibrationCheckOptions& options) {
  std::vector<CalibrationCheck> out;
  for (std::size_t g = 0; g < before.size() && g < after.size(); ++g) {
    const auto& b = before[g];
    const auto& a = after[g];
    CalibrationCheck c;
    c.group = int(g);
    c.focal_px = a.intrinsics.fx;
    if (!b.focal_from_exif && !b.calibration_known) {
      c.source = "none (focal by self-calibration from a default)";
      out.push_back(c);
      continue;
    }
    c.source = b.calibration_known ? b.calibration_source : "exif";
    c.prior_focal_px = b.intrinsics.fx;
    c.focal_change = (a.intrinsics.fx - b.intrinsics.fx) / b.intrinsics.fx;
    if (b.calibration_known) c.corner_shift_px = (corner_offset_px(a.intrinsics) - corner_offset_px(b.intrinsics)).norm();
    std::vector<std::string> found;
    if (std::abs(c.focal_change) > options.focal_tolerance) {
      found.push_back(fmt::format(
          "the solved focal length {:.0f} px is {:+.1f} % from the {} prior {:.0f} px: {}", a.intrinsics.fx,
          100 * c.focal_change, c.source, b.intrinsics.fx,
          b.calibration_known ? "the lens is not the one calibrated (zoom, focus), or the block is bent"
                              : "a wrong sensor width in the list, a digital zoom or crop, or a bent block"));
    }
    if (c.corner_shift_px > options.corner_tolerance_px) {
      found.push_back(fmt::format("its distortion moves the image corner {:.1f} px from the known calibration's",
                                  c.corner_shift_px));
    }
    for (std::size_t i = 0; i < found.size(); ++i) c.finding += (i ? "; " : "") + found[i];
    out.push_back(c);
  }
  return out;
}

}  // namespace strata
