#pragma once
// Sections: a vertical profile along a line through every layer surface and unit
// solid. exporters/section draws it (SVG) and writes it as 3D lines (GeoPackage).
#include "volume/volume.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace strata {

// The profile along A -> B (site frame). Samples at chainage s (metres from A).
struct SectionProfile {
  Eigen::Vector2d a = Eigen::Vector2d::Zero(), b = Eigen::Vector2d::Zero();  // site frame XY
  std::vector<double> s;  // metres along the line
  struct Surface {
    std::string layer, unit;
    std::vector<double> z;  // site frame, NaN where unknown
  };
  struct Body {
    std::string unit;
    std::vector<double> top, bottom;  // site frame, NaN where the unit is absent
  };
  std::vector<Surface> surfaces;  // capture order
  std::vector<Body> bodies;       // excavated units, in order

  double length() const { return (b - a).norm(); }
  Eigen::Vector2d point(double chainage) const { return a + (b - a).normalized() * chainage; }
};

// Samples every layer surface and unit solid along A -> B every `step_m` metres
// (0: one grid cell). Throws InputError when the line is shorter than two steps.
SectionProfile cut_section(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                           const std::vector<LayerSurface>& layers, const std::vector<UnitSolid>& solids,
                           double step_m = 0);

}  // namespace strata
