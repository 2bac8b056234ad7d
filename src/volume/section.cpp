// Sections: the profile along a line through every layer surface and unit solid.
// Its writers (SVG drawing, GeoPackage) are in exporters/section.
#include "volume/section.hpp"

#include "core/door.hpp"
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
  if (!std::isfinite(step_m) || step_m < 0)
    throw InputError(fmt::format("section: the sampling step {} m is not a positive length", step_m));
  const double step = step_m > 0 ? step_m : layers.front().z.grid.cell;
  const double length = (b - a).norm();
  if (!std::isfinite(length)) throw InputError("section: the line's ends are not finite coordinates");
  if (!(length >= 2 * step))
    throw InputError(fmt::format("section: the line is {:.3f} m long; it must be at least {:.3f} m", length, 2 * step));
  // Each sample holds a height per surface and a span per solid: estimated before
  // the first is allocated (a step of 1e-9 m or a line of 1e10 m asks for terabytes).
  const double samples = std::floor(length / step) + 2;
  door::fits_in_memory(samples * double(sizeof(double)) * double(4 + 2 * layers.size() + 4 * solids.size()),
                       fmt::format("section: {:.3f} m sampled every {:g} m ({:.3g} samples)", length, step, samples),
                       "choose a larger --step");
  SectionProfile p;
  p.a = a;
  p.b = b;
  const std::size_t n = std::size_t(std::floor(length / step)) + 1;
  p.s.reserve(n + 1);
  for (std::size_t i = 0; i < n; ++i) p.s.push_back(std::min(double(i) * step, length));
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

void SectionFindOptions::validate() const {
  // A section's finds lie near its face: beyond 100 m they would be another trench's.
  if (!(within_m >= 0) || !std::isfinite(within_m) || within_m > 100)
    throw InputError(
        fmt::format("section: --finds-within {} must be 0 (no finds) or a distance of at most 100 m", within_m));
}

std::size_t add_section_finds(SectionProfile& p, const std::vector<FindRecord>& finds,
                              const Eigen::Vector3d& site_origin, const SectionFindOptions& options) {
  options.validate();
  p.finds.clear();
  p.finds_within_m = options.within_m;
  if (options.within_m <= 0 || !(p.length() > 0)) return 0;
  const Eigen::Vector2d along = (p.b - p.a).normalized();
  const Eigen::Vector2d right(along.y(), -along.x());  // A -> B turned clockwise
  for (const FindRecord& f : finds) {
    const Eigen::Vector3d x = f.position - site_origin;  // site frame
    const Eigen::Vector2d d = x.head<2>() - p.a;
    const double s = d.dot(along), offset = d.dot(right);
    // Only finds beside the line itself: one beyond A or B is not in this section.
    if (s < 0 || s > p.length() || std::abs(offset) > options.within_m) continue;
    p.finds.push_back({f.id, f.unit, f.type, x, s, x.z(), offset});
  }
  std::stable_sort(p.finds.begin(), p.finds.end(), [](const auto& a, const auto& b) { return a.s < b.s; });
  return p.finds.size();
}

}  // namespace strata
