#pragma once
// Sections: a vertical profile along a line through every layer surface and unit
// solid. exporters/section draws it (SVG) and writes it as 3D lines (GeoPackage).
#include "geometry/section_profile.hpp"
#include "project/find_records.hpp"
#include "volume/volume.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace strata {

// Samples every layer surface and unit solid along A -> B every `step_m` metres
// (0: one grid cell). Throws InputError when the line is shorter than two steps.
SectionProfile cut_section(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                           const std::vector<LayerSurface>& layers, const std::vector<UnitSolid>& solids,
                           double step_m = 0);

struct SectionFindOptions {
  // Horizontal distance from the section plane within which a find is projected onto
  // it, metres (either side). 0.25 m takes the finds from the section face and the
  // soil just behind or before it without crowding the drawing with the whole
  // trench; 0 projects none.
  double within_m = 0.25;
  void validate() const;  // InputError naming --finds-within and its value
};

// Projects onto the section's vertical plane every find whose point lies within
// `options.within_m` of it and whose foot falls on the line between A and B
// (positions in the site CRS, `site_origin` the site frame's). Replaces
// profile.finds (sorted by chainage) and sets profile.finds_within_m. Returns how
// many were taken.
std::size_t add_section_finds(SectionProfile& profile, const std::vector<FindRecord>& finds,
                              const Eigen::Vector3d& site_origin, const SectionFindOptions& options);

}  // namespace strata
