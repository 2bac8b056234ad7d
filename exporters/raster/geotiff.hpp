#pragma once
// Raster writer (writer.geotiff): GeoTIFF / Cloud-Optimized GeoTIFF in the site
// CRS. GDAL stays in geotiff.cpp; raster tables inside the GeoPackage are in
// gpkg_raster.hpp.
#include "geometry/raster.hpp"

#include <filesystem>
#include <string>

namespace strata {

struct GeoTiffOptions {
  bool cog = true;                     // Cloud-Optimized GeoTIFF (GDAL COG driver) or plain tiled GTiff
  std::string compression = "DEFLATE"; // DEFLATE, LZW, ZSTD or NONE
};

// What the band of a Float32 raster holds.
struct FloatBand {
  std::string description = "height";
  std::string unit;         // "m", or empty when not stated
  double value_offset = 0;  // metres added to every value: origin Z for heights, 0 for thicknesses
};

// Float32 single band (raster.z + band.value_offset), nodata kDtmNoData. Written to
// a temporary file and renamed. Throws IoError("writer.geotiff: ...").
void write_float_geotiff(const std::filesystem::path& path, const Dtm& raster, const RasterGeoreference& geo,
                         const FloatBand& band, const GeoTiffOptions& options = {});
// Absolute heights (z + origin Z), band "height".
void write_dtm_geotiff(const std::filesystem::path& path, const Dtm& dtm, const RasterGeoreference& geo,
                       const GeoTiffOptions& options = {});
// 4-band Byte RGBA (alpha band flagged as such).
void write_rgba_geotiff(const std::filesystem::path& path, const RgbaRaster& image,
                        const RasterGeoreference& geo, const GeoTiffOptions& options = {});

}  // namespace strata
