#include "exporters/raster/gpkg_raster.hpp"

#include "core/error.hpp"
#include "core/fault.hpp"
#include "exporters/raster/gdal_util.hpp"
#include "project/database.hpp"

#include <gdal_priv.h>

#include <fmt/format.h>

#include <utility>

namespace fs = std::filesystem;

namespace strata {
namespace {

using gdal_detail::DatasetPtr;
using gdal_detail::init_gdal;
using gdal_detail::last_gdal_error;
using gdal_detail::Options;

bool table_exists(Database& db, const std::string& name) {
  auto st = db.prepare("SELECT 1 FROM sqlite_master WHERE type IN ('table', 'view') AND name = ?");
  st.bind(1, name);
  return st.step();
}

// Removes a raster table and its bookkeeping rows; no-op when it does not exist.
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

}  // namespace

std::string raster_table_name(const std::string& prefix, const std::string& layer) {
  std::string s = prefix + "_";
  for (char c : layer) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_';
    s += ok ? c : '_';
  }
  return s;
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
