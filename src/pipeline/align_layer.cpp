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
#include "project/review_records.hpp"
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

// What the alignment starts from: the layer's photos, the survey, and what
// comes out of each step on the way to the georeferenced model.
struct AlignmentInputs {
  LayerRecord layer;
  SiteInfo site;
  std::vector<ImageRecord> records;
  std::vector<MarkerRecord> markers;
  // (marker, image) of observations a person rejected (observation_reviews): neither a
  // detection nor a guided position there is used.
  std::set<std::pair<std::int64_t, std::int64_t>> rejected;
};

// One camera group per camera row (make, model, size, focal setting), and per photo
// its group, feature input, focal prior and capture time.
struct CameraSetup {
  std::vector<CameraGroup> groups;
  std::vector<std::int64_t> camera_ids;   // per group
  std::vector<LensChoice> lens_choices;   // per group
  std::vector<ImageInput> inputs;         // per photo
  std::vector<FeatureImage> feature_images;
  std::vector<std::optional<Intrinsics>> priors;
  std::vector<double> times;              // seconds since the epoch, 0 unknown
};

struct MatchedPhotos {
  std::vector<ImageKeypoints> keypoints;
  std::vector<ImagePair> pairs;
  std::vector<PairMatches> matches;
  FeatureExtractionSummary features;
  PairSelectionSummary selection;
  MatchingSummary matching;
};

// The georeference step's result, with what the survey's coordinates said.
struct GeoreferenceStep {
  GeoreferenceSummary summary;
  SurveyAssessment survey;
};

// What of a surveyed marker the alignment depends on, field for field as MarkerRecord
// had it before schema 15: `sigma_stated` only moves the report's verdict, and adding
// it to the key would have re-aligned every layer of every project after the upgrade.
struct MarkerInputs {
  std::int64_t id;
  std::string name;
  Eigen::Vector3d position, sigma;
  std::string kind, source;
};

// Up to date? The key covers photos, survey, clicked and guided observations and
// options (detected ones are this stage's own output).
std::string alignment_key(Database& db, const AlignmentInputs& in, const AlignOptions& options) {
  CacheKey key("alignment v4");
  key.add(options);
  for (const auto& r : in.records) key.add(r.sha256);
  for (const auto& m : in.markers) key.add(MarkerInputs{m.id, m.name, m.position, m.sigma, m.kind, m.source});
  for (const auto& o : list_observations(db, in.layer.id)) {
    if (o.source != "detected") key.add(o);
  }
  // Only when there are some, so that the key of a layer without reviews is unchanged.
  for (const auto& [marker, image] : in.rejected) key.add("rejected").add(marker).add(image);
  add_known_calibrations(key, db, in.records);
  return key.hex();
}

CameraGroup starting_group(Database& db, const ImageRecord& r, const std::optional<CameraRecord>& cam,
                           const LensChoiceOptions& lens, LensChoice& choice) {
  CameraGroup g;
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
  choice = choose_lens_model(lens, cam);
  apply_lens_choice(g, choice);
  const bool named = cam && !(cam->make.empty() && cam->model.empty());
  log::info("camera {}: {}", named ? fmt::format("{} {} ({}x{})", cam->make, cam->model, r.width, r.height)
                                   : fmt::format("without a name in the EXIF ({}x{})", r.width, r.height),
            choice.reason);
  return g;
}

