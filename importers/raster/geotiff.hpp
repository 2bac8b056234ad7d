#pragma once
// GeoTIFF rasters in: height rasters (reader.dtm: a DTM, a DTM's sigma, the
// synthetic truth surface) and reduced copies of any north-up raster for display
// (reader.raster). GDAL stays in geotiff.cpp.
#include "geometry/raster.hpp"
#include "project/project.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <string_view>
#include <vector>

namespace strata {

// Reads band 1 of a north-up raster of absolute heights in the site CRS into the
// site frame: x = E - origin E, y = N - origin N, z = Z - origin Z (in double: no
// rounding beyond the file's). Nodata -> NaN. Pixels must be square. Throws
// IoError / InputError naming the file.
// Refuses, before reading, a raster whose pixels would not fit in memory
// (door::fits_in_memory: a header may claim 10^6 x 10^6 pixels).
HeightRaster<double> read_height_geotiff(const std::filesystem::path& path, const Eigen::Vector3d& site_origin);
// A surface a user hands strata (`--surface LAYER=FILE`), checked at the door: a
// regular file; in another CRS than the site's, warped into it (bilinear, with a
// warning naming both); without a CRS, taken in the site CRS when its centre is a
// place of the site (project/site_bounds.hpp), else refused. `what` names it.
HeightRaster<double> read_site_height_geotiff(const std::filesystem::path& path, const SiteInfo& site,
                                              std::string_view what);

// A raster product read at reduced size (GDAL RasterIO with resampling), every band
// as float, for drawing it.
struct RasterThumbnail {
  int width = 0, height = 0, bands = 0;
  std::vector<std::vector<float>> band;  // row-major north-up
  std::vector<std::uint8_t> valid;       // 1 where band 1 is finite and not nodata
  // The outer edges in CRS coordinates (not the site frame), metres.
  double west = 0, south = 0, east = 0, north = 0;
};
// Reads at most `max_px` pixels along the longer side, averaging the pixels each
// thumbnail pixel covers when `average` (else the nearest). Throws IoError naming
// the file.
RasterThumbnail read_raster_thumbnail(const std::filesystem::path& path, int max_px, bool average);

// The extent of a north-up raster without reading its pixels: its outer edges in CRS
// coordinates (metres), its pixel size and band count. Throws IoError naming the file.
struct RasterExtent {
  double west = 0, south = 0, east = 0, north = 0;
  double pixel_m = 0;  // east-west pixel size
  int width = 0, height = 0, bands = 0;
};
RasterExtent read_raster_extent(const std::filesystem::path& path);

// The part of a north-up raster inside the CRS rectangle [west, east] x [south, north]
// resampled onto width x height pixels (a map tile): GDAL RasterIO with a floating-point
// source window, averaging when a pixel covers several of the file's, bilinear when it
// covers less than one. Pixels outside the file's data are not `valid` (band values
// 0); a 4-band raster's 4th band is its alpha (valid where > 0). Throws IoError naming
// the file.
RasterThumbnail read_raster_window(const std::filesystem::path& path, double west, double south, double east,
                                   double north, int width, int height);

}  // namespace strata
