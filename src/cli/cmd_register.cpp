// strata register scan: unregistered range scans placed in the site frame on surveyed
// targets, or by ICP against a photogrammetric surface (docs/range.md, "Registration").
// strata register depth: RGB-D depth sequences tracked frame to model and closed on
// their first frames (docs/range.md, "Registration of depth sequences").
#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "pipeline/register_depth.hpp"
#include "pipeline/register_scans.hpp"
#include "project/project.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

namespace strata::cli {
namespace {

// A fit to a photo surface (a scan's, or a depth sequence's surface datum).
nlohmann::json surface_fit_json(const IcpSummary& icp, const CoarseResult& coarse) {
  return {{"rms_m", icp.rms_m},
          {"inlier_share", icp.inlier_share},
          {"sigma_translation_m", icp.sigma_translation_m},
          {"sigma_rotation_rad", icp.sigma_rotation_rad},
          {"eigen_ratio", icp.eigen_ratio},
          {"support_share", icp.support_share},
          {"iterations", icp.iterations},
          {"coarse_yaw_rad", coarse.yaw_rad},
          {"coarse_score", coarse.score}};
}

nlohmann::json registration_json(const LayerRegistrationSummary& s) {
  nlohmann::json out = {{"layer", s.layer}, {"against", s.reference_layer}, {"scans", nlohmann::json::array()}};
  for (const ScanRegistrationResult& r : s.scans) {
    nlohmann::json pose = nlohmann::json::array();
    for (int k = 0; k < 16; ++k) pose.push_back(r.pose(k / 4, k % 4));
    nlohmann::json scan = {{"scan", r.scan.name}, {"method", r.scan.fit->method}, {"transform", pose}};
    scan.update(surface_fit_json(r.icp, r.coarse));
    scan.update({{"points_used", r.points_used}, {"surface_points", r.surface_points}, {"seconds", r.seconds}});
    out["scans"].push_back(std::move(scan));
  }
  return out;
}

nlohmann::json registration_json(const TargetRegistrationResult& r) {
  nlohmann::json pose = nlohmann::json::array();
  for (int k = 0; k < 16; ++k) pose.push_back(r.pose(k / 4, k % 4));
  nlohmann::json targets = nlohmann::json::array();
  for (const TargetResidual& t : r.targets)
    targets.push_back({{"name", t.name}, {"residual_m", t.residual_m}, {"inlier", t.inlier}});
  return {{"scan", r.scan.name},
          {"method", "targets"},
          {"transform", pose},
          {"scale", r.scale},
          {"rms_m", r.rms_m},
          {"inliers", r.inliers},
          {"gate_m", r.gate_m},
          {"sigma_translation_m", r.sigma_translation_m},
          {"sigma_rotation_rad", r.sigma_rotation_rad},
          {"targets", targets},
          {"unmatched", r.unmatched},
          {"seconds", r.seconds}};
}

void print_registration(const TargetRegistrationResult& r) {
  fmt::print("{}: registered on {} of {} targets: RMS {:.2f} mm, scale {:.5f}, sigma {:.2f} mm / {:.3f} mrad\n",
             r.scan.name, r.inliers, r.targets.size(), 1000 * r.rms_m, r.scale, 1000 * r.sigma_translation_m,
             1000 * r.sigma_rotation_rad);
  for (const TargetResidual& t : r.targets)
    fmt::print("  {}: {:.1f} mm{}\n", t.name, 1000 * t.residual_m, t.inlier ? "" : " (left out)");
  fmt::print("run 'strata process' to fuse it into the layer's surface\n");
}

void print_registration(const LayerRegistrationSummary& s) {
  fmt::print("layer {}: {} scan(s) registered against the surface of layer {}\n", s.layer, s.scans.size(),
             s.reference_layer);
  for (const ScanRegistrationResult& r : s.scans) {
    fmt::print("  {}: RMS {:.2f} mm, {:.0f} % inliers of {} points, sigma {:.2f} mm / {:.3f} mrad, {} iterations\n",
               r.scan.name, 1000 * r.icp.rms_m, 100 * r.icp.inlier_share, r.points_used,
               1000 * r.icp.sigma_translation_m, 1000 * r.icp.sigma_rotation_rad, r.icp.iterations);
  }
  fmt::print("run 'strata process' to fuse them into the layer's surface\n");
}

nlohmann::json matrix_json(const Eigen::Matrix4d& m) {
  nlohmann::json out = nlohmann::json::array();
  for (int k = 0; k < 16; ++k) out.push_back(m(k / 4, k % 4));
  return out;
}

nlohmann::json registration_json(const DepthRegistrationSummary& s) {
  nlohmann::json out = {{"layer", s.layer}, {"sequences", nlohmann::json::array()}};
  for (const DepthSequenceResult& q : s.sequences) {
    nlohmann::json frames = nlohmann::json::array();
    for (const DepthFrameResult& r : q.frames) {
      nlohmann::json frame = {{"frame", r.frame.name},
                        {"method", r.frame.fit->method},
                        {"start", r.start},
                        {"feature_matches", r.features.matches},
                        {"feature_inliers", r.features.inliers},
                        {"markers_seen", r.markers_seen},
                        {"pose", matrix_json(r.pose)},
                        {"tracked_pose", matrix_json(r.tracked)},
                        {"rms_m", r.fit.rms_m},
                        {"inlier_share", r.fit.inlier_share},
                        {"sigma_translation_m", r.fit.sigma_translation_m},
                        {"sigma_rotation_rad", r.fit.sigma_rotation_rad},
                        {"iterations", r.fit.iterations},
                        {"median_depth_m", r.median_depth_m},
                        {"points_used", r.points_used}};
      if (r.has_recorded) frame["recorded_pose"] = matrix_json(r.recorded);
      frames.push_back(std::move(frame));
    }
    nlohmann::json markers = nlohmann::json::array();
    for (const DepthMarkerSighting& m : q.markers) {
      nlohmann::json one = {{"name", m.name},
                            {"frames", m.frames},
                            {"position", {m.position.x(), m.position.y(), m.position.z()}}};
      if (q.marker_fit)
        for (const TargetResidual& t : q.marker_fit->targets)
          if (t.name == m.name) one.update({{"residual_m", t.residual_m}, {"inlier", t.inlier}});
      markers.push_back(std::move(one));
    }
    nlohmann::json datum = {{"datum", q.datum}, {"markers", markers}, {"unmatched", q.unmatched}};
    if (q.marker_fit)
      datum.update({{"transform", matrix_json(q.marker_fit->pose)},
                    {"scale", q.marker_fit->scale},
                    {"rms_m", q.marker_fit->rms_m},
                    {"inliers", q.marker_fit->inliers},
                    {"gate_m", q.marker_fit->gate_m},
                    {"sigma_translation_m", q.marker_fit->sigma_translation_m},
                    {"sigma_rotation_rad", q.marker_fit->sigma_rotation_rad}});
    if (q.surface_fit) {
      datum.update(surface_fit_json(q.surface_fit->icp, q.surface_fit->coarse));
      datum.update({{"transform", matrix_json(q.surface_transform)},
                    {"against", q.surface_layer},
                    {"points_used", q.surface_points_used},
                    {"ground_share", q.ground_share},
                    {"level_rad", q.level_rad}});
    }
    out["sequences"].push_back({{"sequence", q.sequence.name},
                                {"datum", datum},
                                {"frames", frames},
                                {"loop_closed", q.loop_closed},
                                {"loop_frames", q.loop_frames},
                                {"loop_inlier_share", q.loop_inlier_share},
                                {"loop_correction_m", q.loop_correction_m},
                                {"loop_correction_rad", q.loop_correction_rad},
                                {"seconds", q.seconds}});
  }
  return out;
}

void print_registration(const DepthRegistrationSummary& s) {
  for (const DepthSequenceResult& q : s.sequences) {
    std::vector<double> rms;
    double worst_t = 0, worst_r = 0;
    for (const DepthFrameResult& r : q.frames) {
      rms.push_back(r.fit.rms_m);
      worst_t = std::max(worst_t, r.fit.sigma_translation_m);
      worst_r = std::max(worst_r, r.fit.sigma_rotation_rad);
    }
    std::sort(rms.begin(), rms.end());
    fmt::print("layer {}: depth sequence '{}': {} frames registered in {:.0f} s; RMS residual median {:.2f} mm, "
               "largest {:.2f} mm; pose sigma at most {:.3f} mm / {:.4f} mrad (lower bounds)\n",
               s.layer, q.sequence.name, q.frames.size(), q.seconds, 1000 * rms[rms.size() / 2], 1000 * rms.back(),
               1000 * worst_t, 1000 * worst_r);
    const auto started = [&](const char* what) {
      return std::count_if(q.frames.begin(), q.frames.end(), [&](const auto& r) { return r.start == what; });
    };
    fmt::print("  frames started from their features' motion: {}, the recorded motion: {}, constant velocity: {}, "
               "no motion: {}\n",
               started("features"), started("recorded"), started("constant-velocity"), started("no-motion"));
    if (q.marker_fit)
      fmt::print("  placed on {} of {} surveyed markers seen: RMS {:.1f} mm, scale {:.4f}\n", q.marker_fit->inliers,
                 q.marker_fit->targets.size(), 1000 * q.marker_fit->rms_m, q.marker_fit->scale);
    else if (q.surface_fit)
      fmt::print("  placed on the photo surface of layer {} (levelled on its ground, turned {:.1f} degrees; coarse "
                 "yaw search and ICP): RMS {:.1f} mm, {:.0f} % of its points within the gate, pose sigma {:.2f} mm / "
                 "{:.3f} mrad (lower bounds)\n",
                 q.surface_layer, q.level_rad * 180 / M_PI, 1000 * q.surface_fit->icp.rms_m,
                 100 * q.surface_fit->icp.inlier_share, 1000 * q.surface_fit->icp.sigma_translation_m,
                 1000 * q.surface_fit->icp.sigma_rotation_rad);
    else
      fmt::print("  placed by the device's first recorded pose\n");
    if (q.loop_closed)
      fmt::print("  loop closed on the first {} frames: the last camera moved {:.1f} mm and turned {:.2f} mrad\n",
                 q.loop_frames, 1000 * q.loop_correction_m, 1000 * q.loop_correction_rad);
    else
      fmt::print("  loop not closed: the last frame does not overlap the first {} frames\n", q.loop_frames);
  }
  fmt::print("run 'strata process' to fuse them into the layer's surface\n");
}

// Opens the project under its write lock, registers, and prints the result.
template <class Register>
void run_registration(const std::string& dir, bool json, Register&& register_scans) {
  const ProjectLock lock = lock_project(dir);
  Project p = Project::open(dir);
  const auto result = register_scans(p);
  if (json) fmt::print("{}\n", registration_json(result).dump(2));
  else print_registration(result);
}

// strata register depth DIR --layer L [--sequence NAME] [--json]
void register_depth_registration(CLI::App& reg) {
  auto* cmd = reg.add_subcommand(
      "depth",
      "register a layer's RGB-D depth sequences in the site frame: each frame fitted by robust\n"
      "point-to-plane ICP to the model of the frames before it, starting from the motion its colour\n"
      "frame's features (ORB, RANSAC) measured against the previous frame or the motion the device\n"
      "recorded (--start); then the loop closed by fitting the last frame to the first ones and\n"
      "spreading the correction along the sequence; then every frame fitted again to the model of all\n"
      "frames. The sequence is placed in the site frame by the device's first recorded pose, or, when\n"
      "it has no recorded poses (or with --datum markers), on the surveyed markers (coded targets)\n"
      "its colour frames see, at least 3; failing those (or with --datum surface), levelled on its\n"
      "ground and fitted to the layer's photo surface (--against) by the coarse yaw search and ICP, as\n"
      "an unregistered scan is. Per frame: RMS residual, inlier share, pose sigma.\n"
      "When any frame cannot be registered, nothing is changed. See docs/range.md.");
  auto dir = std::make_shared<std::string>();
  auto layer = std::make_shared<std::string>();
  auto sequence = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  auto rounds = std::make_shared<int>(DepthTrackingOptions{}.refine_rounds);
  cmd->add_option("DIR", *dir, "project folder")->required();
  cmd->add_option("--layer", *layer, "the layer whose depth sequences to register")->required();
  cmd->add_option("--sequence", *sequence, "one sequence, by name (default: every sequence of the layer)");
  cmd->add_option("--rounds", *rounds, "rounds of re-registration against the model of all frames (0..10)")
      ->capture_default_str();
  auto start = std::make_shared<std::string>("recorded");
  auto datum = std::make_shared<std::string>("auto");
  cmd->add_option("--start", *start,
                  "what starts each frame's fit when both are at hand: recorded (the device's motion) or\n"
                  "features (the colour frames'); either falls back on the other, then on constant velocity")
      ->check(CLI::IsMember({"features", "recorded"}))
      ->capture_default_str();
  auto against = std::make_shared<std::string>("layer");
  cmd->add_option("--datum", *datum,
                  "what places a sequence in the site frame: device (its first recorded pose), markers (the\n"
                  "surveyed markers its colour frames see), surface (the photo surface) or auto (device with\n"
                  "recorded poses, else markers when 3 are seen, else the surface when there is one)")
      ->check(CLI::IsMember({"auto", "device", "markers", "surface"}))
      ->capture_default_str();
  cmd->add_option("--against", *against,
                  "the surface datum's surface: the layer's own photo surface, or the previous layer's")
      ->check(CLI::IsMember({"layer", "previous"}))
      ->capture_default_str();
  cmd->add_flag("--json", *json, "print the registration figures as JSON (every frame's poses and fit)");
  cmd->footer("Example: strata register depth site --layer L4 --json > L4_depth.json");
  cmd->callback([=] {
    DepthRegistrationOptions options;
    options.start = *start == "recorded" ? DepthStart::recorded : DepthStart::features;
    options.datum = *datum == "device"    ? DepthDatum::device
                    : *datum == "markers" ? DepthDatum::markers
                    : *datum == "surface" ? DepthDatum::surface
                                          : DepthDatum::automatic;
    options.surface.against = *against == "previous" ? RegistrationReference::previous : RegistrationReference::layer;
    if (!sequence->empty()) options.sequence = *sequence;
    options.tracking.refine_rounds = *rounds;
    run_registration(*dir, *json, [&](Project& p) { return register_layer_depth(p, *layer, options); });
  });
}

}  // namespace

void register_registration_commands(CLI::App& app) {
  auto* reg = app.add_subcommand("register", "place range scans and depth sequences in the site frame");
  reg->require_subcommand(1);
  auto* cmd = reg->add_subcommand(
      "scan",
      "register a layer's unregistered scans in the site frame. With --targets, one scan (--scan) on\n"
      "the surveyed markers its scanner measured: a similarity fitted robustly to the targets named like\n"
      "the markers (blunders left out and listed). Otherwise by robust point-to-plane ICP against a\n"
      "photogrammetric surface: the layer's own (run 'strata process' on its photos first) or, with\n"
      "--against previous, the previous layer's, whose ground outside the trench has not changed; the\n"
      "scanner is taken to be levelled (z up within a few degrees): the rotation about the vertical is\n"
      "searched, then ICP. Each scan becomes 'transform' with its residual RMS, inlier share and pose\n"
      "sigma; when any scan cannot be registered, nothing is changed.");
  auto dir = std::make_shared<std::string>();
  auto layer = std::make_shared<std::string>();
  auto scan = std::make_shared<std::string>();
  auto against = std::make_shared<std::string>("layer");
  auto targets = std::make_shared<std::string>();
  auto target_sigma = std::make_shared<double>(TargetRegistrationOptions{}.target_sigma_m);
  auto json = std::make_shared<bool>(false);
  cmd->add_option("DIR", *dir, "project folder")->required();
  cmd->add_option("--layer", *layer, "the layer whose scans to register")->required();
  cmd->add_option("--scan", *scan, "one scan, by its file name (default: every unregistered scan of the layer)");
  cmd->add_option("--against", *against,
                  "the reference surface: layer (the layer's own photo surface, the default) or previous "
                  "(the layer recorded before it)")
      ->check(CLI::IsMember({"layer", "previous"}));
  auto* targets_opt = cmd->add_option(
      "--targets", *targets,
      "the scanner's measurements of surveyed markers: CSV name,x,y,z (metres, scanner frame), each\n"
      "named like its marker; needs --scan");
  targets_opt->needs(cmd->get_option("--scan"))->check(CLI::ExistingFile);
  cmd->add_option("--target-sigma", *target_sigma, "metres: a target centre as the scanner measures it, one sigma")
      ->needs(targets_opt)
      ->check(CLI::PositiveNumber);
  cmd->get_option("--against")->excludes(targets_opt);
  cmd->add_flag("--json", *json, "print the registration figures as JSON");
  cmd->footer(
      "Examples:\n"
      "  strata register scan site --layer L4\n"
      "  strata register scan site --layer L4 --scan S1.ply --targets S1_targets.csv");
  cmd->callback([=] {
    if (!targets->empty()) {
      TargetRegistrationOptions options;
      options.scan = *scan;
      options.targets = *targets;
      options.target_sigma_m = *target_sigma;
      run_registration(*dir, *json, [&](Project& p) { return register_scan_on_targets(p, *layer, options); });
      return;
    }
    ScanRegistrationOptions options;
    options.against = *against == "previous" ? RegistrationReference::previous : RegistrationReference::layer;
    if (!scan->empty()) options.scan = *scan;
    run_registration(*dir, *json, [&](Project& p) { return register_layer_scans(p, *layer, options); });
  });
  register_depth_registration(*reg);
}

}  // namespace strata::cli
