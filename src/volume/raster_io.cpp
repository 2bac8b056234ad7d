// GeoTIFF height rasters (reader.dtm) and thickness rasters (writer.thickness).
#include "volume/raster_io.hpp"

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "crs/crs.hpp"
#include "products/gdal_util.hpp"

#include <cpl_error.h>
#include <fmt/format.h>
#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <cerrno>
#include <cmath>
#include <limits>
#include <memory>

namespace strata {
namespace fs = std::filesystem;
namespace {

constexpr double kNodata = -9999.0;

using products_detail::DatasetPtr;

}  // namespace

HeightField read_height_raster(const fs::path& path, const Eigen::Vector3d& site_origin) {
  GDALAllRegister();
  DatasetPtr ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
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
  const int cols = ds->GetRasterXSize(), rows = ds->GetRasterYSize();
  GDALRasterBand* band = ds->GetRasterBand(1);
  int has_nodata = 0;
  const double nodata = band->GetNoDataValue(&has_nodata);
  std::vector<double> values(std::size_t(cols) * std::size_t(rows));
  if (band->RasterIO(GF_Read, 0, 0, cols, rows, values.data(), cols, rows, GDT_Float64, 0, 0) != CE_None)
    throw IoError(fmt::format("reader.dtm: {}: cannot read band 1", path.string()));
  HeightField f;
  f.cell = cell;
  f.nx = cols;
  f.ny = rows;
  // Pixel centres; row 0 is the northernmost, HeightField j grows northwards.
  f.x0 = gt[0] + 0.5 * cell - site_origin.x();
  f.y0 = gt[3] - (rows - 0.5) * cell - site_origin.y();
  f.z.assign(values.size(), std::numeric_limits<double>::quiet_NaN());
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      const double v = values[std::size_t(r) * cols + c];
      if ((has_nodata && v == nodata) || !std::isfinite(v)) continue;
      f.z[std::size_t(rows - 1 - r) * cols + c] = v - site_origin.z();
    }
  return f;
}

void write_field_geotiff(const fs::path& path, const HeightField& field, const Eigen::Vector3d& site_origin,
                         const std::string& crs, double value_offset, const std::string& description) {
  GDALAllRegister();
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GTiff");
  if (!driver) throw IoError("writer.thickness: GDAL has no GTiff driver");
  write_atomically(path, "writer.thickness", [&](const fs::path& tmp) {
    char** opts = nullptr;
    opts = CSLSetNameValue(opts, "COMPRESS", "DEFLATE");
    opts = CSLSetNameValue(opts, "PREDICTOR", "3");
    opts = CSLSetNameValue(opts, "TILED", "YES");
    // A failure anywhere (create, a row, the flush on close: a full disk) names the
    // cause; write_atomically removes the temporary.
    auto failed = [&](const std::string& what) {
      const std::string why = products_detail::write_failure(tmp);
      return IoError(fmt::format("writer.thickness: {}: {}{}", path.string(), what, why));
    };
    CPLErrorReset();
    errno = 0;
    {
      DatasetPtr ds(driver->Create(tmp.c_str(), field.nx, field.ny, 1, GDT_Float32, opts));
      CSLDestroy(opts);
      if (!ds) throw failed("cannot create: ");
      const double west = site_origin.x() + field.x0 - 0.5 * field.cell;
      const double north = site_origin.y() + field.y0 + (field.ny - 0.5) * field.cell;
      double gt[6] = {west, field.cell, 0, north, 0, -field.cell};
      ds->SetGeoTransform(gt);
      OGRSpatialReference srs;
      const CrsInfo info = describe_crs(crs);
      if (srs.importFromWkt(info.wkt.c_str()) == OGRERR_NONE) {
        srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
        ds->SetSpatialRef(&srs);
      }
      GDALRasterBand* band = ds->GetRasterBand(1);
      band->SetNoDataValue(kNodata);
      band->SetDescription(description.c_str());
      band->SetUnitType("m");
      std::vector<float> row(std::size_t(field.nx));
      CPLErrorReset();  // from here, any GDAL failure is the writing's
      errno = 0;
      for (int r = 0; r < field.ny; ++r) {
        const int j = field.ny - 1 - r;
        for (int i = 0; i < field.nx; ++i) {
          const double v = field.at(i, j);
          row[std::size_t(i)] = std::isfinite(v) ? float(v + value_offset) : float(kNodata);
        }
        if (band->RasterIO(GF_Write, 0, r, field.nx, 1, row.data(), field.nx, 1, GDT_Float32, 0, 0) != CE_None) {
          ds.reset();
          throw failed(fmt::format("cannot write row {}: ", r));
        }
      }
    }  // closed: GDAL flushes here, and a failure shows in its error state
    if (products_detail::gdal_failed()) throw failed("");
  });
}

}  // namespace strata
