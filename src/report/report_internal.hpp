#pragma once
// Internal to the report module: what the layer and site reports share.
#include "pipeline/alignment_store.hpp"
#include "pipeline/stage_results.hpp"
#include "report/report.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace strata::report_detail {

// Everything the report shows about one layer, read once from the database.
struct LayerData {
  LayerRecord layer;
  SiteInfo site;
  std::vector<ImageRecord> images;
  std::optional<StoredAlignment> alignment;
  std::optional<DenseQuality> dense_quality;
  std::optional<ProductsQuality> products_quality;
  std::map<std::string, Eigen::Vector3d> marker_positions;  // site frame, by name
  std::optional<std::filesystem::path> dtm, ortho;          // absolute paths of existing files
  std::vector<Camera> cameras;                              // registered photos, site frame
  std::optional<CoverageMap> coverage;
  std::string coverage_source;                              // "DTM" or "sparse points"
  LayerFigures figures;
  std::vector<Finding> findings;
  std::vector<std::string> notes;                           // what could not be read, in plain words
};

LayerData gather_layer(Project& project, const LayerRecord& layer, const ReportOptions& options);

// The sections of one layer (full) or its summary (for the site report).
std::string layer_sections_html(const LayerData& d, const ReportOptions& options);
std::string findings_html(const std::vector<Finding>& findings);
std::string verdict_html(const std::vector<Finding>& findings);

// The site report's finds: counts per recorded unit and every find, checked against
// the voxel model when it exists (conflicts first, as warnings, also returned in
// `warnings`), else the record alone and what to run.
std::string finds_section_html(Project& project, std::vector<Finding>* warnings);

// A complete page around `body`, with the stylesheet inline.
std::string page_html(const std::string& title, const std::string& subtitle, const std::string& body);

}  // namespace strata::report_detail
