#pragma once
// Raster writers (writer.geotiff, writer.gpkg_raster): GeoTIFF / Cloud-Optimized
// GeoTIFF in the site CRS, and raster tables inside project.gpkg. GDAL stays in
// geotiff.cpp.
#include "geometry/raster.hpp"
#include "project/database.hpp"

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

// Raster table name for a layer: prefix + "_" + the layer name with anything but
// [A-Za-z0-9_] replaced by '_' (SQLite identifiers that QGIS and GDAL accept).
std::string raster_table_name(const std::string& prefix, const std::string& layer);

enum class GpkgRasterKind {
  gridded_coverage,  // Float32 elevation (OGC 17-066r1), TIFF tiles
  tiles_png,         // RGBA PNG tiles
};

// Copies a GeoTIFF into the GeoPackage as a raster table (GDAL GPKG driver,
// APPEND_SUBDATASET=YES), replacing a table of the same name. Must be called with
// no strata transaction open on the file (GDAL opens its own connection).
void write_gpkg_raster(const std::filesystem::path& gpkg, const std::filesystem::path& source_tif,
                       const std::string& table, GpkgRasterKind kind, const std::string& description);

// Removes a raster table and its GeoPackage bookkeeping rows (tile matrix, gridded
// coverage ancillary, extensions). No-op when it does not exist.
void drop_gpkg_raster_table(Database& db, const std::string& table);

}  // namespace strata
