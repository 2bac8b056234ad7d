#include "exporters/raster/geotiff.hpp"

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"
#include "exporters/raster/gdal_util.hpp"

#include <cpl_conv.h>
#include <gdal_priv.h>

#include <fmt/format.h>

#include <cerrno>
#include <cmath>
#include <memory>

namespace fs = std::filesystem;

namespace strata {
namespace {

using gdal_detail::DatasetPtr;
using gdal_detail::Options;
using gdal_detail::gdal_failed;
using gdal_detail::init_gdal;
using gdal_detail::last_gdal_error;
using gdal_detail::write_failure;

DatasetPtr make_mem(const RasterGrid& g, int bands, GDALDataType type, const RasterGeoreference& geo) {
  init_gdal();
  GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
  STRATA_CHECK(mem != nullptr, "GDAL has no MEM driver");
  DatasetPtr ds(mem->Create("", g.width, g.height, bands, type, nullptr));
  if (!ds) throw IoError("writer.geotiff: cannot create an in-memory raster: " + last_gdal_error());
  // North-up geotransform in real CRS coordinates: the origin comes back here and
  // only here (design.md "Frames and precision").
  double gt[6] = {geo.origin.x() + g.x_min, g.cell, 0.0, geo.origin.y() + g.y_max, 0.0, -g.cell};
  ds->SetGeoTransform(gt);
  if (!geo.crs_wkt.empty()) ds->SetProjection(geo.crs_wkt.c_str());
  return ds;
}

// Copies a MEM dataset to a GeoTIFF/COG at `path` through a temporary name.
void write_copy(GDALDataset* src, const fs::path& path, const GeoTiffOptions& o, bool floating) {
  Options opt;
  GDALDriver* drv = nullptr;
  const std::string compress = o.compression.empty() ? "NONE" : o.compression;
  if (o.cog) {
    drv = GetGDALDriverManager()->GetDriverByName("COG");
    opt.set("COMPRESS", compress);
    opt.set("BLOCKSIZE", "256");
    opt.set("OVERVIEWS", "AUTO");
    if (compress != "NONE") opt.set("PREDICTOR", "YES");  // floating-point or horizontal, per type
    opt.set("BIGTIFF", "IF_SAFER");
  } else {
    drv = GetGDALDriverManager()->GetDriverByName("GTiff");
    opt.set("TILED", "YES");
    opt.set("COMPRESS", compress);
    if (compress != "NONE") opt.set("PREDICTOR", floating ? "3" : "2");
    opt.set("BIGTIFF", "IF_SAFER");
  }
  if (!drv) throw IoError(fmt::format("writer.geotiff: {}: GDAL lacks the {} driver", path.string(),
                                      o.cog ? "COG" : "GTiff"));
  write_atomically(
      path, "writer.geotiff",
      [&](const fs::path& tmp) {
        CPLErrorReset();
        errno = 0;
        DatasetPtr out(drv->CreateCopy(tmp.string().c_str(), src, FALSE, opt.get(), nullptr, nullptr));
        const bool created = out != nullptr;
        out.reset();  // flush and close before the rename; a failure here is a failed write too
        if (!created || gdal_failed()) throw IoError(fmt::format("writer.geotiff: {}: {}", path.string(), write_failure(tmp)));
      },
      "products.geotiff.temp_written");
}

}  // namespace

void write_float_geotiff(const fs::path& path, const Dtm& raster, const RasterGeoreference& geo,
                         const FloatBand& band, const GeoTiffOptions& options) {
  const RasterGrid& g = raster.grid;
  if (g.width <= 0 || g.height <= 0) throw ProcessingError(fmt::format("writer.geotiff: {}: empty raster", path.string()));
  DatasetPtr ds = make_mem(g, 1, GDT_Float32, geo);
  std::vector<float> v(raster.z.size());
  for (std::size_t i = 0; i < v.size(); ++i) {
    // Absolute height in double, then Float32: about 0.1 mm resolution at 1,500 m.
    v[i] = std::isfinite(raster.z[i]) ? float(double(raster.z[i]) + band.value_offset) : float(kDtmNoData);
  }
  GDALRasterBand* b = ds->GetRasterBand(1);
  b->SetNoDataValue(kDtmNoData);
  b->SetDescription(band.description.c_str());
  if (!band.unit.empty()) b->SetUnitType(band.unit.c_str());
  if (b->RasterIO(GF_Write, 0, 0, g.width, g.height, v.data(), g.width, g.height, GDT_Float32, 0, 0, nullptr) !=
      CE_None) {
    throw IoError(fmt::format("writer.geotiff: {}: {}", path.string(), last_gdal_error()));
  }
  ds->SetMetadataItem("AREA_OR_POINT", "Area");
  write_copy(ds.get(), path, options, true);
}

void write_dtm_geotiff(const fs::path& path, const Dtm& dtm, const RasterGeoreference& geo,
                       const GeoTiffOptions& options) {
  write_float_geotiff(path, dtm, geo, {.description = "height", .unit = {}, .value_offset = geo.origin.z()}, options);
}

void write_rgba_geotiff(const fs::path& path, const RgbaRaster& image, const RasterGeoreference& geo,
                        const GeoTiffOptions& options) {
  const RasterGrid& g = image.grid;
  STRATA_CHECK(image.rgba.size() == g.cells() * 4, "RGBA size mismatch");
  if (g.width <= 0 || g.height <= 0) throw ProcessingError(fmt::format("writer.geotiff: {}: empty image", path.string()));
  DatasetPtr ds = make_mem(g, 4, GDT_Byte, geo);
  // Pixel-interleaved buffer: pixel stride 4, line stride 4*width, band stride 1.
  int bands[4] = {1, 2, 3, 4};
  if (ds->RasterIO(GF_Write, 0, 0, g.width, g.height, const_cast<std::uint8_t*>(image.rgba.data()), g.width,
                   g.height, GDT_Byte, 4, bands, 4, GSpacing(4) * g.width, 1, nullptr) != CE_None) {
    throw IoError(fmt::format("writer.geotiff: {}: {}", path.string(), last_gdal_error()));
  }
  const GDALColorInterp ci[4] = {GCI_RedBand, GCI_GreenBand, GCI_BlueBand, GCI_AlphaBand};
  for (int k = 0; k < 4; ++k) ds->GetRasterBand(k + 1)->SetColorInterpretation(ci[k]);
  write_copy(ds.get(), path, options, false);
}

}  // namespace strata