CameraSetup set_up_cameras(Project& project, const std::vector<ImageRecord>& records, const AlignOptions& options) {
  auto& db = project.db();
  CameraSetup s;
  std::map<std::int64_t, int> group_of_camera;
  for (const auto& r : records) {
    const std::int64_t cam_id = r.camera_id.value_or(0);
    auto [it, inserted] = group_of_camera.try_emplace(cam_id, int(s.groups.size()));
    if (inserted) {
      const auto cam = r.camera_id ? find_camera(db, *r.camera_id) : std::nullopt;
      LensChoice choice;
      s.groups.push_back(starting_group(db, r, cam, options.lens, choice));
      s.lens_choices.push_back(choice);
      s.camera_ids.push_back(cam_id);
    }
    s.inputs.push_back({r.name, it->second});
    s.feature_images.push_back({r.name, project.dir() / r.media_path, r.sha256});
    const CameraGroup& group = s.groups[it->second];
    s.priors.push_back(group.focal_from_exif || group.calibration_known ? std::optional<Intrinsics>(group.intrinsics)
                                                                        : std::nullopt);
    s.times.push_back(r.captured_at ? double(iso_seconds(*r.captured_at).value_or(0)) : 0.0);
  }
  return s;
}

// Without one matching pair the sparse stage can only say that no initial pair
// exists; the usual cause is photos without texture (black, blurred, overexposed)
// or photos that do not overlap, which the keypoint counts tell apart.
InputError no_matching_pair(const std::string& layer, const MatchedPhotos& m) {
  const auto& keypoints = m.keypoints;
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
  return InputError(fmt::format(
      "layer {}: no two of its {} photos match ({} of {} pairs verified; {} keypoints in all, fewest: {}): "
      "the photos show too little texture (black, blurred, over- or underexposed) or do not overlap",
      layer, keypoints.size(), m.matching.verified, m.pairs.size(), m.features.keypoints, fewest));
}

// Features and matches (cached under cache/).
MatchedPhotos match_photos(const AlignOptions& options, const CameraSetup& cameras, const std::string& layer,
                           const std::filesystem::path& cache, AlignmentTimings& timings) {
  MatchedPhotos m;
  m.keypoints = extract_features(options.features, cameras.feature_images, cache, &m.features);
  timings.features_s = m.features.seconds;
  fault::point("process.features.done");
  check_cancelled();
  m.pairs = select_pairs(options.pairs, m.keypoints, cache, cameras.times, &m.selection);
  m.matches = match_pairs(options.matching, m.keypoints, m.pairs, cameras.priors, cache, &m.matching);
  timings.matching_s = m.selection.seconds + m.matching.seconds;
  fault::point("process.matching.done");
  log::info("layer {}: {} keypoints in {} photos, {} of {} pairs verified", layer, m.features.keypoints,
            m.keypoints.size(), m.matching.verified, m.pairs.size());
  if (m.matching.verified == 0) throw no_matching_pair(layer, m);
  check_cancelled();
  return m;
}

// Coded targets in the photos -> detected observations of the surveyed markers.
std::vector<ObservationRecord> detect_coded_targets(const AlignOptions& options, const AlignmentInputs& in,
                                                    const CameraSetup& cameras, AlignmentTimings& timings) {
  std::vector<ObservationRecord> detected;
  if (!options.detect_targets) return detected;
  std::map<std::string, const MarkerRecord*> marker_by_name;
  for (const auto& m : in.markers) marker_by_name[m.name] = &m;
  std::set<int> unknown_ids;
  Stopwatch sw;
  Progress progress("coded targets", in.records.size());
  for (std::size_t i = 0; i < in.records.size(); ++i) {
    check_cancelled();
    for (const auto& d : detect_targets(options.targets, cameras.feature_images[i].path)) {
      const auto it = marker_by_name.find(target_name(options.naming, d.id));
      if (it == marker_by_name.end()) {
        unknown_ids.insert(d.id);
        continue;
      }
      if (in.rejected.count({it->second->id, in.records[i].id})) continue;  // a person said it is not the marker
      detected.push_back({0, it->second->id, in.records[i].id, d.centre, "detected"});
    }
    progress.step();
  }
  progress.finish();
  timings.targets_s = sw.seconds();
  fault::point("process.targets.done");
  if (!unknown_ids.empty()) {
    std::string ids;
    for (int id : unknown_ids) ids += (ids.empty() ? "" : ", ") + std::to_string(id);
    log::warn("coded targets with ids {} have no surveyed marker of that name (rule '{}'); ignored", ids,
              options.naming.rule);
  }
  return detected;
}

