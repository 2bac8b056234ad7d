// strata markers: the surveyed markers, their observations and their residuals in
// each processed layer; strata markers guide: find hand-clicked markers in every
// photo of a layer.
#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "core/error.hpp"
#include "core/log.hpp"
#include "core/text_table.hpp"
#include "pipeline/guide_layer.hpp"
#include "project/project.hpp"
#include "project/records.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <map>
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

// ---- strata markers: the list and the residuals

// Millimetres to 0.1 mm; a residual that rounds to zero is "0.0", never "-0.0".
std::string mm(double metres) {
  const double v = 1000 * metres;
  return fmt::format("{:.1f}", std::abs(v) < 0.05 ? 0.0 : v);
}

// One layer's residual of one marker, as a cell of the residual table: the 3D
// residual in mm, or what happened to the marker.
std::string residual_cell(const MarkerResidualRecord& r) {
  if (r.role == "rejected") return fmt::format("{} rejected", mm(r.residual_m.norm()));
  if (!r.triangulated) return "not located";
  return mm(r.residual_m.norm());
}

double rmse_of(const std::vector<const MarkerResidualRecord*>& rows, const std::string& role, int& n) {
  double sum = 0;
  n = 0;
  for (const auto* r : rows) {
    if (r->role != role || !r->triangulated) continue;
    sum += r->residual_m.squaredNorm();
    ++n;
  }
  return n > 0 ? std::sqrt(sum / n) : 0.0;
}

nlohmann::json residual_json(const MarkerResidualRecord& r) {
  nlohmann::json j = {{"layer", r.layer}, {"role", r.role}, {"triangulated", r.triangulated}, {"images", r.images}};
  if (r.triangulated) {
    j["de_m"] = r.residual_m.x();
    j["dn_m"] = r.residual_m.y();
    j["dz_m"] = r.residual_m.z();
    j["xyz_m"] = r.residual_m.norm();
    j["reprojection_px"] = r.reprojection_px;
  }
  return j;
}

// The 3D residual of every marker (rows) in every processed layer (columns), in
// blocks of layers as wide as the terminal, and each layer's RMSE.
void print_residual_matrix(const std::vector<MarkerRecord>& markers,
                           const std::vector<MarkerResidualRecord>& residuals, int width) {
  std::vector<std::string> layers;
  std::map<std::string, std::map<std::string, const MarkerResidualRecord*>> at;  // layer -> marker -> row
  for (const auto& r : residuals) {
    if (!at.count(r.layer)) layers.push_back(r.layer);
    at[r.layer][r.marker] = &r;
  }
  fmt::print("\nResiduals, photogrammetric minus surveyed (3D, mm), in each processed layer:\n");
  constexpr int kColumn = 14;  // "123.4 rejected" and the gap
  const std::size_t per_block = std::size_t(std::max(1, (width - 14) / kColumn));
  for (std::size_t b = 0; b < layers.size(); b += per_block) {
    const std::size_t e = std::min(layers.size(), b + per_block);
    TextTable t;
    t.columns.push_back({"marker"});
    for (std::size_t l = b; l < e; ++l) t.columns.push_back({layers[l], true});
    for (const auto& m : markers) {
      std::vector<std::string> row{m.name};
      bool seen = false;
      for (std::size_t l = b; l < e; ++l) {
        const auto it = at[layers[l]].find(m.name);
        seen = seen || it != at[layers[l]].end();
        row.push_back(it == at[layers[l]].end() ? "-" : residual_cell(*it->second));
      }
      if (seen) t.add(std::move(row));
    }
    for (const char* role : {"control", "check"}) {
      std::vector<std::string> row{fmt::format("{} RMSE", role)};
      bool any = false;
      for (std::size_t l = b; l < e; ++l) {
        std::vector<const MarkerResidualRecord*> rows;
        for (const auto& [name, r] : at[layers[l]]) rows.push_back(r);
        int n = 0;
        const double rmse = rmse_of(rows, role, n);
        row.push_back(n > 0 ? fmt::format("{} ({})", mm(rmse), n) : "-");
        any = any || n > 0;
      }
      if (any) t.add(std::move(row));
    }
    fmt::print("{}", t.render(width));
  }
  for (const auto& line : wrap_text("'-': not seen in that layer's photos. Each axis: strata markers DIR --layer L; "
                                    "the verdict on them: strata report DIR --layer L --out report.html",
                                    width)) {
    fmt::print("{}\n", line);
  }
}

