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
  // A find projected onto the section plane (the vertical plane through A -> B).
  struct Find {
    std::string id, unit, type;  // find number, the unit it was recorded in, its type (may be empty)
    Eigen::Vector3d position = Eigen::Vector3d::Zero();  // surveyed point, site frame
    double s = 0;       // chainage of its foot on A -> B, metres from A
    double z = 0;       // height, site frame (the surveyed height: projection is horizontal)
    // Metres from the plane, horizontally: positive to the right of A -> B, the side
    // the drawing is seen from (A on the left), i.e. in front of the section face;
    // negative behind it.
    double offset = 0;
  };
  std::vector<Surface> surfaces;  // capture order
  std::vector<Body> bodies;       // excavated units, in order
  std::vector<Find> finds;        // by chainage
  double finds_within_m = 0;      // |offset| limit the finds were taken with; 0: finds not projected

  double length() const { return (b - a).norm(); }
  Eigen::Vector2d point(double chainage) const { return a + (b - a).normalized() * chainage; }
};

}  // namespace strata