// One observation per marker and photo. A click wins (a person looked), then a
// coded-target detection, then a guided one (derived from the clicks; 'markers
// guide' never places one where a detection exists, but a later detection may).
std::vector<ObservationRecord> chosen_observations(Database& db, const AlignmentInputs& in,
                                                   const std::vector<ObservationRecord>& detected) {
  std::vector<ObservationRecord> chosen;
  std::set<std::pair<std::int64_t, std::int64_t>> taken;
  const auto stored = list_observations(db, in.layer.id);
  for (const auto& o : stored) {
    if (o.source != "clicked") continue;
    taken.emplace(o.marker_id, o.image_id);
    chosen.push_back(o);
  }
  for (const auto& o : detected) {
    if (taken.emplace(o.marker_id, o.image_id).second) chosen.push_back(o);
  }
  for (const auto& o : stored) {
    if (o.source == "guided" && !in.rejected.count({o.marker_id, o.image_id}) &&
        taken.emplace(o.marker_id, o.image_id).second) {
      chosen.push_back(o);
    }
  }
  return chosen;
}

// What the survey's coordinates alone say (georef/survey.hpp): heights that are all
// equal are unknown (ODM gcp files from a plan survey write 0.0), not level ground:
// such markers become horizontal control with a weak height prior. Coordinates rounded
// to a coarse step carry that rounding whatever sigma the file states: the sigma is
// raised to it. Both are a warning and a weight, not a failure.
SurveyAssessment assess_markers(const std::vector<MarkerRecord>& markers) {
  std::vector<Eigen::Vector3d> surveyed;
  for (const auto& m : markers) surveyed.push_back(m.position);
  return assess_survey(surveyed);
}

void warn_about_survey(const AlignmentInputs& in, const SurveyAssessment& survey, const AlignOptions& options) {
  const std::string& layer = in.layer.name;
  if (survey.heights_equal) {
    log::warn("layer {}: every surveyed marker height is {:.3f} m, taken as unknown: horizontal control "
              "only (height sigma {} m); heights and volumes of this layer are not tied to the survey",
              layer, in.markers.front().position.z(), options.georef.unknown_height_sigma_m);
  }
  if (survey.plan_coarse()) {
    log::warn("layer {}: every surveyed E, N is a multiple of {} m: rounded coordinates, weighed with at "
              "least {:.3f} m per axis (the rounding's own sigma, step / sqrt(12))",
              layer, survey.plan_step_m, survey.plan_rounding_sigma_m());
  }
  if (survey.height_coarse()) {
    log::warn("layer {}: every surveyed height is a multiple of {} m: rounded heights, weighed with at "
              "least {:.3f} m", layer, survey.height_step_m, survey.height_rounding_sigma_m());
  }
}

std::vector<MarkerConstraint> marker_constraints(const AlignmentInputs& in, const std::set<std::int64_t>& observed,
                                                 const SurveyAssessment& survey, const AlignOptions& options) {
  std::map<std::int64_t, const MarkerRecord*> marker_by_id;
  for (const auto& m : in.markers) marker_by_id[m.id] = &m;
  std::vector<MarkerConstraint> constraints;
  for (std::int64_t id : observed) {
    const MarkerRecord& m = *marker_by_id.at(id);
    Eigen::Vector3d sigma = m.sigma;
    sigma.x() = std::max(sigma.x(), survey.plan_rounding_sigma_m());
    sigma.y() = std::max(sigma.y(), survey.plan_rounding_sigma_m());
    sigma.z() = std::max(sigma.z(), survey.height_rounding_sigma_m());
    if (survey.heights_equal) sigma.z() = std::max(sigma.z(), options.georef.unknown_height_sigma_m);
    constraints.push_back({m.name, m.position - in.site.origin, sigma, m.kind == "control"});
  }
  return constraints;
}

