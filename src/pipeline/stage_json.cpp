#include "pipeline/stage_json.hpp"

#include "pipeline/json_fields.hpp"

#include <cmath>

namespace strata {

constexpr int enum_count(MarkerRole) { return 3; }
constexpr int enum_count(CameraModel) { return 3; }
constexpr int enum_count(OrthoMarkerStatus) { return 6; }

template <typename Io>
void describe(Io& io, AxisRmse& r) {
  io("e_m", r.e);
  io("n_m", r.n);
  io("z_m", r.z);
  io("horizontal_m", r.horizontal);
  io("xyz_m", r.xyz);
  io("markers", r.markers);
  io("markers_with_height", r.markers_z);
}

template <typename Io>
void describe(Io& io, Blunder& b) {
  io("marker", b.marker);
  bool one_photo = !b.image.empty();  // else the whole marker (null)
  io.when("image", one_photo, b.image);
  io("amount", b.amount);
  io("unit", b.unit);
  io("reason", b.reason);
}

template <typename Io>
void describe(Io& io, ObservationResidual& o) {
  io("image", o.image_name);
  io("to_rays_px", o.to_rays_px);
  io("to_survey_px", o.to_survey_px);
  io("sigma_px", o.sigma_px);
  io("dropped", o.dropped);
}

// Views of fields that the JSON nests in an object of their own.
struct DenseStepsView {
  DenseSummary& s;
};
template <typename Io>
void describe(Io& io, DenseStepsView& v) {
  io("view_selection", v.s.view_selection);
  io("undistortion", v.s.undistortion);
  io("depth_maps", v.s.depth_maps);
  io("filtering", v.s.filtering);
  io("fusion", v.s.fusion);
  io("meshing", v.s.meshing);
  io("writing", v.s.writing);
  io("total", v.s.total);
}

struct LeaveOneOutView {
  double& dE;
  double& dN;
  double& dZ;
};
template <typename Io>
void describe(Io& io, LeaveOneOutView& v) {
  io("dE", v.dE);
  io("dN", v.dN);
  io("dZ", v.dZ);
}

struct ObservationSigmaView {
  double& keypoints_px;
  double& markers_px;
};
template <typename Io>
void describe(Io& io, ObservationSigmaView& v) {
  io("keypoints", v.keypoints_px);
  io("markers", v.markers_px);
}

template <typename Io>
void describe(Io& io, MarkerResidual& r) {
  io("marker", r.name);
  io("role", r.role);
  io("triangulated", r.triangulated);
  io("height_known", r.height_known);
  io("dE", r.dE);
  io("dN", r.dN);
  io("dZ", r.dZ);
  io("reprojection_px", r.reprojection_px);
  io("images", r.images);
  io("observed", r.observed);
  io("dispersion_m", r.dispersion_m);
  io("dispersion_px", r.dispersion_px);
  io("diagnosis", r.diagnosis);
  io("distance_misfit_m", r.distance_misfit_m);
  LeaveOneOutView loo{r.loo_dE, r.loo_dN, r.loo_dZ};
  io.when("leave_one_out", r.loo, loo);
  io("observations", r.observations);
}

template <typename Io>
void describe(Io& io, CameraFigures& c) {
  Intrinsics& k = c.intrinsics;
  io("camera_id", c.camera_id);
  io("model", k.model);
  io("model_source", c.lens.source);
  io("model_reason", c.lens.reason);
  io("focal_35mm", c.lens.focal_35mm);
  io("focal_source", c.focal_source);
  io("calibration_source", c.calibration_source);
  io("calibration_fixed", c.calibration_fixed);
  io("width", k.width);
  io("height", k.height);
  io("fx", k.fx);
  io("fy", k.fy);
  io("cx", k.cx);
  io("cy", k.cy);
  // The coefficients of the model only (the model is read first).
  io("k1", k.k1);
  io("k2", k.k2);
  if (k.model != CameraModel::radial) io("k3", k.k3);
  if (k.model == CameraModel::fisheye) io("k4", k.k4);
  if (k.model == CameraModel::brown) {
    io("p1", k.p1);
    io("p2", k.p2);
  }
}

template <typename Io>
void describe(Io& io, FocalAttempt& a) {
  io("factor", a.factor);
  io("prior_px", a.prior_px);
  io("registered", a.registered);
  io("rmse_px", a.rmse_px);
  io("focal_px", a.focal_px);
  bool failed = !a.failure.empty();
  io.when("failure", failed, a.failure);
  io("chosen", a.chosen);
}

template <typename Io>
void describe(Io& io, FocalSearchSummary& s) {
  io("groups", s.groups);
  io("attempts", s.attempts);
}

template <typename Io>
void describe(Io& io, CalibrationCheck& c) {
  io("group", c.group);
  io("source", c.source);
  io("focal_px", c.focal_px);
  io("prior_focal_px", c.prior_focal_px);
  io("focal_change", c.focal_change);
  io("corner_shift_px", c.corner_shift_px);
  io("finding", c.finding);
}

template <typename Io>
void describe(Io& io, SurveyAssessment& s) {
  io("plan_step_m", s.plan_step_m);
  io("height_step_m", s.height_step_m);
  io("heights_equal", s.heights_equal);
}

template <typename Io>
void describe(Io& io, PairCounts& p) {
  io("selected", p.selected);
  io("verified", p.verified);
  io("exhaustive", p.exhaustive);
}

template <typename Io>
void describe(Io& io, AlignmentTimings& t) {
  io("features_s", t.features_s);
  io("matching_s", t.matching_s);
  io.omit_empty("targets_s", t.targets_s);
  io("sfm_s", t.sfm_s);
  io("georeference_s", t.georeference_s);
  io("total_s", t.total_s);
}

template <typename Io>
void describe(Io& io, AlignmentQuality& q) {
  io("layer", q.layer);
  io("images_total", q.images_total);
  io("images_registered", q.sparse.registered_images);
  io("unregistered", q.unregistered);
  io("points", q.sparse.points);
  io("observations", q.sparse.observations);
  io("mean_track_length", q.sparse.mean_track_length);
  io("reprojection_rmse_px", q.sparse.reprojection_rmse_px);
  io("gsd_m", q.sparse.gsd_m);
  io("cameras", q.cameras);
  io.omit_empty("focal_search", q.focal_search);
  io("georeferenced", q.georeferenced);
  io("control_rmse", q.control_rmse);
  io("check_rmse", q.check_rmse);
  io("leave_one_out_rmse", q.leave_one_out_rmse);
  io("rejected_markers", q.rejected_markers);
  io("unusable_markers", q.unusable_markers);
  io("blunders", q.blunders);
  ObservationSigmaView sigma{q.keypoint_sigma_px, q.marker_sigma_px};
  io("observation_sigma_px", sigma);
  io("detected_observations", q.detected_observations);
  io("pairs", q.pairs);
  io("markers", q.markers);
  io.omit_empty("georeference_message", q.georeference_message);
  io("georeference_diagnosis", q.georeference_diagnosis);
  io("calibration_check", q.calibration_check);
  io("survey", q.survey);
  io("timings", q.timings);
  io("peak_memory_mb", q.peak_memory_mb);
}

nlohmann::json to_json(const AlignmentQuality& quality) { return json_fields::write(quality); }

AlignmentQuality alignment_quality_from_json(const nlohmann::json& j) {
  AlignmentQuality q;
  json_fields::read(j, q);
  q.sparse.total_images = q.images_total;
  return q;
}

template <typename Io>
void describe(Io& io, StepFigures& s) {
  io("seconds", s.seconds);
  double mb = double(s.peak_memory_bytes) / 1048576.0;
  io("peak_memory_mb", mb);
  if constexpr (Io::reading) s.peak_memory_bytes = std::int64_t(std::llround(mb * 1048576.0));
}

template <typename Io>
void describe(Io& io, DenseQuality& q) {
  DenseSummary& s = q.figures;
  io("layer", q.layer);
  io("images_total", s.images_total);
  io("images_with_depth", s.images_with_depth);
  io("depth_scale", s.depth_scale);
  io("gsd_m", s.gsd_m);
  io("smoothing_m", s.smoothing_m);
  io("voxel_size_m", s.voxel_size_m);
  io("active_voxels", s.active_voxels);
  io("floating_voxels_removed", s.floating_voxels_removed);
  io("mesh_faces", s.mesh_faces);
  io("points", s.points);
  io("points_below_weight", s.points_below_weight);
  io("completeness", s.completeness);
  io("area_m2", s.area_m2);
  io("median_distance_sparse_m", s.median_distance_sparse_m);
  io("p95_distance_sparse_m", s.p95_distance_sparse_m);
  io("photos", q.photos);
  io("scans_fused", s.scans_fused);
  io("scans_unregistered", q.scans_unregistered);
  io("scan_points", s.scan_points);
  io("scan_weight_share", s.scan_weight_share);
  io("unit_sigma_m", s.unit_sigma_m);
  DenseStepsView steps{s};
  io("steps", steps);
}

template <typename Io>
void describe(Io& io, DtmSigmaFigures& s) {
  io("path", s.path);
  io("median_m", s.median_m);
  io("p95_m", s.p95_m);
}

template <typename Io>
void describe(Io& io, DtmFigures& d) {
  io("path", d.path);
  io("cell_m", d.cell_m);
  io("width", d.width);
  io("height", d.height);
  io("valid_cells", d.valid_cells);
  io("area_m2", d.area_m2);
  io("min_m", d.min_m);
  io("max_m", d.max_m);
  io("mean_m", d.mean_m);
  io("median_distance_sparse_m", d.median_distance_sparse_m);
  io("sparse_points_compared", d.sparse_points_compared);
  io.omit_empty("sigma", d.sigma);
}

template <typename Io>
void describe(Io& io, OrthoFigures& o) {
  io("path", o.path);
  io("cell_m", o.cell_m);
  io("views", o.views);
  io("views_used", o.views_used);
  io("coverage", o.coverage);
  io("seam_fraction", o.seam_fraction);
  io("balance_rms_before", o.balance_rms_before);
  io("balance_rms_after", o.balance_rms_after);
  io("gain_min", o.gain_min);
  io("gain_max", o.gain_max);
}

template <typename Io>
void describe(Io& io, OrthoMarkerFigures& m) {
  io("marker", m.marker);
  io("role", m.role);
  io("status", m.status);
  io.omit_empty("source_pixel_mm", m.source_pixel_mm);
  if (m.status != OrthoMarkerStatus::detected) return;  // read first: the offsets exist only then
  io("E", m.e_m);
  io("N", m.n_m);
  io("dE_mm", m.de_mm);
  io("dN_mm", m.dn_mm);
  io("offset_mm", m.offset_mm);
  io("offset_px", m.offset_px);
  io("within_tolerance", m.within_tolerance);
  io("detections", m.detections);
  io("scales", m.scales);
}

template <typename Io>
void describe(Io& io, OrthoMarkerCheckFigures& c) {
  io("cell_m", c.cell_m);
  io("tolerance_px", c.tolerance_px);
  io("surveyed", c.surveyed);
  io("detected", c.detected);
  io("over_tolerance", c.over_tolerance);
  io("max_px", c.max_px);
  io("rmse_px", c.rmse_px);
  io("max_mm", c.max_mm);
  io("rmse_mm", c.rmse_mm);
  io("unknown_target_ids", c.unknown_target_ids);
  io("markers", c.markers);
}

template <typename Io>
void describe(Io& io, ContourFigures& c) {
  io("interval_m", c.interval_m);
  io("lines", c.lines);
}

template <typename Io>
void describe(Io& io, FootprintFigures& f) {
  io("area_m2", f.area_m2);
  io("perimeter_m", f.perimeter_m);
  io("polygons", f.polygons);
}

template <typename Io>
void describe(Io& io, ProductsSteps& s) {
  io("dtm", s.dtm);
  io.omit_empty("ortho", s.ortho);
  io.omit_empty("ortho_markers", s.ortho_markers);
  io("vectors", s.vectors);
  io.omit_empty("gpkg_rasters", s.gpkg_rasters);
  io("total", s.total);
}

template <typename Io>
void describe(Io& io, ProductsQuality& q) {
  io("layer", q.layer);
  io("dtm", q.dtm);
  io("ortho", q.ortho);  // null without photos
  io.omit_empty("ortho_markers", q.ortho_markers);
  io("contours", q.contours);
  io("footprint", q.footprint);
  io("steps", q.steps);
}

nlohmann::json to_json(const DenseQuality& quality) { return json_fields::write(quality); }

DenseQuality dense_quality_from_json(const nlohmann::json& j) {
  DenseQuality q;
  json_fields::read(j, q);
  return q;
}

nlohmann::json to_json(const ProductsQuality& quality) { return json_fields::write(quality); }

ProductsQuality products_quality_from_json(const nlohmann::json& j) {
  ProductsQuality q;
  json_fields::read(j, q);
  return q;
}

std::optional<StageRecord> load_stage_record(Database& db, std::int64_t layer_id, const char* stage) {
  auto st = db.prepare("SELECT inputs_key, quality_json FROM reconstructions WHERE layer_id = ? AND stage = ?");
  st.bind_all(layer_id, stage);
  if (!st.step()) return std::nullopt;
  StageRecord r{st.get_text(0), nlohmann::json::parse(st.get_text(1), nullptr, false)};
  if (r.quality.is_discarded()) r.quality = nlohmann::json::object();
  return r;
}

std::optional<AlignmentQuality> stored_alignment_quality(Database& db, std::int64_t layer_id) {
  const auto r = load_stage_record(db, layer_id, "sparse");
  if (!r) return std::nullopt;
  return alignment_quality_from_json(r->quality);
}

std::optional<DenseQuality> stored_dense_quality(Database& db, std::int64_t layer_id) {
  const auto r = load_stage_record(db, layer_id, "dense");
  if (!r) return std::nullopt;
  return dense_quality_from_json(r->quality);
}

std::optional<ProductsQuality> stored_products_quality(Database& db, std::int64_t layer_id) {
  const auto r = load_stage_record(db, layer_id, "products");
  if (!r) return std::nullopt;
  return products_quality_from_json(r->quality);
}

const AxisRmse* AlignmentQuality::quoted_rmse() const {
  if (check_rmse.markers > 0) return &check_rmse;
  if (control_rmse.markers > 0) return &control_rmse;
  return nullptr;
}

}  // namespace strata
