// strata register scan: unregistered range scans placed in the site frame by ICP
// against a photogrammetric surface (docs/range.md, "Registration").
#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "pipeline/register_scans.hpp"
#include "project/project.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <memory>

namespace strata::cli {
namespace {

nlohmann::json registration_json(const LayerRegistrationSummary& s) {
  nlohmann::json out = {{"layer", s.layer}, {"against", s.reference_layer}, {"scans", nlohmann::json::array()}};
  for (const ScanRegistrationResult& r : s.scans) {
    nlohmann::json pose = nlohmann::json::array();
    for (int k = 0; k < 16; ++k) pose.push_back(r.pose(k / 4, k % 4));
    out["scans"].push_back({{"scan", r.scan.name},
                            {"method", r.scan.fit->method},
                            {"transform", pose},
                            {"rms_m", r.icp.rms_m},
                            {"inlier_share", r.icp.inlier_share},
                            {"sigma_translation_m", r.icp.sigma_translation_m},
                            {"sigma_rotation_rad", r.icp.sigma_rotation_rad},
                            {"eigen_ratio", r.icp.eigen_ratio},
                            {"support_share", r.icp.support_share},
                            {"iterations", r.icp.iterations},
                            {"coarse_yaw_rad", r.coarse.yaw_rad},
                            {"coarse_score", r.coarse.score},
                            {"points_used", r.points_used},
                            {"surface_points", r.surface_points},
                            {"seconds", r.seconds}});
  }
  return out;
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

}  // namespace

void register_registration_commands(CLI::App& app) {
  auto* reg = app.add_subcommand("register", "place range scans in the site frame");
  reg->require_subcommand(1);
  auto* cmd = reg->add_subcommand(
      "scan",
      "register a layer's unregistered scans by robust point-to-plane ICP against a photogrammetric\n"
      "surface: the layer's own (run 'strata process' on its photos first) or, with --against previous,\n"
      "the previous layer's, whose ground outside the trench has not changed. The scanner is taken to\n"
      "be levelled (z up within a few degrees): the rotation about the vertical is searched, then ICP.\n"
      "Each scan becomes 'transform' with its residual RMS, inlier share and pose sigma; when any scan\n"
      "cannot be registered, nothing is changed.");
  auto dir = std::make_shared<std::string>();
  auto layer = std::make_shared<std::string>();
  auto scan = std::make_shared<std::string>();
  auto against = std::make_shared<std::string>("layer");
  auto json = std::make_shared<bool>(false);
  cmd->add_option("DIR", *dir, "project folder")->required();
  cmd->add_option("--layer", *layer, "the layer whose scans to register")->required();
  cmd->add_option("--scan", *scan, "one scan, by its file name (default: every unregistered scan of the layer)");
  cmd->add_option("--against", *against,
                  "the reference surface: layer (the layer's own photo surface, the default) or previous "
                  "(the layer recorded before it)")
      ->check(CLI::IsMember({"layer", "previous"}));
  cmd->add_flag("--json", *json, "print the registration figures as JSON");
  cmd->footer("Example: strata register scan site --layer L4");
  cmd->callback([=] {
    ScanRegistrationOptions options;
    options.against = *against == "previous" ? RegistrationReference::previous : RegistrationReference::layer;
    if (!scan->empty()) options.scan = *scan;
    const ProjectLock lock = lock_project(*dir);
    Project p = Project::open(*dir);
    const LayerRegistrationSummary s = register_layer_scans(p, *layer, options);
    if (*json) fmt::print("{}\n", registration_json(s).dump(2));
    else print_registration(s);
  });
}

}  // namespace strata::cli
