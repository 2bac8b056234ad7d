#include "products/raster_io.hpp"

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/log.hpp"

#include <cpl_conv.h>
#include <cpl_string.h>
#include <gdal_priv.h>

#include "products/gdal_util.hpp"

#include <fmt/format.h>

#include <cerrno>
#include <cmath>
#include <memory>
#include <mutex>

namespace fs = std::filesystem;

namespace strata {
namespace products_detail {

std::string last_gdal_error() {
  const char* m = CPLGetLastErrorMsg();
  return m && *m ? m : "unknown GDAL error";
}

// Why writing `tmp` failed. GDAL reports a full disk as whatever libtiff met first
// ("TIFFAppendToStrip: Seek error"), so a file system left with almost no room, or
// errno ENOSPC, is named as such.
std::string write_failure(const fs::path& tmp) {
  const int saved_errno = errno;
  std::error_code ec;
  const auto space = fs::space(tmp.parent_path(), ec);
  constexpr std::uintmax_t kNearlyFull = 1u << 20;
  if (saved_errno == ENOSPC || (!ec && space.available < kNearlyFull)) {
    return fmt::format("No space left on device ({} KiB free on the file system of {}; GDAL said: {})",
                       ec ? 0 : space.available / 1024, tmp.parent_path().string(), last_gdal_error());
  }
  return last_gdal_error();
}

}  // namespace products_detail

namespace {

using products_detail::DatasetPtr;
using products_detail::gdal_failed;
using products_detail::init_gdal;
using products_detail::last_gdal_error;
using products_detail::write_failure;

// Owned list of "KEY=VALUE" creation options.
class Options {
 public:
  Options() = default;
  ~Options() { CSLDestroy(list_); }
  Options(const Options&) = delete;
  Options& operator=(const Options&) = delete;
  void set(const char* key, const std::string& value) { list_ = CSLSetNameValue(list_, key, value.c_str()); }
  char** get() const { return list_; }

