#include "importers/raster/geotiff.hpp"

#include "core/door.hpp"
#include "core/error.hpp"
#include "core/log.hpp"
#include "crs/crs.hpp"
#include "project/site_bounds.hpp"

#include <fmt/format.h>
#include <gdal_priv.h>
#include <gdalwarper.h>
#include <ogr_spatialref.h>

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

namespace {

// Band 1 of an open north-up raster of heights, into the site frame.
HeightRaster<double> read_heights(GDALDataset* ds, const fs::path& path, const Eigen::Vector3d& site_origin) {
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
  if (!(cell > 0) || !std::isfinite(cell) || !std::isfinite(gt[0]) || !std::isfinite(gt[3]))
    throw InputError(fmt::format("reader.dtm: {}: the geotransform is not a grid of positive pixels", path.string()));
  door::fits_in_memory(double(r.grid.width) * double(r.grid.height) * 2 * sizeof(double),
                       fmt::format("reader.dtm: {}: {} x {} pixels", path.string(), r.grid.width, r.grid.height),
                       "a raster of the trench at its ground resolution is far smaller");
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

}  // namespace

HeightRaster<double> read_height_geotiff(const fs::path& path, const Eigen::Vector3d& site_origin) {
  register_gdal();
  door::input_file(path, "reader.dtm: raster");
  std::unique_ptr<GDALDataset, DatasetCloser> ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  if (!ds) throw IoError(fmt::format("reader.dtm: {}: cannot open as a raster", path.string()));
  return read_heights(ds.get(), path, site_origin);
}

HeightRaster<double> read_site_height_geotiff(const fs::path& path, const SiteInfo& site, std::string_view what) {
  register_gdal();
  door::input_file(path, what);
  std::unique_ptr<GDALDataset, DatasetCloser> ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  if (!ds) throw IoError(fmt::format("reader.dtm: {} {}: cannot open as a raster", what, path.string()));
  const OGRSpatialReference* srs = ds->GetSpatialRef();
  if (!srs) {
    double gt[6];
    if (ds->GetGeoTransform(gt) == CE_None) {
      const Eigen::Vector2d centre(gt[0] + gt[1] * ds->GetRasterXSize() / 2, gt[3] + gt[5] * ds->GetRasterYSize() / 2);
      check_site_position(site, centre, fmt::format("reader.dtm: {} {} (no CRS: read in the site CRS), its centre",
                                                    what, path.string()));
    }
    return read_heights(ds.get(), path, site.origin);
  }
  OGRSpatialReference site_srs;
  site_srs.SetFromUserInput(describe_crs(site.crs).wkt.c_str());
  if (srs->IsSame(&site_srs)) return read_heights(ds.get(), path, site.origin);
  char* site_wkt = nullptr;
  site_srs.exportToWkt(&site_wkt);
  const std::string dst(site_wkt ? site_wkt : "");
  CPLFree(site_wkt);
  std::unique_ptr<GDALDataset, DatasetCloser> warped(GDALDataset::FromHandle(
      GDALAutoCreateWarpedVRT(GDALDataset::ToHandle(ds.get()), nullptr, dst.c_str(), GRA_Bilinear, 0.0, nullptr)));
  if (!warped)
    throw CrsError(fmt::format("reader.dtm: {} {}: its CRS ({}) cannot be transformed into the site CRS {}", what,
                               path.string(), srs->GetName() ? srs->GetName() : "unnamed", site.crs));
  log::warn("reader.dtm: {} {} is in {}, not the site CRS {}: warped into it (bilinear)", what, path.string(),
            srs->GetName() ? srs->GetName() : "another CRS", site.crs);
  return read_heights(warped.get(), path, site.origin);
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

namespace {

struct OpenRaster {
  std::unique_ptr<GDALDataset, DatasetCloser> ds;
  std::array<double, 6> gt{};
  int width = 0, height = 0;
};

OpenRaster open_north_up(const fs::path& path) {
  register_gdal();
  OpenRaster r;
  r.ds.reset(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  if (!r.ds) throw IoError(fmt::format("reader.raster: {}: cannot read the raster", path.string()));
  r.width = r.ds->GetRasterXSize();
  r.height = r.ds->GetRasterYSize();
  if (r.ds->GetGeoTransform(r.gt.data()) != CE_None || r.gt[2] != 0 || r.gt[4] != 0 || r.gt[1] <= 0 ||
      r.gt[5] >= 0 || r.width <= 0 || r.height <= 0) {
    throw IoError(fmt::format("reader.raster: {}: not a north-up georeferenced raster", path.string()));
  }
  return r;
}

}  // namespace

RasterExtent read_raster_extent(const fs::path& path) {
  const OpenRaster r = open_north_up(path);
  RasterExtent e;
  e.width = r.width;
  e.height = r.height;
  e.bands = r.ds->GetRasterCount();
  e.pixel_m = r.gt[1];
  e.west = r.gt[0];
  e.north = r.gt[3];
  e.east = r.gt[0] + r.width * r.gt[1];
  e.south = r.gt[3] + r.height * r.gt[5];
  return e;
}

RasterThumbnail read_raster_window(const fs::path& path, double west, double south, double east, double north,
                                   int width, int height) {
  if (!(east > west) || !(north > south) || width <= 0 || height <= 0) {
    throw IoError(fmt::format("reader.raster: {}: an empty window was asked for", path.string()));
  }
  const OpenRaster r = open_north_up(path);
  RasterThumbnail t;
  t.width = width;
  t.height = height;
  t.bands = r.ds->GetRasterCount();
  t.west = west;
  t.south = south;
  t.east = east;
  t.north = north;
  const std::size_t n = std::size_t(width) * std::size_t(height);
  t.band.assign(std::size_t(t.bands), std::vector<float>(n, 0.0f));
  t.valid.assign(n, 0);
  // The window in the file's pixels (fractional), and the tile pixels it maps to:
  // only whole tile pixels that lie inside the file are read.
  const double px = (east - west) / width, py = (north - south) / height;  // metres per tile pixel
  const double file_px = r.gt[1], file_py = -r.gt[5];
  const double fx0 = (west - r.gt[0]) / file_px, fy0 = (r.gt[3] - north) / file_py;
  const double per_x = px / file_px, per_y = py / file_py;  // file pixels per tile pixel
  const int c0 = std::clamp(int(std::ceil(-fx0 / per_x - 1e-9)), 0, width);
  const int c1 = std::clamp(int(std::floor((r.width - fx0) / per_x + 1e-9)), 0, width);
  const int r0 = std::clamp(int(std::ceil(-fy0 / per_y - 1e-9)), 0, height);
  const int r1 = std::clamp(int(std::floor((r.height - fy0) / per_y + 1e-9)), 0, height);
  if (c1 <= c0 || r1 <= r0 || t.bands == 0) return t;
  const int cw = c1 - c0, rh = r1 - r0;
  const double sx0 = std::clamp(fx0 + c0 * per_x, 0.0, double(r.width));
  const double sy0 = std::clamp(fy0 + r0 * per_y, 0.0, double(r.height));
  const double sw = std::min(cw * per_x, r.width - sx0), sh = std::min(rh * per_y, r.height - sy0);
  GDALRasterIOExtraArg extra;
  INIT_RASTERIO_EXTRA_ARG(extra);
  extra.eResampleAlg = per_x > 1 ? GRIORA_Average : GRIORA_Bilinear;
  extra.bFloatingPointWindowValidity = TRUE;
  extra.dfXOff = sx0;
  extra.dfYOff = sy0;
  extra.dfXSize = sw;
  extra.dfYSize = sh;
  const int ix0 = std::clamp(int(std::floor(sx0)), 0, r.width - 1);
  const int iy0 = std::clamp(int(std::floor(sy0)), 0, r.height - 1);
  const int ixs = std::clamp(int(std::ceil(sx0 + sw)) - ix0, 1, r.width - ix0);
  const int iys = std::clamp(int(std::ceil(sy0 + sh)) - iy0, 1, r.height - iy0);
  std::vector<float> part(std::size_t(cw) * std::size_t(rh));
  for (int b = 0; b < t.bands; ++b) {
    if (r.ds->GetRasterBand(b + 1)->RasterIO(GF_Read, ix0, iy0, ixs, iys, part.data(), cw, rh, GDT_Float32, 0, 0,
                                             &extra) != CE_None) {
      throw IoError(fmt::format("reader.raster: {}: cannot read band {}", path.string(), b + 1));
    }
    auto& out = t.band[std::size_t(b)];
    for (int row = 0; row < rh; ++row) {
      std::copy_n(part.begin() + std::ptrdiff_t(row) * cw, cw,
                  out.begin() + std::ptrdiff_t(r0 + row) * width + c0);
    }
  }
  int has_nodata = 0;
  const double nodata = r.ds->GetRasterBand(1)->GetNoDataValue(&has_nodata);
  for (int row = r0; row < r1; ++row) {
    for (int col = c0; col < c1; ++col) {
      const std::size_t i = std::size_t(row) * std::size_t(width) + std::size_t(col);
      const float v = t.band[0][i];
      bool ok = std::isfinite(v) && !(has_nodata && std::abs(double(v) - nodata) < 1e-3);
      if (t.bands == 4) ok = ok && t.band[3][i] > 0;
      t.valid[i] = ok ? 1 : 0;
    }
  }
  return t;
}

}  // namespace strata
