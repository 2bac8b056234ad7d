#include "pipeline/register_depth.hpp"

#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/log.hpp"
#include "core/progress.hpp"
#include "core/resources.hpp"
#include "core/statistics.hpp"
#include "importers/depth/depth_files.hpp"
#include "pipeline/depth_frames.hpp"
#include "project/database.hpp"
#include "project/records.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <map>
#include <optional>

namespace strata {
namespace {

constexpr const char* kStage = "register.depth";

std::vector<DepthSequenceRecord> sequences_to_register(Database& db, const LayerRecord& layer,
                                                       const std::optional<std::string>& name) {
  std::vector<DepthSequenceRecord> out;
  for (const auto& s : list_depth_sequences(db, layer.id))
    if (!name || s.name == *name) out.push_back(s);
  if (out.empty()) {
    throw InputError(name ? fmt::format("{}: layer {} has no depth sequence named '{}'", kStage, layer.name, *name)
                          : fmt::format("{}: layer {} has no depth sequence (strata import depth)", kStage,
                                        layer.name));
  }
  return out;
}

// Why a frame's fit cannot be trusted, or empty.
std::string refusal(const DepthFrameResult& r, double noise_k, const DepthRegistrationOptions& o) {
  const double expected = std::sqrt(2.0) * noise_k * r.median_depth_m * r.median_depth_m;
  if (!r.fit.converged) return fmt::format("no convergence in {} iterations", r.fit.iterations);
  if (r.fit.inlier_share < o.min_inlier_share)
    return fmt::format("too little overlap with the other frames ({:.0f} % of its points within the gate, at "
                       "least {:.0f} % needed)",
                       100 * r.fit.inlier_share, 100 * o.min_inlier_share);
  if (r.fit.rms_m > o.max_rms_ratio * expected)
    return fmt::format("RMS residual {:.1f} mm, more than {} x the {:.1f} mm its depth noise explains", 1000 * r.fit.rms_m,
                       o.max_rms_ratio, 1000 * expected);
  return {};
}

ScanBounds bounds_under(const std::vector<Eigen::Vector3d>& points, const Eigen::Isometry3d& pose) {
  ScanBounds b{Eigen::Vector3d::Constant(HUGE_VAL), Eigen::Vector3d::Constant(-HUGE_VAL)};
  for (const auto& p : points) {
    const Eigen::Vector3d q = pose * p;
    b.min = b.min.cwiseMin(q);
    b.max = b.max.cwiseMax(q);
  }
  return b;
}

// A frame as the registration reads it.
struct FrameInput {
  std::vector<Eigen::Vector3d> points;                   // thinned, camera frame
  std::optional<RgbdFeatures> features;                  // with a colour frame, when features are used
  std::vector<std::pair<std::string, Eigen::Vector3d>> targets;  // markers seen, camera frame (markers datum)
};

RgbdCamera rgbd_camera(const DepthSequenceRecord& seq) {
  const DepthIntrinsics& k = seq.intrinsics;
  return {k.width, k.height, k.fx, k.fy, k.cx, k.cy, seq.depth_scale_m, seq.noise_k};
}

// The coded targets of a colour frame with a depth at their centre: the median of the
// depths within `window` pixels of it (the print is flat; a few pixels average the
// noise), back-projected to the camera frame. Targets whose id names no marker, or
// with no depth there, are left out.
std::vector<std::pair<std::string, Eigen::Vector3d>> targets_with_depth(const std::vector<std::uint8_t>& grey,
                                                                        const DepthImage& depth,
                                                                        const DepthSequenceRecord& seq,
                                                                        const DepthRegistrationOptions& o) {
  const DepthIntrinsics& k = seq.intrinsics;
  std::vector<std::pair<std::string, Eigen::Vector3d>> out;
  for (const TargetDetection& t : detect_targets(o.targets, grey.data(), k.width, k.height)) {
    const std::string name = target_name(o.naming, t.id);
    if (name.empty()) continue;
    const int u0 = int(std::lround(t.centre.x())), v0 = int(std::lround(t.centre.y()));
    std::vector<double> z;
    for (int v = v0 - o.marker_window_px; v <= v0 + o.marker_window_px; ++v)
      for (int u = u0 - o.marker_window_px; u <= u0 + o.marker_window_px; ++u) {
        if (u < 0 || v < 0 || u >= k.width || v >= k.height) continue;
        const std::uint16_t d = depth.values[std::size_t(v) * std::size_t(k.width) + std::size_t(u)];
        if (d > 0) z.push_back(d * seq.depth_scale_m);
      }
    if (z.size() < 3) continue;  // an edge or a hole: no depth to trust
    const double zc = median_in_place(z);
    out.emplace_back(name, Eigen::Vector3d((t.centre.x() - k.cx) * zc / k.fx, (t.centre.y() - k.cy) * zc / k.fy, zc));
  }
  return out;
}

// Reads every frame: its thinned points and figures into `out.frames`, its colour
// frame's features and markers when they are needed.
std::vector<FrameInput> read_frames(Project& project, const DepthSequenceRecord& seq,
                                    const std::vector<DepthFrameRecord>& records, bool features, bool markers,
                                    const DepthRegistrationOptions& o, DepthSequenceResult& out) {
  std::vector<FrameInput> frames;
  Progress progress(fmt::format("depth: reading {}", seq.name), records.size());
  for (const auto& f : records) {
    check_cancelled();
    FrameInput in;
    std::vector<Eigen::Vector3d> points = depth_frame_points(project.dir() / f.media_path, seq);
    std::erase_if(points, [&](const Eigen::Vector3d& p) { return p.z() > o.max_depth_m; });
    if (points.empty())
      throw InputError(fmt::format("{}: sequence '{}': frame {} has no depth nearer than {} m", kStage, seq.name,
                                   f.name, o.max_depth_m));
    std::vector<double> z;
    z.reserve(points.size());
    for (const auto& p : points) z.push_back(p.z());
    DepthFrameResult r;
    r.frame = f;
    r.has_recorded = f.recorded_pose.has_value();
    if (f.recorded_pose) r.recorded = *f.recorded_pose;
    r.median_depth_m = median_in_place(z);
    in.points = voxel_subsample(points, o.frame_voxel_m);
    r.points_used = in.points.size();
    if (f.colour_media_path && (features || markers)) {
      const DepthImage depth = read_depth_png(project.dir() / f.media_path, seq.intrinsics);
      const std::vector<std::uint8_t> grey =
          read_grey_frame(project.dir() / *f.colour_media_path, seq.intrinsics.width, seq.intrinsics.height);
      if (features) in.features = extract_rgbd_features(grey, depth.values, rgbd_camera(seq), o.features);
      if (markers) in.targets = targets_with_depth(grey, depth, seq, o);
      r.markers_seen = int(in.targets.size());
    }
    frames.push_back(std::move(in));
    out.frames.push_back(std::move(r));
    progress.step();
  }
  progress.finish();
  return frames;
}

// The motion of frame b relative to frame a from their features: the usual match, else
// the wide one (a corner turned between the two frames: the ratio test leaves too few
// matches; docs/range.md, "Depth sequences, measured").
RgbdMotion feature_motion(const FrameInput& a, const FrameInput& b, const DepthRegistrationOptions& o) {
  if (!a.features || !b.features) return {};
  RgbdMotion m = rgbd_relative_motion(*a.features, *b.features, o.features);
  if (!m.found) {
    RgbdMotion wide = rgbd_relative_motion(*a.features, *b.features, o.wide_features);
    if (wide.found) m = wide;
  }
  return m;
}

// The step that starts each frame's fit (frame i relative to frame i - 1), by the
// preference of `start`: the features' motion, the recorded one, or neither (constant
// velocity). Records in each frame what was chosen.
std::vector<std::optional<Eigen::Isometry3d>> choose_steps(const std::vector<FrameInput>& frames,
                                                           const DepthRegistrationOptions& o,
                                                           DepthSequenceResult& out) {
  std::vector<std::optional<Eigen::Isometry3d>> steps(frames.size());
  for (std::size_t i = 1; i < frames.size(); ++i) {
    DepthFrameResult& r = out.frames[i];
    std::optional<Eigen::Isometry3d> recorded;
    if (r.has_recorded && out.frames[i - 1].has_recorded)
      recorded = Eigen::Isometry3d(out.frames[i - 1].recorded).inverse() * Eigen::Isometry3d(r.recorded);
    if (o.start == DepthStart::features || !recorded) r.features = feature_motion(frames[i - 1], frames[i], o);
    else if (frames[i].features && frames[i - 1].features)
      r.features = rgbd_relative_motion(*frames[i - 1].features, *frames[i].features, o.features);
    const bool use_features = r.features.found && (o.start == DepthStart::features || !recorded);
    if (use_features) {
      steps[i] = r.features.motion;
      r.start = "features";
    } else if (recorded) {
      steps[i] = recorded;
      r.start = "recorded";
    } else {
      r.start = "constant-velocity";
    }
  }
  return steps;
}

// Why frame i's tracking fit shows the tracking was lost, or empty: it kept much less
// of its points within the gate than the frames tracked before it (the median of the
// last kRecentFrames), or did not converge and kept clearly less.
std::string tracking_lost(const std::vector<IcpSummary>& fits, std::size_t i) {
  constexpr std::size_t kRecentFrames = 5;
  constexpr double kLostShare = 0.6, kUnconvergedShare = 0.75;
  std::vector<double> shares;
  for (std::size_t k = i; k-- > 1 && shares.size() < kRecentFrames;) shares.push_back(fits[k].inlier_share);
  if (shares.empty()) return {};
  const double typical = median_in_place(shares), share = fits[i].inlier_share;
  if (share < kLostShare * typical || (!fits[i].converged && share < kUnconvergedShare * typical))
    return fmt::format("{:.0f} % of its points within the gate of the model, against {:.0f} % for the frames "
                       "before it{}",
                       100 * share, 100 * typical,
                       fits[i].converged ? "" : fmt::format(", no convergence in {} iterations", fits[i].iterations));
  return {};
}

// Each marker's position in the sequence's frame: its camera-frame points moved by
// the frames' poses, the median per axis over the frames that saw it.
std::vector<DepthMarkerSighting> locate_markers(const std::vector<FrameInput>& frames,
                                                const std::vector<Eigen::Isometry3d>& poses) {
  std::map<std::string, std::array<std::vector<double>, 3>> seen;
  for (std::size_t i = 0; i < frames.size(); ++i)
    for (const auto& [name, camera] : frames[i].targets) {
      const Eigen::Vector3d p = poses[i] * camera;
      for (int a = 0; a < 3; ++a) seen[name][std::size_t(a)].push_back(p[a]);
    }
  std::vector<DepthMarkerSighting> out;
  for (auto& [name, axes] : seen) {
    DepthMarkerSighting m;
    m.name = name;
    m.frames = int(axes[0].size());
    for (int a = 0; a < 3; ++a) m.position[a] = median_in_place(axes[std::size_t(a)]);
    out.push_back(std::move(m));
  }
  return out;
}

// The surveyed markers the sequence saw (out.markers), paired by name with the survey.
MarkerPairs surveyed_sightings(Project& project, DepthSequenceResult& out) {
  std::vector<NamedPoint> seen;
  for (const DepthMarkerSighting& m : out.markers) seen.push_back({m.name, m.position});
  MarkerPairs pairs = pair_with_markers(project, seen);
  out.unmatched = pairs.unmatched;
  return pairs;
}

// The refusal when fewer than 3 surveyed markers were seen and no other datum is at
// hand; `no_surface`: why the photo surface of `layer` cannot place it either, or empty.
[[noreturn]] void refuse_too_few_markers(const DepthSequenceRecord& seq, const DepthSequenceResult& out,
                                         std::size_t surveyed, const std::string& layer,
                                         const std::string& no_surface) {
  std::vector<std::string> names;
  for (const DepthMarkerSighting& m : out.markers) names.push_back(fmt::format("{} ({} frames)", m.name, m.frames));
  throw InputError(fmt::format(
      "{}: sequence '{}': {} surveyed marker(s) seen in its colour frames{}{}; at least 3 are needed to place a "
      "sequence without recorded poses in the site frame{}. Nothing was changed. Record the markers in the "
      "sequence, {}or import it with --poses",
      kStage, seq.name, surveyed, names.empty() ? std::string() : ": ", fmt::join(names, ", "),
      no_surface.empty() ? std::string() : ", and " + no_surface,
      no_surface.empty() ? std::string()
                         : fmt::format("process the layer's photos first (strata process DIR --layer {} --until "
                                       "dense), ",
                                       layer)));
}

// The sequence's frame -> the site frame, fitted on the surveyed markers it saw.
Eigen::Isometry3d place_on_markers(const MarkerPairs& pairs, const DepthSequenceRecord& seq,
                                   const DepthRegistrationOptions& o, DepthSequenceResult& out) {
  if (pairs.names.size() < 3) refuse_too_few_markers(seq, out, pairs.names.size(), {}, {});
  out.marker_fit = fit_on_markers(pairs, o.marker_fit, fmt::format("{}: sequence '{}'", kStage, seq.name),
                                  "the markers seen in its colour frames");
  for (const TargetResidual& t : out.marker_fit->targets)
    if (!t.inlier)
      log::warn("{}: sequence '{}': marker {} is {:.1f} mm from its survey, beyond the {:.1f} mm gate: left out",
                kStage, seq.name, t.name, 1000 * t.residual_m, 1000 * out.marker_fit->gate_m);
  return Eigen::Isometry3d(out.marker_fit->pose);
}

// Why the photo surface cannot place the sequence (its file is missing), or empty.
std::string surface_missing(Project& project, const LayerRecord& layer, const ScanRegistrationOptions& o) {
  const std::filesystem::path file = reference_surface_file(project, layer.name, o.against);
  if (std::filesystem::exists(file)) return {};
  return fmt::format("there is no photo surface to fit it to ({} is missing)",
                     std::filesystem::relative(file, project.dir()).string());
}

// The whole sequence as one cloud in its frame (frame 0's camera): every frame's
// thinned points moved by its pose, thinned again as a scan is.
std::vector<Eigen::Vector3d> sequence_cloud(const std::vector<FrameInput>& frames,
                                            const std::vector<Eigen::Isometry3d>& poses, double voxel_m) {
  std::vector<Eigen::Vector3d> all;
  for (std::size_t i = 0; i < frames.size(); ++i)
    for (const auto& p : frames[i].points) all.push_back(poses[i] * p);
  return voxel_subsample(all, voxel_m);
}

// The rotation that turns the sequence's up direction to +z: the normal of its ground
// (the plane most of its points lie on), on the side of the cameras. A hand-held
// sequence's frame is not levelled; the coarse search of the scans assumes it is.
Eigen::Matrix3d level_on_ground(const std::vector<Eigen::Vector3d>& cloud, const std::vector<Eigen::Isometry3d>& poses,
                                const DepthRegistrationOptions& o, DepthSequenceResult& out) {
  const PlaneFit ground = dominant_plane(cloud, o.level_tolerance_m);
  double above = 0;  // mean height of the cameras over the ground along its normal
  for (const auto& p : poses) above += ground.normal.dot(p.translation() - ground.point);
  const Eigen::Vector3d up = above >= 0 ? ground.normal : Eigen::Vector3d(-ground.normal);
  const Eigen::Matrix3d level = Eigen::Quaterniond::FromTwoVectors(up, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  out.ground_share = ground.inlier_share;
  out.level_rad = std::acos(std::clamp(up.z(), -1.0, 1.0));
  return level;
}

// The sequence's frame -> the site frame, fitted to the photo surface as an
// unregistered scan is: levelled on its ground, then the coarse yaw search and ICP,
// refused on the scans' checks (the sequence's noise: k z^2 at the frames' median depth).
Eigen::Isometry3d place_on_surface(Project& project, const LayerRecord& layer, const DepthSequenceRecord& seq,
                                   const std::vector<FrameInput>& frames, const std::vector<Eigen::Isometry3d>& poses,
                                   const DepthRegistrationOptions& o, DepthSequenceResult& out) {
  const ReferenceSurface surface = load_reference_surface(project, layer.name, o.surface.against, o.surface);
  const std::vector<Eigen::Vector3d> cloud = sequence_cloud(frames, poses, o.surface.scan_voxel_m);
  const Eigen::Matrix3d level = level_on_ground(cloud, poses, o, out);
  std::vector<Eigen::Vector3d> levelled;
  levelled.reserve(cloud.size());
  for (const auto& p : cloud) levelled.push_back(level * p);
  SurfaceFit fit = fit_to_surface(levelled, surface, o.surface);
  std::vector<double> depths;
  for (const DepthFrameResult& r : out.frames) depths.push_back(r.median_depth_m);
  const double z = median_in_place(depths), sigma_m = seq.noise_k * z * z;
  if (const std::string why = surface_fit_refusal(sigma_m, fit.icp, o.surface); !why.empty())
    throw InputError(fmt::format("{}: sequence '{}': cannot place it on the photo surface of layer {}: {}. Nothing "
                                 "was changed. Record surveyed markers in the sequence (3 or more), or import it "
                                 "with --poses",
                                 kStage, seq.name, surface.layer, why));
  Eigen::Isometry3d to_site = fit.icp.pose;
  to_site.linear() = fit.icp.pose.linear() * level;
  out.surface_layer = surface.layer;
  out.surface_points_used = cloud.size();
  out.surface_transform = to_site.matrix();
  out.surface_fit = std::move(fit);
  return to_site;
}

// Each frame's start as it was used (the step chosen above, unless its fit was not
// consistent with the last frames' or there was none: then the start that won), and a
// refusal at the first frame where the tracking was lost, naming it and why.
void check_tracking(const DepthTrackingSummary& t, const DepthSequenceRecord& seq, DepthSequenceResult& out) {
  for (std::size_t i = 1; i < out.frames.size(); ++i) {
    DepthFrameResult& r = out.frames[i];
    switch (t.started[i]) {
      case TrackingStart::constant_velocity: r.start = "constant-velocity"; break;
      case TrackingStart::no_motion: r.start = "no-motion"; break;
      case TrackingStart::none:
      case TrackingStart::step: break;
    }
    const IcpSummary& f = t.tracking_fit[i];
    log::debug("{}: frame {}: tracking started from {} (features {} of {} agreeing), {} iterations{}, {:.0f} % of its "
               "points within the gate, RMS {:.2f} mm{}; camera at {:.4f} {:.4f} {:.4f}",
               kStage, r.frame.name, r.start, r.features.inliers, r.features.matches, f.iterations,
               f.converged ? "" : " (not converged)", 100 * f.inlier_share, 1000 * f.rms_m,
               f.degenerate ? ", degenerate" : "", t.tracked[i].translation().x(), t.tracked[i].translation().y(),
               t.tracked[i].translation().z());
    if (const std::string why = tracking_lost(t.tracking_fit, i); !why.empty())
      throw InputError(fmt::format(
          "{}: sequence '{}': frame {}: tracking lost after frame {}: {} (started from {}; its colour frame's "
          "features against the frame before: {} matches, {} agreeing). Nothing was changed. Record the sequence "
          "with smaller steps between frames (turn corners slowly), or import it with --poses",
          kStage, seq.name, r.frame.name, out.frames[i - 1].frame.name, why, r.start, r.features.matches,
          r.features.inliers));
  }
}

// The datum as far as it can be chosen before the frames are read: automatic stays
// automatic for a sequence without recorded poses (markers if at least 3 are seen,
// else the surface). Refuses a datum that cannot place the sequence.
DepthDatum datum_before_reading(Project& project, const LayerRecord& layer, const DepthSequenceRecord& seq,
                                bool recorded, bool colour, const DepthRegistrationOptions& o) {
  DepthDatum datum = o.datum;
  if (datum == DepthDatum::automatic && recorded) return DepthDatum::device;
  if (datum == DepthDatum::automatic && (!colour || !project.site().origin_set)) {
    // No markers can place it: the surface, if there is one.
    const std::string missing = surface_missing(project, layer, o.surface);
    if (missing.empty()) return DepthDatum::surface;
    datum = DepthDatum::markers;  // refused below, saying what is missing
  }
  if (datum == DepthDatum::device && !recorded)
    throw InputError(fmt::format("{}: sequence '{}' was imported without --poses: no device pose places it in the "
                                 "site frame; register it on the markers its colour frames see (--datum markers) or "
                                 "on the photo surface (--datum surface)",
                                 kStage, seq.name));
  const std::string no_surface =
      o.datum == DepthDatum::automatic ? " (and " + surface_missing(project, layer, o.surface) + ")" : std::string();
  if (datum == DepthDatum::markers && !colour)
    throw InputError(fmt::format("{}: sequence '{}' has {}: the markers that place it in the site frame are found in "
                                 "its colour frames{}; import it with --colour (or with --poses)",
                                 kStage, seq.name,
                                 recorded ? "frames without a colour frame" : "no recorded poses and frames without a "
                                                                              "colour frame",
                                 no_surface));
  if (datum == DepthDatum::markers && !project.site().origin_set)
    throw InputError(fmt::format("{}: sequence '{}': the site has no surveyed markers yet{}: import them first (strata "
                                 "import markers); the sequence is placed on them",
                                 kStage, seq.name, no_surface));
  if (datum == DepthDatum::surface)
    if (const std::string missing = surface_missing(project, layer, o.surface); !missing.empty())
      throw InputError(fmt::format("{}: sequence '{}': {}: process the layer's photos first (strata process DIR "
                                   "--layer {} --until dense)",
                                   kStage, seq.name, missing, layer.name));
  return datum;
}

const char* datum_name(DepthDatum d) {
  switch (d) {
    case DepthDatum::device: return "device";
    case DepthDatum::markers: return "markers";
    case DepthDatum::surface: return "surface";
    case DepthDatum::automatic: break;
  }
  return "auto";
}

DepthSequenceResult register_sequence(Project& project, const LayerRecord& layer, const DepthSequenceRecord& seq,
                                      const DepthRegistrationOptions& o) {
  const Stopwatch sw;
  DepthSequenceResult out;
  out.sequence = seq;
  const std::vector<DepthFrameRecord> records = list_depth_frames(project.db(), seq.id);
  if (records.size() < 2)
    throw InputError(fmt::format("{}: sequence '{}' has {} frame(s); tracking needs at least 2", kStage, seq.name,
                                 records.size()));
  const bool recorded = std::all_of(records.begin(), records.end(), [](const auto& f) { return f.recorded_pose; });
  const bool colour = std::all_of(records.begin(), records.end(), [](const auto& f) { return f.colour_media_path; });
  DepthDatum datum = datum_before_reading(project, layer, seq, recorded, colour, o);
  const bool markers = datum == DepthDatum::markers || datum == DepthDatum::automatic;
  const bool features = colour && (o.start == DepthStart::features || !recorded);
  const std::vector<FrameInput> frames = read_frames(project, seq, records, features, markers, o, out);

  std::vector<std::vector<Eigen::Vector3d>> points;
  for (const FrameInput& f : frames) points.push_back(f.points);
  const std::vector<std::optional<Eigen::Isometry3d>> steps = choose_steps(frames, o, out);
  // The device datum: frame 0 where the device recorded it. The markers and surface
  // data: tracked in frame 0's camera frame, then the whole sequence moved onto them.
  const Eigen::Isometry3d first =
      datum == DepthDatum::device ? Eigen::Isometry3d(out.frames[0].recorded) : Eigen::Isometry3d::Identity();
  DepthTrackingSummary t = track_depth_sequence(points, first, steps, o.tracking);
  check_tracking(t, seq, out);
  std::optional<Eigen::Isometry3d> to_site;  // frame 0's camera frame -> the site frame (markers, surface)
  if (markers) {
    out.markers = locate_markers(frames, t.poses);
    const MarkerPairs pairs = surveyed_sightings(project, out);
    if (datum == DepthDatum::automatic && pairs.names.size() >= 3) datum = DepthDatum::markers;
    else if (datum == DepthDatum::automatic) {
      if (const std::string missing = surface_missing(project, layer, o.surface); !missing.empty())
        refuse_too_few_markers(seq, out, pairs.names.size(), layer.name, missing);
      datum = DepthDatum::surface;
    }
    if (datum == DepthDatum::markers) to_site = place_on_markers(pairs, seq, o, out);
  }
  if (datum == DepthDatum::surface) to_site = place_on_surface(project, layer, seq, frames, t.poses, o, out);
  if (to_site) {
    for (auto& p : t.poses) p = *to_site * p;
    for (auto& p : t.tracked) p = *to_site * p;
  }
  out.datum = datum_name(datum);
  out.loop_closed = t.loop_closed;
  out.loop_frames = t.loop_frames;
  out.loop_inlier_share = t.loop_fit.inlier_share;
  out.loop_correction_m = t.loop_correction_m;
  out.loop_correction_rad = t.loop_correction_rad;
  for (std::size_t i = 0; i < out.frames.size(); ++i) {
    DepthFrameResult& r = out.frames[i];
    r.tracked = t.tracked[i].matrix();
    r.pose = t.poses[i].matrix();
    r.fit = t.fit[i];
    const bool fitted = i > 0 || r.fit.iterations > 0;  // the first frame is fitted only in the rounds
    if (const std::string why = fitted ? refusal(r, seq.noise_k, o) : std::string(); !why.empty())
      throw InputError(fmt::format("{}: sequence '{}': frame {}: cannot register it: {}. Nothing was changed. "
                                   "Check the frame (a blurred or empty view) and its recorded pose, or import "
                                   "the sequence without it",
                                   kStage, seq.name, r.frame.name, why));
    r.frame.pose = r.pose;
    r.frame.bounds = bounds_under(frames[i].points, t.poses[i]);
    r.frame.fit = DepthFrameFit{t.loop_closed ? "loop-closure" : "tracking", r.fit.rms_m, r.fit.inlier_share,
                                r.fit.sigma_translation_m, r.fit.sigma_rotation_rad};
  }
  out.seconds = sw.seconds();
  const auto starts = [&](const char* what) {
    return std::count_if(out.frames.begin(), out.frames.end(), [&](const auto& r) { return r.start == what; });
  };
  log::info("{}: sequence '{}': {} frames registered in {:.1f} s (started from features {}, recorded motion {}, "
            "constant velocity {}, no motion {}); datum: {}; loop {}",
            kStage, seq.name, out.frames.size(), out.seconds, starts("features"), starts("recorded"),
            starts("constant-velocity"), starts("no-motion"),
            out.marker_fit    ? fmt::format("{} of {} markers, RMS {:.1f} mm", out.marker_fit->inliers,
                                            out.marker_fit->targets.size(), 1000 * out.marker_fit->rms_m)
            : out.surface_fit ? fmt::format("the photo surface of layer {}, RMS {:.1f} mm, {:.0f} % within the gate",
                                            out.surface_layer, 1000 * out.surface_fit->icp.rms_m,
                                            100 * out.surface_fit->icp.inlier_share)
                              : std::string("the device's first pose"),
            t.loop_closed ? fmt::format("closed on the first {} frames (the last camera moved {:.1f} mm, {:.2f} mrad)",
                                        t.loop_frames, 1000 * t.loop_correction_m, 1000 * t.loop_correction_rad)
                          : std::string("not closed (the last frame does not overlap the first ones)"));
  return out;
}

}  // namespace

void DepthRegistrationOptions::validate() const {
  auto need = [](bool ok, const char* field, const char* what) {
    if (!ok) throw InputError(fmt::format("{}: {} must be {}", kStage, field, what));
  };
  need(frame_voxel_m > 0, "frame_voxel_m", "> 0 (metres)");
  need(max_depth_m > 0, "max_depth_m", "> 0 (metres)");
  need(min_inlier_share > 0 && min_inlier_share < 1, "min_inlier_share", "in (0, 1)");
  need(max_rms_ratio > 0, "max_rms_ratio", "> 0");
  need(marker_fit.point_sigma_m > 0, "marker_fit.point_sigma_m", "> 0 (metres)");
  need(marker_fit.gate_sigmas > 0, "marker_fit.gate_sigmas", "> 0");
  need(marker_fit.min_gate_m > 0, "marker_fit.min_gate_m", "> 0 (metres)");
  need(marker_fit.max_scale_error > 0 && marker_fit.max_scale_error < 1, "marker_fit.max_scale_error", "in (0, 1)");
  need(marker_window_px >= 0 && marker_window_px <= 10, "marker_window_px", "0..10 (pixels)");
  need(level_tolerance_m > 0, "level_tolerance_m", "> 0 (metres)");
  surface.validate();
  tracking.validate();
  features.validate();
  wide_features.validate();
  targets.validate();
  naming.validate();
}

DepthRegistrationSummary register_layer_depth(Project& project, const std::string& layer_name,
                                              const DepthRegistrationOptions& options) {
  options.validate();
  Database& db = project.db();
  const LayerRecord layer = require_layer(db, layer_name);
  DepthRegistrationSummary out;
  out.layer = layer_name;
  for (const auto& seq : sequences_to_register(db, layer, options.sequence))
    out.sequences.push_back(register_sequence(project, layer, seq, options));
  fault::point("register.depth.registered");
  Transaction tx(db);
  for (const auto& s : out.sequences) {
    for (const auto& r : s.frames) {
      set_depth_frame_registered(db, r.frame.id, r.pose, *r.frame.bounds, *r.frame.fit);
      fault::point("register.depth.frame_written");
    }
  }
  fault::point("register.depth.before_commit");
  tx.commit();
  return out;
}

}  // namespace strata
