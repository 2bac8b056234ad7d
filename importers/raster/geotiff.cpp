#include "importers/raster/geotiff.hpp"

#include "core/error.hpp"

#include <fmt/format.h>
#include <gdal_priv.h>

#include <algorithm>
#include <array>
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

void register_gdal() {
  static std::once_flag registered;
  std::call_once(registered, [] { GDALAllRegister(); });
}

}  // namespace

HeightRaster<double> read_height_geotiff(const fs::path& path, const Eigen::Vector3d& site_origin) {
  register_gdal();
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

RasterThumbnail read_raster_thumbnail(const fs::path& path, int max_px, bool average) {
  register_gdal();
  std::unique_ptr<GDALDataset, DatasetCloser> ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  if (!ds) throw IoError(fmt::format("reader.raster: {}: cannot read the raster", path.string()));
  const int w = ds->GetRasterXSize(), h = ds->GetRasterYSize();
  std::array<double, 6> gt{};
  if (ds->GetGeoTransform(gt.data()) != CE_None || gt[2] != 0 || gt[4] != 0 || w <= 0 || h <= 0) {
    throw IoError(fmt::format("reader.raster: {}: not a north-up georeferenced raster", path.string()));
  }
  const double f = std::max(1.0, double(std::max(w, h)) / std::max(1, max_px));
  RasterThumbnail t;
  t.width = std::max(1, int(std::lround(w / f)));
  t.height = std::max(1, int(std::lround(h / f)));
  t.bands = ds->GetRasterCount();
  t.west = gt[0];
  t.south = gt[3] + h * gt[5];
  t.east = gt[0] + w * gt[1];
  t.north = gt[3];
  GDALRasterIOExtraArg extra;
  INIT_RASTERIO_EXTRA_ARG(extra);
  extra.eResampleAlg = average ? GRIORA_Average : GRIORA_NearestNeighbour;
  t.band.resize(std::size_t(t.bands));
  for (int b = 0; b < t.bands; ++b) {
    auto& v = t.band[std::size_t(b)];
    v.resize(std::size_t(t.width) * std::size_t(t.height));
    if (ds->GetRasterBand(b + 1)->RasterIO(GF_Read, 0, 0, w, h, v.data(), t.width, t.height, GDT_Float32, 0, 0,
                                           &extra) != CE_None) {
      throw IoError(fmt::format("reader.raster: {}: cannot read band {}", path.string(), b + 1));
    }
  }
  int has_nodata = 0;
  const double nodata = t.bands ? ds->GetRasterBand(1)->GetNoDataValue(&has_nodata) : 0;
  t.valid.assign(std::size_t(t.width) * std::size_t(t.height), 1);
  if (t.bands) {
    for (std::size_t i = 0; i < t.valid.size(); ++i) {
      const float v = t.band[0][i];
      if (!std::isfinite(v) || (has_nodata && std::abs(double(v) - nodata) < 1e-3)) t.valid[i] = 0;
    }
  }
  return t;
}

}  // namespace strata
