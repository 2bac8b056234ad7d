#pragma once
// A vertical section as sampled: what volume/section.hpp cuts through the layer
// surfaces and unit solids, and what exporters/section draws and writes. Plain data.
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

}  // namespace strata
