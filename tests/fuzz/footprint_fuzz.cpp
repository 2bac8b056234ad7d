// reader.footprint: the trench outline (or a unit's footprint) that `strata volume
// --outline FILE` reads through GDAL: any vector format GDAL opens; the seeds are
// GeoJSON, what QGIS users draw and save. An accepted outline is at least a triangle
// of finite points.
#include "fuzz/fuzz_support.hpp"
#include "fuzz/targets.hpp"
#include "volume/site_volumes.hpp"

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
  const Eigen::Vector3d origin(500000.0, 4000000.0, 100.0);  // metres, site CRS
  if (!accepts([&] { ring = read_footprint(file, origin); }, kInputName)) return 0;
  if (ring.size() < 3) throw FuzzFailure("reader.footprint: accepted an outline of fewer than 3 points");
  for (const auto& p : ring) {
    if (!p.allFinite()) throw FuzzFailure("reader.footprint: accepted an outline with a point that is not finite");
  }
  return 0;
}

}  // namespace strata::fuzz
