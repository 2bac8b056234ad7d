#include "project/site_bounds.hpp"

#include "core/error.hpp"
#include "crs/crs.hpp"

#include <fmt/format.h>

#include <cmath>
#include <map>
#include <mutex>
#include <optional>

namespace strata {
namespace {

// The area of use of a CRS and its transformation to longitude and latitude, made
// once per CRS (PROJ's database lookups cost milliseconds; an import checks
// thousands of points).
struct CrsBounds {
  std::optional<AreaOfUse> area;
  std::optional<CrsTransform> to_lonlat;
};

const CrsBounds& bounds_of(const std::string& crs) {
  static std::mutex mutex;
  static std::map<std::string, CrsBounds> cache;
  const std::lock_guard lock(mutex);
  auto it = cache.find(crs);
  if (it != cache.end()) return it->second;
  CrsBounds b;
  try {
    b.area = area_of_use(crs);
    if (b.area) b.to_lonlat.emplace(crs, "EPSG:4326");
  } catch (const CrsError&) {
    b.area.reset();  // a CRS PROJ cannot place: only the distance to the site is checked
  }
  return cache.emplace(crs, std::move(b)).first->second;
}

bool within(double v, double lo, double hi) { return v >= lo && v <= hi; }

// Longitude `lon` within [west, east] widened by the margin, across 180 degrees too.
bool within_longitudes(double lon, double west, double east, double margin) {
  if (west <= east) return within(lon, west - margin, east + margin);
  return lon >= west - margin || lon <= east + margin;
}

void check_plan(const SiteInfo& site, double e, double n, std::string_view what, const std::string& shown) {
  // Beyond any projected CRS's range (PROJ would return infinities).
  constexpr double kMaxProjected_m = 1e8;
  if (!std::isfinite(e) || !std::isfinite(n) || std::abs(e) > kMaxProjected_m || std::abs(n) > kMaxProjected_m)
    throw InputError(fmt::format("{}: {} is not a coordinate in the site CRS {}", what, shown, site.crs));
  if (site.origin_set) {
    const double d = std::hypot(e - site.origin.x(), n - site.origin.y());
    if (d > kSiteRadius_m)
      throw InputError(fmt::format("{}: {} is {:.1f} km from the site's origin ({:.3f}, {:.3f}); a point of the site "
                                   "lies within {:g} km of it (a digit missing, or another CRS?)",
                                   what, shown, d / 1000, site.origin.x(), site.origin.y(), kSiteRadius_m / 1000));
  }
  const CrsBounds& b = bounds_of(site.crs);
  if (!b.area || !b.to_lonlat) return;
  Eigen::Vector3d ll;
  try {
    ll = b.to_lonlat->apply({e, n, 0});
  } catch (const CrsError&) {
    throw InputError(fmt::format("{}: {} is not a place in the site CRS {}", what, shown, site.crs));
  }
  const AreaOfUse& a = *b.area;
  if (!within_longitudes(ll.x(), a.west, a.east, kAreaOfUseMargin_deg) ||
      !within(ll.y(), a.south - kAreaOfUseMargin_deg, a.north + kAreaOfUseMargin_deg))
    throw InputError(fmt::format("{}: {} lies at {:.3f}°, {:.3f}° (longitude, latitude), outside the area where the "
                                 "site CRS {} is used ({}); is it in another CRS?",
                                 what, shown, ll.x(), ll.y(), site.crs, a.name.empty() ? "its area of use" : a.name));
}

}  // namespace

void check_site_position(const SiteInfo& site, const Eigen::Vector2d& p, std::string_view what) {
  check_plan(site, p.x(), p.y(), what, fmt::format("E, N = {}, {}", p.x(), p.y()));
}

void check_site_point(const SiteInfo& site, const Eigen::Vector3d& p, std::string_view what) {
  const std::string shown = fmt::format("E, N, Z = {}, {}, {}", p.x(), p.y(), p.z());
  check_plan(site, p.x(), p.y(), what, shown);
  if (!std::isfinite(p.z()) || p.z() < kLowestZ_m || p.z() > kHighestZ_m)
    throw InputError(fmt::format("{}: {}: the height is not between {:g} and {:g} m", what, shown, kLowestZ_m,
                                 kHighestZ_m));
}

}  // namespace strata
