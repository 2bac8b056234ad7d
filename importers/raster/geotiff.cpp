#include "importers/raster/geotiff.hpp"

#include "core/error.hpp"

#include <fmt/format.h>
#include <gdal_priv.h>

#include <cmath>
#include <limits>
#include <memory>
#include <mutex>

namespace strata {
namespace fs = std::filesystem;
namespace {

struct DatasetCloser {
  void operator()(GDALDataset* d) const { GDALClose(GDALDataset::ToHandle(d)); }
};

}  // namespace

HeightRaster<double> read_height_geotiff(const fs::path& path, const Eigen::Vector3d& site_origin) {
  static std::once_flag registered;
  std::call_once(registered, [] { GDALAllRegister(); });
  std::unique_ptr<GDALDataset, DatasetCloser> ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  if (!ds) throw IoError(fmt::format("reader.dtm: {}: cannot open as a raster", path.string()));
  if (ds->GetRasterCount() < 1) throw InputError(fmt::format("reader.dtm: {}: no raster band", path.string()));
  double gt[6];
  if (ds->GetGeoTransform(gt) != CE_None)
    throw InputError(fmt::format("reader.dtm: {}: no geotransform (not georeferenced)", path.string()));
  if (gt[2] != 0 || gt[4] != 0 || gt[5] >= 0)
    throw InputError(fmt::format("reader.dtm: {}: rotated or south-up rasters are not supported", path.string()));
  const double cell = gt[1];
  if (std::abs(-gt[5] - cell) > 1e-9 * cell)
    throw InputError(fmt::format("reader.dtm: {}: pixels are {} x {} m, not square", path.string(), gt[1], -gt[5]));
  HeightRaster<double> r;
  r.grid.cell = cell;
  r.grid.x_min = gt[0] - site_origin.x();
  r.grid.y_max = gt[3] - site_origin.y();
  r.grid.width = ds->GetRasterXSize();
  r.grid.height = ds->GetRasterYSize();
  GDALRasterBand* band = ds->GetRasterBand(1);
  int has_nodata = 0;
  const double nodata = band->GetNoDataValue(&has_nodata);
  r.z.resize(r.grid.cells());
  if (band->RasterIO(GF_Read, 0, 0, r.grid.width, r.grid.height, r.z.data(), r.grid.width, r.grid.height,
                     GDT_Float64, 0, 0) != CE_None)
    throw IoError(fmt::format("reader.dtm: {}: cannot read band 1", path.string()));
  for (double& v : r.z)
    v = (has_nodata && v == nodata) || !std::isfinite(v) ? std::numeric_limits<double>::quiet_NaN()
                                                          : v - site_origin.z();
  return r;
}

}  // namespace strata