// One layer's residuals axis by axis.
void print_layer_residuals(const std::string& layer, const std::vector<MarkerResidualRecord>& residuals, int width) {
  TextTable t;
  t.columns = {{"marker"}, {"role"}, {"photos", true}, {"dE mm", true}, {"dN mm", true}, {"dZ mm", true},
               {"3D mm", true}, {"reprojection px", true}};
  std::vector<const MarkerResidualRecord*> rows;
  for (const auto& r : residuals) {
    if (r.layer != layer) continue;
    rows.push_back(&r);
    if (r.triangulated) {
      t.add({r.marker, r.role, std::to_string(r.images), mm(r.residual_m.x()), mm(r.residual_m.y()),
             mm(r.residual_m.z()), mm(r.residual_m.norm()), fmt::format("{:.2f}", r.reprojection_px)});
    } else {
      t.add({r.marker, r.role, std::to_string(r.images), "not located"});
    }
  }
  fmt::print("\nResiduals in layer {}, photogrammetric minus surveyed:\n{}", layer, t.render(width));
  for (const char* role : {"control", "check"}) {
    int n = 0;
    const double rmse = rmse_of(rows, role, n);
    if (n > 0) fmt::print("{} RMSE {} mm over {} {}\n", role, mm(rmse), n, n == 1 ? "marker" : "markers");
  }
}

void list_markers_command(const std::string& dir, const std::string& layer, bool json) {
  Project p = Project::open(dir);
  // Observations per marker and source (a marker may have several per photo: a
  // click and a detection; the alignment takes one, see docs/markers.md).
  std::map<std::int64_t, std::map<std::string, int>> seen;
  for (const auto& o : list_observations(p.db())) seen[o.marker_id][o.source]++;
  const auto markers = list_markers(p.db());
  const auto residuals = list_marker_residuals(p.db());
  if (!layer.empty() && !find_layer(p.db(), layer))
    throw InputError(fmt::format("markers: there is no layer '{}' in {}", layer, dir));
  if (json) {
    nlohmann::json j = nlohmann::json::array();
    for (const auto& m : markers) {
      auto& s = seen[m.id];
      const int total = s["clicked"] + s["guided"] + s["detected"];
      nlohmann::json per_layer = nlohmann::json::array();
      for (const auto& r : residuals) {
        if (r.marker == m.name && (layer.empty() || r.layer == layer)) per_layer.push_back(residual_json(r));
      }
      j.push_back({{"name", m.name}, {"kind", m.kind}, {"E", m.position.x()}, {"N", m.position.y()},
                   {"Z", m.position.z()}, {"sigma_m", m.sigma.x()}, {"sigma_stated", m.sigma_stated},
                   {"observations", total},
                   {"sources", {{"clicked", s["clicked"]}, {"guided", s["guided"]}, {"detected", s["detected"]}}},
                   {"residuals", per_layer}});
    }
    fmt::print("{}\n", j.dump(2));
    return;
  }
  const int width = terminal_width();
  TextTable t;
  t.columns = {{"marker"}, {"kind"}, {"E", true}, {"N", true}, {"Z", true}, {"sigma", true}, {"obs", true},
               {"clicked", true}, {"guided", true}, {"detected", true}};
  int control = 0;
  for (const auto& m : markers) {
    auto& s = seen[m.id];
    control += m.kind == "control";
    t.add({m.name, m.kind, fmt::format("{:.4f}", m.position.x()), fmt::format("{:.4f}", m.position.y()),
           fmt::format("{:.4f}", m.position.z()), fmt::format("{:.4f}{}", m.sigma.x(), m.sigma_stated ? "" : "*"),
           std::to_string(s["clicked"] + s["guided"] + s["detected"]), std::to_string(s["clicked"]),
           std::to_string(s["guided"]), std::to_string(s["detected"])});
  }
  fmt::print("{}", t.render(width));
  fmt::print("{} markers ({} control, {} check); sigma in metres, * strata's default weight (the survey stated "
             "none)\n",
             markers.size(), control, int(markers.size()) - control);
  if (!layer.empty()) {
    if (std::none_of(residuals.begin(), residuals.end(), [&](const auto& r) { return r.layer == layer; })) {
      fmt::print("\nLayer {} has no residuals: it is not aligned yet, or no surveyed marker was seen in its photos "
                 "(strata process {} --layer {} --until sparse)\n", layer, dir, layer);
    } else {
      print_layer_residuals(layer, residuals, width);
    }
  } else if (residuals.empty()) {
    fmt::print("No layer is aligned with markers yet: each marker's residuals appear here after "
               "strata process {} --layer L.\n", dir);
  } else {
    print_residual_matrix(markers, residuals, width);
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

void register_markers_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "markers",
      "list the surveyed markers with their observations (clicked, guided, detected) and their\n"
      "residuals in each processed layer; 'strata markers guide DIR --layer L' finds hand-clicked\n"
      "markers in every photo");
  auto dir = std::make_shared<std::string>();
  auto layer = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  cmd->add_option("DIR", *dir, "project folder");
  cmd->add_option("--layer", *layer, "one layer's residuals axis by axis (dE, dN, dZ, reprojection)");
  cmd->add_flag("--json", *json, "machine-readable output, with every layer's residuals");
  cmd->footer("Examples: strata markers site; strata markers site --layer L1");
  cmd->require_subcommand(0, 1);
  CLI::App* guide = register_markers_guide_command(*cmd);
  cmd->callback([=] {
    if (guide->parsed()) return;
    if (dir->empty()) throw InputError("markers: the project folder DIR is required (strata markers DIR)");
    list_markers_command(*dir, *layer, *json);
  });
}

}  // namespace strata::cli
