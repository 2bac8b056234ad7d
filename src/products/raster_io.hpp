#pragma once
// Raster writers of the products (writer.geotiff, writer.gpkg_raster): GeoTIFF /
// Cloud-Optimized GeoTIFF in the site CRS, and raster tables inside project.gpkg.
// GDAL stays in raster_io.cpp.
#include "products/dtm.hpp"
#include "project/database.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace strata {

// Where a site-frame grid sits in the real world.
struct RasterGeoreference {
  std::string crs_wkt;                               // WKT of the site CRS (describe_crs().wkt)
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();  // site origin E, N, Z (metres)
};

struct GeoTiffOptions {
  bool cog = true;                     // Cloud-Optimized GeoTIFF (GDAL COG driver) or plain tiled GTiff
  std::string compression = "DEFLATE"; // DEFLATE, LZW, ZSTD or NONE
};

// No-data value of DTM files: a finite number, because some GIS tools (and GRASS
// r.in.gdal) treat NaN inconsistently.
constexpr double kDtmNoData = -9999.0;

// RGBA image on a site-frame grid; alpha 0 where nothing was seen.
struct RgbaRaster {
  RasterGrid grid;
  std::vector<std::uint8_t> rgba;  // row-major north-up, 4 bytes per cell
};

// Float32 single band of absolute heights (z + origin.z), nodata kDtmNoData.
// Written to a temporary file and renamed. Throws IoError("writer.geotiff: ...").
void write_dtm_geotiff(const std::filesystem::path& path, const Dtm& dtm, const RasterGeoreference& geo,
                       const GeoTiffOptions& options = {});
// 4-band Byte RGBA (alpha band flagged as such).
void write_rgba_geotiff(const std::filesystem::path& path, const RgbaRaster& image,
                        const RasterGeoreference& geo, const GeoTiffOptions& options = {});

// Reads a DTM GeoTIFF back into the site frame (for exports and tests).
Dtm read_dtm_geotiff(const std::filesystem::path& path, const Eigen::Vector3d& origin);

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
