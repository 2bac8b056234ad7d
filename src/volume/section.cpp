// Sections: the profile along a line through every layer surface and unit solid.
// Its writers (SVG drawing, GeoPackage) are in exporters/section.
#include "volume/section.hpp"

#include "core/error.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace strata {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

}  // namespace

SectionProfile cut_section(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const std::vector<LayerSurface>& layers,
                           const std::vector<UnitSolid>& solids, double step_m) {
  if (layers.empty()) throw InputError("section: there are no layer surfaces to cut");
  const double step = step_m > 0 ? step_m : layers.front().z.grid.cell;
  const double length = (b - a).norm();
  if (!(length >= 2 * step))
    throw InputError(fmt::format("section: the line is {:.3f} m long; it must be at least {:.3f} m", length, 2 * step));
  SectionProfile p;
  p.a = a;
  p.b = b;
  const int n = int(std::floor(length / step)) + 1;
  for (int i = 0; i < n; ++i) p.s.push_back(std::min(i * step, length));
  if (p.s.back() < length - 1e-9) p.s.push_back(length);
  for (const auto& l : layers) {
    SectionProfile::Surface s{l.layer, l.unit, {}};
    for (double c : p.s) {
      const Eigen::Vector2d q = p.point(c);
      s.z.push_back(sample_height(l.z, q.x(), q.y()));
    }
    p.surfaces.push_back(std::move(s));
  }
  for (const auto& solid : solids) {
    SectionProfile::Body body{solid.unit, {}, {}};
    for (double c : p.s) {
      const Eigen::Vector2d q = p.point(c);
      const double t = sample_height(solid.top, q.x(), q.y()), bt = sample_height(solid.bottom, q.x(), q.y());
      const bool ok = std::isfinite(t) && std::isfinite(bt) && t > bt;
      body.top.push_back(ok ? t : kNaN);
      body.bottom.push_back(ok ? bt : kNaN);
    }
    p.bodies.push_back(std::move(body));
  }
  return p;
}

}  // namespace strata
