#pragma once
// A section of the site along a line, as `strata export section` and the field
// station's map both make it: the site model (every layer surface and unit solid,
// load_site_model), the profile cut along the line (cut_section), the finds near its
// plane projected onto it, and the drawing's options from the record. Orchestration
// only: the maths is in src/volume/section.*, the drawing in exporters/section.
#include "exporters/section/section_writers.hpp"
#include "project/project.hpp"
#include "volume/section.hpp"
#include "volume/site_volumes.hpp"

#include <Eigen/Core>

#include <cstddef>
#include <string>

namespace strata {

struct SiteSectionRequest {
  Eigen::Vector2d a = Eigen::Vector2d::Zero(), b = Eigen::Vector2d::Zero();  // E, N, site CRS metres
  double step_m = 0;           // sampling step along the line, metres; 0: one grid cell
  SectionFindOptions finds;    // finds projected onto the plane
  double scale = 20;           // drawing at 1:scale
  std::string title = "Section";
};

struct SiteSection {
  SectionProfile profile;
  SectionDrawingOptions drawing;  // scale, title, CRS, unit types from the record
  SiteInfo site;
  std::size_t finds_recorded = 0, finds_projected = 0;
};

// Throws InputError (fewer than two layer surfaces, a line shorter than two steps,
// bad options) as load_site_model and cut_section do.
SiteSection cut_site_section(Project& project, const SiteVolumeOptions& model, const SiteSectionRequest& request);

}  // namespace strata
