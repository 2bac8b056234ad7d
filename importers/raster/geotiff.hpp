#pragma once
// GeoTIFF height rasters in (reader.dtm): a DTM, a DTM's sigma, the synthetic
// truth surface. GDAL stays in geotiff.cpp.
#include "geometry/raster.hpp"

#include <Eigen/Core>

#include <filesystem>

namespace strata {

// Reads band 1 of a north-up raster of absolute heights in the site CRS into the
// site frame: x = E - origin E, y = N - origin N, z = Z - origin Z (in double: no
// rounding beyond the file's). Nodata -> NaN. Pixels must be square. Throws
// IoError / InputError naming the file.
HeightRaster<double> read_height_geotiff(const std::filesystem::path& path, const Eigen::Vector3d& site_origin);

}  // namespace strata
