#pragma once
// Sections: a vertical profile along a line through every layer surface and unit
// solid. exporters/section draws it (SVG) and writes it as 3D lines (GeoPackage).
#include "geometry/section_profile.hpp"
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

}  // namespace strata
