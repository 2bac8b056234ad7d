// strata markers guide: find hand-clicked markers in every photo of a layer.
#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "core/error.hpp"
#include "core/log.hpp"
#include "pipeline/guide_layer.hpp"
#include "project/project.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <memory>
#include <string>

namespace strata::cli {
namespace {

struct GuideArgs {
  std::string dir;
  std::string layer;
  bool json = false;
  MarkerGuideOptions options;
};

nlohmann::json number_or_null(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

nlohmann::json to_json(const GuideLayerResult& r) {
  const auto& names = r.photo_names;
  nlohmann::json markers = nlohmann::json::array();
  for (const auto& m : r.summary.markers) {
    nlohmann::json added = nlohmann::json::array(), clicks = nlohmann::json::array(),
                   rejected = nlohmann::json::array();
    for (const auto& g : m.added) {
      added.push_back({{"image", names[std::size_t(g.photo)]}, {"x", g.pixel.x()}, {"y", g.pixel.y()},
                       {"score", g.score}, {"symmetry", g.symmetry}, {"residual_px", g.residual_px}});
    }
    for (const auto& c : m.clicks) {
      clicks.push_back({{"image", names[std::size_t(c.photo)]},
                        {"clicked", {c.clicked.x(), c.clicked.y()}},
                        {"refined", c.refined_ok ? nlohmann::json{c.refined.x(), c.refined.y()} : nlohmann::json(nullptr)},
                        {"moved_px", c.moved_px},
                        {"symmetry", c.symmetry},
                        {"to_rays_px", number_or_null(c.to_rays_px)},
                        {"far", c.far}});
    }
    for (const auto& x : m.rejected) {
      rejected.push_back({{"image", names[std::size_t(x.photo)]}, {"reason", x.reason}, {"value", x.value}});
    }
    markers.push_back({{"marker", m.name},
                       {"triangulated", m.triangulated},
                       {"message", m.message},
                       {"plane_points", m.plane_points},
                       {"normal", {m.normal.x(), m.normal.y(), m.normal.z()}},
                       {"predicted", m.predicted},
                       {"rmse_px", m.rmse_px},
                       {"added", added},
                       {"clicks", clicks},
                       {"rejected", rejected}});
  }
  return {{"layer", r.layer},           {"guided", r.summary.added},   {"replaced", r.replaced},
          {"seconds", r.summary.seconds}, {"markers", markers},
          {"unregistered_clicks", r.unregistered_clicks}};
}

void print_text(const GuideLayerResult& r) {
  const auto& names = r.photo_names;
  fmt::print("layer {}: {} guided observations ({} replaced) in {:.1f} s\n", r.layer, r.summary.added, r.replaced,
             r.summary.seconds);
  fmt::print("  {:<10} {:>7} {:>9} {:>6} {:>9} {:>13} {:>10}\n", "marker", "clicks", "predicted", "added",
             "rmse px", "clicks moved", "ground");
  for (const auto& m : r.summary.markers) {
    if (!m.triangulated) {
      fmt::print("  {:<10} {:>7}  not triangulated: {}\n", m.name, m.clicks.size(), m.message);
      continue;
    }
    double moved = 0;
    for (const auto& c : m.clicks) moved = std::max(moved, c.moved_px);
    fmt::print("  {:<10} {:>7} {:>9} {:>6} {:>9.2f} {:>10.1f} px {:>10}\n", m.name, m.clicks.size(), m.predicted,
               m.added.size(), m.rmse_px, moved,
               m.plane_points > 0 ? fmt::format("{} pts", m.plane_points) : std::string("vertical"));
  }
  for (const auto& m : r.summary.markers) {
    if (m.added.empty() && m.rejected.empty()) continue;
    fmt::print("  {}:", m.name);
    for (const auto& g : m.added) fmt::print(" {} ({:.2f} px)", names[std::size_t(g.photo)], g.residual_px);
    fmt::print("\n");
    for (const auto& x : m.rejected) {
      log::info("  {}: not added in {}: {} ({:.2f})", m.name, names[std::size_t(x.photo)], x.reason, x.value);
    }
  }
  for (const auto& c : r.unregistered_clicks) log::warn("click of {} ignored: the photo is not aligned", c);
}

void warn_far_clicks(const GuideLayerResult& r) {
  for (const auto& m : r.summary.markers) {
    for (const auto& c : m.clicks) {
      if (c.far) {
        log::warn("{}: the click in {} is {:.1f} px from where the other rays meet; check or re-click it", m.name,
                  r.photo_names[std::size_t(c.photo)], c.to_rays_px);
      }
    }
  }
}

void run_guide(const GuideArgs& a) {
  const ProjectLock lock = lock_project(a.dir);
  Project p = Project::open(a.dir);
  const GuideLayerResult r = guide_layer(p, a.layer, a.options);
  warn_far_clicks(r);
  if (a.json) {
    fmt::print("{}\n", to_json(r).dump(2));
  } else {
    print_text(r);
  }
}

}  // namespace

CLI::App* register_markers_guide_command(CLI::App& markers) {
  auto args = std::make_shared<GuideArgs>();
  CLI::App* cmd = markers.add_subcommand(
      "guide",
      "Find hand-clicked (non-coded) markers in every photo of an aligned layer.\n\n"
      "Workflow:\n"
      "  1. click each marker at its centre in 2-3 photos taken from different sides and\n"
      "     import the clicks (an OpenDroneMap gcp_list) and the survey:\n"
      "     strata import markers DIR gcp_list.txt --format odm; strata import markers DIR survey.csv\n"
      "  2. align the layer with the clicks: strata process DIR --layer L --until sparse\n"
      "     (needs 3 control markers clicked in 2 photos each to georeference)\n"
      "  3. strata markers guide DIR --layer L: each marker is triangulated from its\n"
      "     clicks, predicted in every photo that sees it, and found there to sub-pixel\n"
      "     (its clicked appearance warped onto the ground plane, then its centre of\n"
      "     symmetry); the clicks are refined the same way. Found positions that agree with\n"
      "     the triangulation are stored as 'guided' observations (replacing the layer's\n"
      "     earlier ones); a click far from where the other rays meet is named.\n"
      "  4. strata process DIR --layer L again: the alignment now uses the guided\n"
      "     observations (a click still wins in its own photo) and reports the markers'\n"
      "     residuals; compare the check RMSE with step 2.\n"
      "See docs/markers.md.");
  cmd->add_option("DIR", args->dir, "project folder")->required();
  cmd->add_option("--layer", args->layer, "the aligned layer")->required();
  cmd->add_flag("--json", args->json, "machine-readable report on stdout");
  cmd->add_option("--min-score", args->options.min_score,
                  "smallest normalised cross-correlation of the clicked appearance to accept a match (-1..1)")
      ->capture_default_str();
  cmd->add_option("--search-px", args->options.search_px,
                  "pixels around the prediction searched (about the clicks' errors)")
      ->capture_default_str();
  cmd->add_option("--marker-size", args->options.marker_size_m, "printed width of the markers, metres")
      ->capture_default_str();
  cmd->add_option("--gate-px", args->options.gate_px,
                  "a guided observation must reproject within this of the marker's triangulation, pixels")
      ->capture_default_str();
  cmd->add_flag("!--no-symmetry", args->options.centre_on_symmetry,
                "markers that are not point-symmetric: keep the template match, do not centre on symmetry");
  cmd->callback([args] { run_guide(*args); });
  return cmd;
}

}  // namespace strata::cli
