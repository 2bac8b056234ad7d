#include "pipeline/align_layer.hpp"

#include "core/time.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/hash.hpp"
#include "core/log.hpp"
#include "core/progress.hpp"
#include "core/resources.hpp"
#include "georef/survey.hpp"
#include "pipeline/alignment_store.hpp"
#include "pipeline/camera_calibration.hpp"
#include "project/records.hpp"
#include "sfm/quality.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <ctime>
#include <map>
#include <set>

namespace strata {
namespace {

// Without any EXIF focal length, start from a moderately wide lens: 1.2 x the
// long side, as COLMAP does; self-calibration refines it.
constexpr double kDefaultFocalFactor = 1.2;

nlohmann::json rmse_json(const AxisRmse& r) {
  return {{"e_m", r.e},         {"n_m", r.n},          {"z_m", r.z},
          {"horizontal_m", r.horizontal}, {"xyz_m", r.xyz}, {"markers", r.markers},
          {"markers_with_height", r.markers_z}};
}

// NaN and infinity are not JSON: null.
nlohmann::json number_or_null(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

}  // namespace

void AlignOptions::validate() const {
  features.validate();
  pairs.validate();
  matching.validate();
  targets.validate();
  naming.validate();
  lens.validate();
  focal_search.validate();
  sfm.validate();
  georef.validate();
}

AlignResult align_layer(Project& project, const std::string& layer_name, const AlignOptions& options) {
  options.validate();
  auto& db = project.db();
  const LayerRecord layer = require_layer(db, layer_name);
  const SiteInfo site = project.site();
  const std::vector<ImageRecord> records = list_images(db, layer.id);
  if (records.size() < 2) {
    throw ProcessingError(fmt::format("layer {} has {} photo(s); alignment needs at least 2 (import "
                                      "30-60 photos per layer)", layer.name, records.size()));
  }
  const auto markers = list_markers(db);
  AlignResult result;

  // Up to date? The key covers photos, survey, clicked and guided observations and
  // options (detected ones are this stage's own output).
  // Version 4: georeference screening 3 and blunder rejection.
  CacheKey key("alignment v4");
  key.add(options);
  for (const auto& r : records) key.add(r.sha256);
  for (const auto& m : markers) key.add(m);
  for (const auto& o : list_observations(db, layer.id)) {
    if (o.source != "detected") key.add(o);
  }
  add_known_calibrations(key, db, records);
  const std::string inputs_key = key.hex();
  if (!options.force) {
    if (auto stored = load_alignment(db, layer); stored && stored->inputs_key == inputs_key) {
      result.skipped = true;
      result.quality = stored->quality;
      return result;
    }
  }

  Stopwatch total;
  nlohmann::json timings;
  const auto cache = project.cache_dir();

  // ---- camera groups: one per camera row (make, model, size, focal setting)
  std::vector<CameraGroup> groups;
  std::vector<std::int64_t> camera_ids;
  std::map<std::int64_t, int> group_of_camera;
  std::vector<ImageInput> inputs;
  std::vector<FeatureImage> feature_images;
  std::vector<std::optional<Intrinsics>> priors;
  std::vector<LensChoice> lens_choices;  // per group
  std::vector<double> times;
  for (const auto& r : records) {
    const std::int64_t cam_id = r.camera_id.value_or(0);
    auto [it, inserted] = group_of_camera.try_emplace(cam_id, int(groups.size()));
    if (inserted) {
      CameraGroup g;
      const auto cam = r.camera_id ? find_camera(db, *r.camera_id) : std::nullopt;
      Intrinsics& k = g.intrinsics;
      k.width = r.width;
      k.height = r.height;
      g.focal_from_exif = cam && cam->focal_px;
      k.fx = k.fy = g.focal_from_exif ? *cam->focal_px : kDefaultFocalFactor * std::max(r.width, r.height);
      k.cx = (r.width - 1) / 2.0;
      k.cy = (r.height - 1) / 2.0;
      g.calibration_source = g.focal_from_exif ? "exif" : "default";
      if (r.camera_id) apply_known_calibration(db, *r.camera_id, g);
      // The lens model: from the lens or the option (a known calibration keeps its own).
      LensChoice choice = choose_lens_model(options.lens, cam);
      apply_lens_choice(g, choice);
      const bool named = cam && !(cam->make.empty() && cam->model.empty());
      log::info("camera {}: {}", named ? fmt::format("{} {} ({}x{})", cam->make, cam->model, r.width, r.height)
                                       : fmt::format("without a name in the EXIF ({}x{})", r.width, r.height),
                choice.reason);
      lens_choices.push_back(choice);
      groups.push_back(g);
      camera_ids.push_back(cam_id);
    }
    inputs.push_back({r.name, it->second});
    feature_images.push_back({r.name, project.dir() / r.media_path, r.sha256});
    const CameraGroup& group = groups[it->second];
    priors.push_back(group.focal_from_exif || group.calibration_known ? std::optional<Intrinsics>(group.intrinsics)
                                                                      : std::nullopt);
    times.push_back(r.captured_at ? double(iso_seconds(*r.captured_at).value_or(0)) : 0.0);
  }

  // ---- features and matches (cached under cache/)
  FeatureExtractionSummary fs;
  const auto keypoints = extract_features(options.features, feature_images, cache, &fs);
  timings["features_s"] = fs.seconds;
  fault::point("process.features.done");
  check_cancelled();
  PairSelectionSummary ps;
  const auto pairs = select_pairs(options.pairs, keypoints, cache, times, &ps);
  MatchingSummary ms;
  const auto matches = match_pairs(options.matching, keypoints, pairs, priors, cache, &ms);
  timings["matching_s"] = ps.seconds + ms.seconds;
  fault::point("process.matching.done");
  log::info("layer {}: {} keypoints in {} photos, {} of {} pairs verified", layer.name, fs.keypoints,
            records.size(), ms.verified, pairs.size());
  if (ms.verified == 0) {
    // Without one matching pair the sparse stage can only say that no initial pair
    // exists; the usual cause is photos without texture (black, blurred, overexposed)
    // or photos that do not overlap, which the keypoint counts tell apart.
    std::vector<std::size_t> by_count(keypoints.size());
    for (std::size_t i = 0; i < by_count.size(); ++i) by_count[i] = i;
    std::stable_sort(by_count.begin(), by_count.end(), [&](std::size_t a, std::size_t b) {
      return keypoints[a].points.size() < keypoints[b].points.size();
    });
    std::string fewest;
    for (std::size_t k = 0; k < std::min<std::size_t>(3, by_count.size()); ++k) {
      fewest += fmt::format("{}{} {}", k ? ", " : "", keypoints[by_count[k]].image,
                            keypoints[by_count[k]].points.size());
    }
    throw InputError(fmt::format(
        "layer {}: no two of its {} photos match ({} of {} pairs verified; {} keypoints in all, fewest: {}): "
        "the photos show too little texture (black, blurred, over- or underexposed) or do not overlap",
        layer.name, records.size(), ms.verified, pairs.size(), fs.keypoints, fewest));
  }
  check_cancelled();

  // ---- coded targets -> detected observations
  std::map<std::string, const MarkerRecord*> marker_by_name;
  for (const auto& m : markers) marker_by_name[m.name] = &m;
  std::vector<ObservationRecord> detected;
  std::set<int> unknown_ids;
  if (options.detect_targets) {
    Stopwatch sw;
    Progress progress("coded targets", records.size());
    for (std::size_t i = 0; i < records.size(); ++i) {
      check_cancelled();
      for (const auto& d : detect_targets(options.targets, feature_images[i].path)) {
        const std::string name = target_name(options.naming, d.id);
        const auto it = marker_by_name.find(name);
        if (it == marker_by_name.end()) {
          unknown_ids.insert(d.id);
          continue;
        }
        detected.push_back({0, it->second->id, records[i].id, d.centre, "detected"});
      }
      progress.step();
    }
    progress.finish();
    timings["targets_s"] = sw.seconds();
    fault::point("process.targets.done");
    if (!unknown_ids.empty()) {
      std::string ids;
      for (int id : unknown_ids) ids += (ids.empty() ? "" : ", ") + std::to_string(id);
      log::warn("coded targets with ids {} have no surveyed marker of that name (rule '{}'); ignored",
                ids, options.naming.rule);
    }
  }

  // ---- incremental reconstruction
  // Photos without EXIF focal length: the default prior, and others when it fails.
  IncrementalSummary is;
  FocalSearchSummary focal_search;
  Reconstruction rec = reconstruct_with_focal_search(
      options.focal_search, groups,
      [&](const std::vector<CameraGroup>& start, IncrementalSummary& summary) {
        return reconstruct_incremental(options.sfm, start, inputs, keypoints, matches, &summary);
      },
      is, focal_search);
  timings["sfm_s"] = is.seconds;
  fault::point("process.sfm.done");
  if (is.registered < 2) {
    throw ProcessingError(fmt::format(
        "layer {}: only {} of {} photos could be aligned; the photos overlap too little or show too "
        "little texture", layer.name, is.registered, records.size()));
  }
  check_cancelled();

  // ---- georeference: clicked, detected and guided observations of known markers
  std::map<std::int64_t, int> index_of_image;
  for (std::size_t i = 0; i < records.size(); ++i) index_of_image[records[i].id] = int(i);
  std::map<std::int64_t, const MarkerRecord*> marker_by_id;
  for (const auto& m : markers) marker_by_id[m.id] = &m;
  std::vector<MarkerObservation> observations;
  std::set<std::int64_t> observed_markers;
  auto add_observation = [&](const ObservationRecord& o) {
    observations.push_back({marker_by_id.at(o.marker_id)->name, index_of_image.at(o.image_id), o.pixel});
    observed_markers.insert(o.marker_id);
  };
  // One observation per marker and photo. A click wins (a person looked), then a
  // coded-target detection, then a guided one (derived from the clicks; 'markers
  // guide' never places one where a detection exists, but a later detection may).
  std::set<std::pair<std::int64_t, std::int64_t>> taken;
  const auto stored_observations = list_observations(db, layer.id);
  for (const auto& o : stored_observations) {
    if (o.source != "clicked") continue;
    taken.emplace(o.marker_id, o.image_id);
    add_observation(o);
  }
  for (const auto& o : detected) {
    if (taken.emplace(o.marker_id, o.image_id).second) add_observation(o);
  }
  for (const auto& o : stored_observations) {
    if (o.source == "guided" && taken.emplace(o.marker_id, o.image_id).second) add_observation(o);
  }
  // What the survey's coordinates alone say (georef/survey.hpp): heights that are all
  // equal are unknown (ODM gcp files from a plan survey write 0.0), not level ground:
  // such markers become horizontal control with a weak height prior. Coordinates rounded
  // to a coarse step carry that rounding whatever sigma the file states: the sigma is
  // raised to it. Both are a warning and a weight, not a failure.
  std::vector<Eigen::Vector3d> surveyed;
  for (const auto& m : markers) surveyed.push_back(m.position);
  const SurveyAssessment survey = assess_survey(surveyed);
  const bool heights_unknown = survey.heights_equal;
  if (heights_unknown && !observed_markers.empty()) {
    log::warn("layer {}: every surveyed marker height is {:.3f} m, taken as unknown: horizontal control "
              "only (height sigma {} m); heights and volumes of this layer are not tied to the survey",
              layer.name, markers.front().position.z(), options.georef.unknown_height_sigma_m);
  }
  if (survey.plan_step_m >= 0.02 && !observed_markers.empty()) {
    log::warn("layer {}: every surveyed E, N is a multiple of {} m: rounded coordinates, weighed with at "
              "least {:.3f} m per axis (the rounding's own sigma, step / sqrt(12))",
              layer.name, survey.plan_step_m, survey.plan_rounding_sigma_m());
  }
  if (survey.height_step_m >= 0.02 && !observed_markers.empty()) {
    log::warn("layer {}: every surveyed height is a multiple of {} m: rounded heights, weighed with at "
              "least {:.3f} m", layer.name, survey.height_step_m, survey.height_rounding_sigma_m());
  }
  std::vector<MarkerConstraint> constraints;
  for (std::int64_t id : observed_markers) {
    const MarkerRecord& m = *marker_by_id.at(id);
    Eigen::Vector3d sigma = m.sigma;
    sigma.x() = std::max(sigma.x(), survey.plan_rounding_sigma_m());
    sigma.y() = std::max(sigma.y(), survey.plan_rounding_sigma_m());
    sigma.z() = std::max(sigma.z(), survey.height_rounding_sigma_m());
    if (heights_unknown) sigma.z() = std::max(sigma.z(), options.georef.unknown_height_sigma_m);
    constraints.push_back({m.name, m.position - site.origin, sigma, m.kind == "control"});
  }
  GeoreferenceSummary gs;
  if (constraints.empty()) {
    gs = keep_arbitrary_frame(rec);
    log::warn("layer {}: no surveyed marker is seen in its photos; the layer is aligned in an "
              "arbitrary local frame at an arbitrary scale (not georeferenced)", layer.name);
  } else {
    gs = georeference(options.georef, constraints, observations, keypoints, rec);
  }
  timings["georeference_s"] = gs.seconds;
  fault::point("process.georeference.done");

  // ---- quality
  const ReconstructionQuality q = measure_quality(rec, keypoints);
  nlohmann::json quality;
  quality["layer"] = layer.name;
  quality["images_total"] = records.size();
  quality["images_registered"] = q.registered_images;
  quality["unregistered"] = is.unregistered;
  quality["points"] = q.points;
  quality["observations"] = q.observations;
  quality["mean_track_length"] = q.mean_track_length;
  quality["reprojection_rmse_px"] = q.reprojection_rmse_px;
  quality["cameras"] = cameras_json(rec, lens_choices, camera_ids);
  if (!focal_search.groups.empty()) quality["focal_search"] = focal_search_json(focal_search);
  quality["gsd_m"] = q.gsd_m;
  quality["georeferenced"] = gs.georeferenced;
  quality["control_rmse"] = rmse_json(gs.control);
  quality["check_rmse"] = rmse_json(gs.check);
  quality["leave_one_out_rmse"] = rmse_json(gs.leave_one_out);
  quality["rejected_markers"] = gs.rejected;
  quality["unusable_markers"] = gs.unusable;
  nlohmann::json blunders = nlohmann::json::array();
  for (const auto& b : gs.blunders) {
    blunders.push_back({{"marker", b.marker},
                        {"image", b.image.empty() ? nlohmann::json(nullptr) : nlohmann::json(b.image)},
                        {"amount", number_or_null(b.amount)},
                        {"unit", b.unit},
                        {"reason", b.reason}});
  }
  quality["blunders"] = blunders;
  quality["observation_sigma_px"] = {{"keypoints", gs.keypoint_sigma_px}, {"markers", gs.marker_sigma_px}};
  quality["detected_observations"] = detected.size();
  quality["pairs"] = {{"selected", pairs.size()}, {"verified", ms.verified}, {"exhaustive", ps.exhaustive}};
  nlohmann::json rows = nlohmann::json::array();
  std::vector<std::pair<std::int64_t, nlohmann::json>> residuals;
  std::map<std::string, std::int64_t> marker_id_by_name;
  for (const auto& m : markers) marker_id_by_name[m.name] = m.id;
  for (const auto& r : gs.residuals) {
    nlohmann::json row = {{"marker", r.name}, {"role", to_string(r.role)}, {"triangulated", r.triangulated},
                          {"height_known", r.height_known}, {"dE", r.dE}, {"dN", r.dN}, {"dZ", r.dZ},
                          {"reprojection_px", r.reprojection_px}, {"images", r.images},
                          {"observed", r.observed}, {"dispersion_m", r.dispersion_m},
                          {"dispersion_px", r.dispersion_px}, {"diagnosis", r.diagnosis},
                          {"distance_misfit_m", number_or_null(r.distance_misfit_m)}};
    row["leave_one_out"] = r.loo ? nlohmann::json{{"dE", r.loo_dE}, {"dN", r.loo_dN}, {"dZ", r.loo_dZ}}
                                 : nlohmann::json(nullptr);
    nlohmann::json obs = nlohmann::json::array();
    for (const auto& o : r.observations) {
      obs.push_back({{"image", o.image_name}, {"to_rays_px", number_or_null(o.to_rays_px)},
                     {"to_survey_px", number_or_null(o.to_survey_px)}, {"sigma_px", o.sigma_px},
                     {"dropped", o.dropped}});
    }
    row["observations"] = obs;
    rows.push_back(row);
    residuals.emplace_back(marker_id_by_name.at(r.name), row);
  }
  quality["markers"] = rows;
  if (!gs.message.empty()) quality["georeference_message"] = gs.message;
  quality["georeference_diagnosis"] = gs.diagnosis;
  // Self-calibration against what was known of each camera (EXIF, a known calibration).
  nlohmann::json checks = nlohmann::json::array();
  for (const auto& c : check_self_calibration(groups, rec.groups)) {
    checks.push_back({{"group", c.group}, {"source", c.source}, {"focal_px", c.focal_px},
                      {"prior_focal_px", c.prior_focal_px}, {"focal_change", c.focal_change},
                      {"corner_shift_px", c.corner_shift_px}, {"finding", c.finding}});
    if (!c.finding.empty()) log::warn("layer {}: camera {}: {}", layer.name, c.group, c.finding);
  }
  quality["calibration_check"] = checks;
  quality["survey"] = {{"plan_step_m", survey.plan_step_m},
                       {"height_step_m", survey.height_step_m},
                       {"heights_equal", survey.heights_equal}};
  timings["total_s"] = total.seconds();
  quality["timings"] = timings;
  quality["peak_memory_mb"] = double(peak_memory_bytes()) / (1024.0 * 1024.0);

  // ---- store, in one transaction with the detected observations
  Transaction tx(db);
  db.prepare(
        "DELETE FROM observations WHERE source = 'detected' AND image_id IN (SELECT id FROM images "
        "WHERE layer_id = ?)")
      .bind_all(layer.id)
      .run();
  for (const auto& o : detected) upsert_observation(db, o);
  fault::point("process.align.observations_replaced");
  StoredAlignment stored;
  stored.rec = rec;
  stored.images = records;
  stored.camera_ids = camera_ids;
  stored.quality = quality;
  stored.inputs_key = inputs_key;
  store_alignment(db, layer, site, stored, residuals);
  fault::point("process.align.before_commit");
  tx.commit();
  fault::point("process.align.after_commit");
  result.quality = quality;
  return result;
}

}  // namespace strata
