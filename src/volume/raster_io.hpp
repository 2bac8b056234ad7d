#pragma once
// GeoTIFF height rasters in and thickness rasters out (GDAL stays in raster_io.cpp).
// Named stages in the PDAL manner: errors start with "reader.dtm" / "writer.thickness".
#include "dense/dense.hpp"  // HeightField

#include <Eigen/Core>

#include <filesystem>
#include <string>

namespace strata {

// Reads band 1 of a north-up raster of absolute heights in the site CRS (a DTM,
// the synthetic truth surface) as a HeightField on its own pixel centres, in the
// site frame: x = E - origin E, y = N - origin N, z = Z - origin Z. Nodata -> NaN.
// Pixels must be square. Throws IoError / InputError naming the file.
HeightField read_height_raster(const std::filesystem::path& path, const Eigen::Vector3d& site_origin);

// Writes a Float32 GeoTIFF of a site-frame field (NaN = nodata -9999) with real
// CRS coordinates: each value + `value_offset` (0 for thicknesses, origin Z for
// heights). `crs` is what describe_crs accepts ("EPSG:32636"). Written to a
// temporary file and renamed.
void write_field_geotiff(const std::filesystem::path& path, const HeightField& field,
                         const Eigen::Vector3d& site_origin, const std::string& crs,
                         double value_offset, const std::string& description);

}  // namespace strata