 private:
  char** list_ = nullptr;
};

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

bool table_exists(Database& db, const std::string& name) {
  auto st = db.prepare("SELECT 1 FROM sqlite_master WHERE type IN ('table', 'view') AND name = ?");
  st.bind(1, name);
  return st.step();
}

}  // namespace

void write_dtm_geotiff(const fs::path& path, const Dtm& dtm, const RasterGeoreference& geo,
                       const GeoTiffOptions& options) {
  const RasterGrid& g = dtm.grid;
  if (g.width <= 0 || g.height <= 0) throw ProcessingError(fmt::format("writer.geotiff: {}: empty DTM", path.string()));
  DatasetPtr ds = make_mem(g, 1, GDT_Float32, geo);
  std::vector<float> v(dtm.z.size());
  for (std::size_t i = 0; i < v.size(); ++i) {
    // Absolute height in double, then Float32: about 0.1 mm resolution at 1,500 m.
    v[i] = std::isfinite(dtm.z[i]) ? float(double(dtm.z[i]) + geo.origin.z()) : float(kDtmNoData);
  }
  GDALRasterBand* b = ds->GetRasterBand(1);
  b->SetNoDataValue(kDtmNoData);
  b->SetDescription("height");
  if (b->RasterIO(GF_Write, 0, 0, g.width, g.height, v.data(), g.width, g.height, GDT_Float32, 0, 0, nullptr) !=
      CE_None) {
    throw IoError(fmt::format("writer.geotiff: {}: {}", path.string(), last_gdal_error()));
  }
  ds->SetMetadataItem("AREA_OR_POINT", "Area");
  write_copy(ds.get(), path, options, true);
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

Dtm read_dtm_geotiff(const fs::path& path, const Eigen::Vector3d& origin) {
  init_gdal();
  DatasetPtr ds(GDALDataset::FromHandle(GDALOpen(path.string().c_str(), GA_ReadOnly)));
  if (!ds) throw IoError(fmt::format("reader.geotiff: {}: {}", path.string(), last_gdal_error()));
  double gt[6];
  if (ds->GetGeoTransform(gt) != CE_None || gt[2] != 0 || gt[4] != 0 || std::abs(gt[1] + gt[5]) > 1e-12) {
    throw InputError(fmt::format("reader.geotiff: {}: not a north-up raster with square cells", path.string()));
  }
  Dtm d;
  d.grid.cell = gt[1];
  d.grid.x_min = gt[0] - origin.x();
  d.grid.y_max = gt[3] - origin.y();
  d.grid.width = ds->GetRasterXSize();
  d.grid.height = ds->GetRasterYSize();
  d.z.resize(d.grid.cells());
  GDALRasterBand* b = ds->GetRasterBand(1);
  if (b->RasterIO(GF_Read, 0, 0, d.grid.width, d.grid.height, d.z.data(), d.grid.width, d.grid.height,
                  GDT_Float32, 0, 0, nullptr) != CE_None) {
    throw IoError(fmt::format("reader.geotiff: {}: {}", path.string(), last_gdal_error()));
  }
  int has_nodata = 0;
  const double nodata = b->GetNoDataValue(&has_nodata);
  for (float& z : d.z) {
    if (!std::isfinite(z) || (has_nodata && double(z) == double(float(nodata)))) {
      z = std::numeric_limits<float>::quiet_NaN();
    } else {
      z = float(double(z) - origin.z());
    }
  }
  return d;
}

std::string raster_table_name(const std::string& prefix, const std::string& layer) {
  std::string s = prefix + "_";
  for (char c : layer) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_';
    s += ok ? c : '_';
  }
  return s;
}

void drop_gpkg_raster_table(Database& db, const std::string& table) {
  // Children before parents: gpkg_tile_matrix(_set) reference gpkg_contents.
  const std::pair<const char*, const char*> rows[] = {
      {"gpkg_2d_gridded_tile_ancillary", "tpudt_name"},
      {"gpkg_2d_gridded_coverage_ancillary", "tile_matrix_set_name"},
      {"gpkg_tile_matrix", "table_name"},
      {"gpkg_tile_matrix_set", "table_name"},
      {"gpkg_extensions", "table_name"},
      {"gpkg_metadata_reference", "table_name"},
      {"gpkg_contents", "table_name"},
  };
  for (const auto& [bookkeeping, column] : rows) {
    if (!table_exists(db, bookkeeping)) continue;
    db.prepare(fmt::format("DELETE FROM {} WHERE lower({}) = lower(?)", bookkeeping, column)).bind_all(table).run();
  }
  db.exec(fmt::format("DROP TABLE IF EXISTS \"{}\"", table));
}

void write_gpkg_raster(const fs::path& gpkg, const fs::path& source_tif, const std::string& table,
                       GpkgRasterKind kind, const std::string& description) {
  init_gdal();
  {
    // Replace: GDAL refuses to append a raster table that exists already.
    Database db(gpkg, false);
    Transaction tx(db);
    drop_gpkg_raster_table(db, table);
    tx.commit();
  }
  fault::point("products.gpkg_raster.table_dropped");
  DatasetPtr src(GDALDataset::FromHandle(GDALOpen(source_tif.string().c_str(), GA_ReadOnly)));
  if (!src) throw IoError(fmt::format("writer.gpkg_raster: {}: {}", source_tif.string(), last_gdal_error()));
  GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("GPKG");
  if (!drv) throw IoError("writer.gpkg_raster: GDAL lacks the GPKG driver");
  Options opt;
  opt.set("APPEND_SUBDATASET", "YES");
  opt.set("RASTER_TABLE", table);
  opt.set("RASTER_IDENTIFIER", table);
  opt.set("RASTER_DESCRIPTION", description);
  if (kind == GpkgRasterKind::gridded_coverage) {
    opt.set("TILE_FORMAT", "TIFF");  // Float32 tiles, lossless (OGC 17-066r1 TIFF encoding)
  } else {
    opt.set("TILE_FORMAT", "PNG");   // keeps the alpha band
  }
  CPLErrorReset();
  DatasetPtr out(drv->CreateCopy(gpkg.string().c_str(), src.get(), FALSE, opt.get(), nullptr, nullptr));
  if (!out) {
    throw IoError(fmt::format("writer.gpkg_raster: {}: table {}: {}", gpkg.string(), table, last_gdal_error()));
  }
}

}  // namespace strata
