#pragma once
// The field report: one self-contained HTML file (images inline as PNG,
// drawings as inline SVG, CSS inline, no links out) that tells an archaeologist
// at the trench edge whether a layer is recorded well enough to dig it away.
// OpenCV and the database queries stay in the .cpp files.
#include "project/project.hpp"
#include "report/quality_rules.hpp"

#include <filesystem>
#include <string>
#include <vector>

namespace strata {

struct ReportOptions {
  QualityThresholds thresholds;
  int image_px = 760;          // pixels: width of plan drawings and thumbnails
  int coverage_cells = 120;    // cells along the longer side of the coverage grid
  int histogram_bins = 24;     // reprojection error histogram
  bool section = true;         // site report: a section along the excavation's long axis
  void validate() const;       // InputError naming the first invalid field
};

struct LayerVerdict {
  std::string layer;
  std::vector<Finding> findings;
  int count(Severity s) const;
};

struct ReportSummary {
  std::vector<LayerVerdict> layers;
  // Site report: one warning per find in conflict with the unit solids (empty
  // without the voxel model).
  std::vector<Finding> finds;
};

// Writes the report of one layer to `out` (temporary file, then rename). Whatever
// stage is missing is said in plain words in the report. Throws InputError for an
// unknown layer, IoError when the file cannot be written.
ReportSummary write_layer_report(Project& project, const std::string& layer, const std::filesystem::path& out,
                                 const ReportOptions& options = {});

// The site report: every layer's verdict and findings, the finds against the unit
// solids, Harris matrix, volumes, thickness maps and a section.
ReportSummary write_site_report(Project& project, const std::filesystem::path& out, const ReportOptions& options = {});

// For the pipeline after every `process`: writes products/<layer>/report.html and
// records it as the layer's product of kind "report". Returns its path.
std::filesystem::path write_layer_report_product(Project& project, const std::string& layer,
                                                 const ReportOptions& options = {});

// The HTML itself (what the writers above put in the file).
std::string layer_report_html(Project& project, const std::string& layer, const ReportOptions& options,
                              ReportSummary* summary = nullptr);
std::string site_report_html(Project& project, const ReportOptions& options, ReportSummary* summary = nullptr);

}  // namespace strata
