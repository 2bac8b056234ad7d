// reader.outline: the trench outline (or a unit's footprint) that `strata volume
// --outline FILE` reads through GDAL: any vector format GDAL opens; the seeds are
// GeoJSON, what QGIS users draw and save. An accepted outline is at least a triangle
// of finite points, every one within the site's bounds, and does not cross itself.
#include "fuzz/fuzz_support.hpp"
#include "fuzz/targets.hpp"
#include "importers/vector/outline.hpp"
#include "project/site_bounds.hpp"

#include <cpl_error.h>

namespace strata::fuzz {

int footprint(const std::uint8_t* data, std::size_t size) {
  constexpr const char* kInputName = "outline_input.geojson";
  // GDAL's drivers report what they refuse on stderr; strata's error says it once.
  static const bool quiet = [] {
    CPLSetErrorHandler(CPLQuietErrorHandler);
    return true;
  }();
  (void)quiet;
  const auto file = write_input(kInputName, data, size);
  std::vector<Eigen::Vector2d> ring;
  SiteInfo site;  // the seeds' site: UTM 36N, origin at 734000 E, 4174000 N
  site.crs = "EPSG:32636";
  site.origin = {734000.0, 4174000.0, 100.0};
  site.origin_set = true;
  if (!accepts([&] { ring = read_outline(file, site, ""); }, kInputName)) return 0;
  if (ring.size() < 3) throw FuzzFailure("reader.outline: accepted an outline of fewer than 3 points");
  for (const auto& p : ring) {
    if (!p.allFinite()) throw FuzzFailure("reader.outline: accepted an outline with a point that is not finite");
    if (p.norm() > kSiteRadius_m + 1) throw FuzzFailure("reader.outline: accepted a vertex far from the site");
  }
  return 0;
}

}  // namespace strata::fuzz