// Clicked, detected and guided observations of known markers -> the similarity
// (and adjustment) onto the survey, or an arbitrary frame when no marker is seen.
GeoreferenceStep georeference_layer(Database& db, const AlignOptions& options, const AlignmentInputs& in,
                                    const std::vector<ObservationRecord>& detected, const MatchedPhotos& m,
                                    Reconstruction& rec) {
  std::map<std::int64_t, int> index_of_image;
  for (std::size_t i = 0; i < in.records.size(); ++i) index_of_image[in.records[i].id] = int(i);
  std::map<std::int64_t, std::string> marker_name;
  for (const auto& mk : in.markers) marker_name[mk.id] = mk.name;
  std::vector<MarkerObservation> observations;
  std::set<std::int64_t> observed;
  for (const auto& o : chosen_observations(db, in, detected)) {
    observations.push_back({marker_name.at(o.marker_id), index_of_image.at(o.image_id), o.pixel});
    observed.insert(o.marker_id);
  }
  GeoreferenceStep step;
  step.survey = assess_markers(in.markers);
  if (observed.empty()) {
    step.summary = keep_arbitrary_frame(rec);
    log::warn("layer {}: no surveyed marker is seen in its photos; the layer is aligned in an "
              "arbitrary local frame at an arbitrary scale (not georeferenced)", in.layer.name);
  } else {
    warn_about_survey(in, step.survey, options);
    step.summary = georeference(options.georef, marker_constraints(in, observed, step.survey, options),
                                observations, m.keypoints, rec);
  }
  fault::point("process.georeference.done");
  return step;
}

std::vector<CameraFigures> camera_figures(const Reconstruction& rec, const CameraSetup& cameras) {
  std::vector<CameraFigures> out;
  for (std::size_t g = 0; g < rec.groups.size(); ++g) {
    const CameraGroup& group = rec.groups[g];
    CameraFigures c;
    if (g < cameras.camera_ids.size()) c.camera_id = cameras.camera_ids[g];
    c.intrinsics = group.intrinsics;
    if (g < cameras.lens_choices.size()) c.lens = cameras.lens_choices[g];
    c.focal_source = group.calibration_known ? "calibration" : group.focal_from_exif ? "exif" : "default";
    c.calibration_source = group.calibration_source;
    c.calibration_fixed = group.calibration_fixed;
    out.push_back(c);
  }
  return out;
}

AlignmentQuality alignment_quality(const AlignmentInputs& in, const CameraSetup& cameras, const MatchedPhotos& m,
                                   const IncrementalSummary& is, const FocalSearchSummary& focal_search,
                                   const Reconstruction& rec, const GeoreferenceStep& geo,
                                   std::size_t detected) {
  const GeoreferenceSummary& gs = geo.summary;
  AlignmentQuality q;
  q.layer = in.layer.name;
  q.images_total = in.records.size();
  q.sparse = measure_quality(rec, m.keypoints);
  q.unregistered = is.unregistered;
  q.cameras = camera_figures(rec, cameras);
  if (!focal_search.groups.empty()) q.focal_search = focal_search;
  q.georeferenced = gs.georeferenced;
  q.control_rmse = gs.control;
  q.check_rmse = gs.check;
  q.leave_one_out_rmse = gs.leave_one_out;
  q.rejected_markers = gs.rejected;
  q.unusable_markers = gs.unusable;
  q.blunders = gs.blunders;
  q.keypoint_sigma_px = gs.keypoint_sigma_px;
  q.marker_sigma_px = gs.marker_sigma_px;
  q.detected_observations = detected;
  q.pairs = {m.pairs.size(), m.matching.verified, m.selection.exhaustive};
  q.markers = gs.residuals;
  q.georeference_message = gs.message;
  q.georeference_diagnosis = gs.diagnosis;
  // Self-calibration against what was known of each camera (EXIF, a known calibration).
  q.calibration_check = check_self_calibration(cameras.groups, rec.groups);
  for (const auto& c : q.calibration_check) {
    if (!c.finding.empty()) log::warn("layer {}: camera {}: {}", q.layer, c.group, c.finding);
  }
  q.survey = geo.survey;
  return q;
}

