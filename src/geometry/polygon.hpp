#pragma once
// Plane polygons in the site frame (metres): trench outlines, footprints, the area a
// check is restricted to.
#include <Eigen/Core>

#include <cstddef>
#include <vector>

namespace strata {

// Whether (x, y) lies inside the polygon: the even-odd rule, a ray cast along +x
// (closed or open ring).
inline bool inside_polygon(const std::vector<Eigen::Vector2d>& poly, double x, double y) {
  bool in = false;
  for (std::size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    const Eigen::Vector2d& a = poly[i];
    const Eigen::Vector2d& b = poly[j];
    if ((a.y() > y) != (b.y() > y)) {
      const double xc = a.x() + (y - a.y()) * (b.x() - a.x()) / (b.y() - a.y());
      if (x < xc) in = !in;
    }
  }
  return in;
}

}  // namespace strata
