// strata report: the field report of a layer or of the whole site, as one
// self-contained HTML file.
#include "cli/commands.hpp"
#include "core/error.hpp"
#include "core/log.hpp"
#include "report/report.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <memory>

namespace strata::cli {

void register_report_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "report",
      "write the field report: one self-contained HTML file (open it in any browser, no network\n"
      "needed). With --layer: is the layer recorded well enough to dig it away? Photos, camera\n"
      "positions, coverage map, marker residuals, reprojection errors, DTM hillshade and\n"
      "plain-language warnings with what to do. Without: the site report (every layer's verdict,\n"
      "the finds: counts per recorded unit and each find with the unit whose solid holds it, those in\n"
      "conflict first as warnings (needs the voxel model of 'strata volume'; without it, the record\n"
      "alone), Harris matrix, volumes, thickness maps, a section with the finds within 0.25 m of it).");
  auto dir = std::make_shared<std::string>();
  auto layer = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  auto options = std::make_shared<ReportOptions>();
  cmd->add_option("DIR", *dir, "project folder")->required();
  cmd->add_option("--layer", *layer, "the layer to report on (default: the whole site)");
  cmd->add_option("--out", *out, "HTML file to write")->required();
  cmd->add_flag("--json", *json, "also print every layer's findings as JSON on stdout");
  cmd->add_option("--max-check-rmse", options->thresholds.max_check_rmse_m,
                  "check-marker RMSE (3D, metres) above which the layer is not ready (default 0.010)");
  cmd->add_option("--max-control-rmse", options->thresholds.max_control_rmse_m,
                  "control-marker RMSE (3D, metres) above which the layer is not ready (default 0.010)");
  cmd->add_option("--min-photos-per-area", options->thresholds.min_photos_per_area,
                  "photos that must see every part of the trench (default 3)");
  cmd->add_option("--max-gsd", options->thresholds.max_gsd_m,
                  "coarsest acceptable ground resolution, metres per pixel (default 0.0025)");
  cmd->add_flag("!--no-section", options->section, "leave the section out of the site report");
  cmd->callback([=] {
    options->validate();
    Project project = Project::open(*dir);
    const ReportSummary summary = layer->empty() ? write_site_report(project, *out, *options)
                                                 : write_layer_report(project, *layer, *out, *options);
    if (*json) {
      nlohmann::json j = nlohmann::json::array();
      for (const auto& l : summary.layers) {
        nlohmann::json findings = nlohmann::json::array();
        for (const auto& f : l.findings) {
          findings.push_back({{"severity", to_string(f.severity)}, {"rule", f.rule}, {"message", f.message},
                              {"advice", f.advice}});
        }
        j.push_back({{"layer", l.layer},
                     {"problems", l.count(Severity::problem)},
                     {"warnings", l.count(Severity::warning)},
                     {"findings", findings}});
      }
      fmt::print("{}\n", j.dump(2));
    } else {
      for (const auto& l : summary.layers) {
        fmt::print("layer {}: {} problems, {} warnings\n", l.layer, l.count(Severity::problem),
                   l.count(Severity::warning));
      }
      if (!summary.finds.empty()) fmt::print("finds: {} in conflict with the unit solids\n", summary.finds.size());
      fmt::print("report: {}\n", *out);
    }
  });
}

}  // namespace strata::cli