// Cameras, points, residuals and quality, in one transaction with the detected
// observations.
void store_layer_alignment(Database& db, const AlignmentInputs& in, const CameraSetup& cameras,
                           const Reconstruction& rec, const std::vector<ObservationRecord>& detected,
                           const AlignmentQuality& quality, const std::string& inputs_key) {
  std::map<std::string, std::int64_t> marker_id_by_name;
  for (const auto& m : in.markers) marker_id_by_name[m.name] = m.id;
  Transaction tx(db);
  db.prepare(
        "DELETE FROM observations WHERE source = 'detected' AND image_id IN (SELECT id FROM images "
        "WHERE layer_id = ?)")
      .bind_all(in.layer.id)
      .run();
  for (const auto& o : detected) upsert_observation(db, o);
  fault::point("process.align.observations_replaced");
  StoredAlignment stored;
  stored.rec = rec;
  stored.images = in.records;
  stored.camera_ids = cameras.camera_ids;
  stored.quality = quality;
  stored.inputs_key = inputs_key;
  store_alignment(db, in.layer, in.site, stored, marker_id_by_name);
  fault::point("process.align.before_commit");
  tx.commit();
  fault::point("process.align.after_commit");
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
  AlignmentInputs in{require_layer(db, layer_name), project.site(), {}, list_markers(db), {}};
  in.records = list_images(db, in.layer.id);
  for (const auto& r : list_observation_reviews(db, in.layer.id)) {
    if (r.verdict == "rejected") in.rejected.emplace(r.marker_id, r.image_id);
  }
  if (in.records.size() < 2) {
    throw ProcessingError(fmt::format("layer {} has {} photo(s); alignment needs at least 2 (import "
                                      "30-60 photos per layer)", in.layer.name, in.records.size()));
  }
  const std::string inputs_key = alignment_key(db, in, options);
  if (!options.force) {
    if (auto stored = load_alignment(db, in.layer); stored && stored->inputs_key == inputs_key) {
      return {true, stored->quality};
    }
  }

  Stopwatch total;
  AlignmentTimings timings;
  const CameraSetup cameras = set_up_cameras(project, in.records, options);
  const MatchedPhotos matched = match_photos(options, cameras, in.layer.name, project.cache_dir(), timings);
  const auto detected = detect_coded_targets(options, in, cameras, timings);

  // Photos without EXIF focal length: the default prior, and others when it fails.
  IncrementalSummary is;
  FocalSearchSummary focal_search;
  Reconstruction rec = reconstruct_with_focal_search(
      options.focal_search, cameras.groups,
      [&](const std::vector<CameraGroup>& start, IncrementalSummary& summary) {
        return reconstruct_incremental(options.sfm, start, cameras.inputs, matched.keypoints, matched.matches,
                                       &summary);
      },
      is, focal_search);
  timings.sfm_s = is.seconds;
  fault::point("process.sfm.done");
  if (is.registered < 2) {
    throw ProcessingError(fmt::format(
        "layer {}: only {} of {} photos could be aligned; the photos overlap too little or show too "
        "little texture", in.layer.name, is.registered, in.records.size()));
  }
  check_cancelled();

  const GeoreferenceStep geo = georeference_layer(db, options, in, detected, matched, rec);
  timings.georeference_s = geo.summary.seconds;
  AlignmentQuality quality =
      alignment_quality(in, cameras, matched, is, focal_search, rec, geo, detected.size());
  timings.total_s = total.seconds();
  quality.timings = timings;
  quality.peak_memory_mb = double(peak_memory_bytes()) / (1024.0 * 1024.0);
  store_layer_alignment(db, in, cameras, rec, detected, quality, inputs_key);
  return {false, quality};
}

}  // namespace strata
