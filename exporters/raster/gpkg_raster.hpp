#pragma once
// Raster tables inside project.gpkg (writer.gpkg_raster), from the GeoTIFFs that
// geotiff.hpp writes. GDAL stays in gpkg_raster.cpp.
#include <filesystem>
#include <string>

namespace strata {

// Raster table name for a layer: prefix + "_" + the layer name with anything but
// [A-Za-z0-9_] replaced by '_' (SQLite identifiers that QGIS and GDAL accept).
std::string raster_table_name(const std::string& prefix, const std::string& layer);

enum class GpkgRasterKind {
  gridded_coverage,  // Float32 elevation (OGC 17-066r1), TIFF tiles
  tiles_png,         // RGBA PNG tiles
};

// Copies a GeoTIFF into the GeoPackage as a raster table (GDAL GPKG driver,
// APPEND_SUBDATASET=YES), replacing a table of the same name and its GeoPackage
// bookkeeping rows (tile matrix, gridded coverage ancillary, extensions). Must be
// called with no strata transaction open on the file (GDAL opens its own connection).
void write_gpkg_raster(const std::filesystem::path& gpkg, const std::filesystem::path& source_tif,
                       const std::string& table, GpkgRasterKind kind, const std::string& description);

}  // namespace strata
