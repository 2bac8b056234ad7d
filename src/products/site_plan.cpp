#include "products/site_plan.hpp"

#include "core/error.hpp"
#include "exporters/raster/gdal_util.hpp"
#include "project/gpkg.hpp"

#include <gdal_alg.h>
#include <gdal_priv.h>
#include <ogrsf_frmts.h>

#include <fmt/format.h>

#include <cmath>
#include <cstring>
#include <memory>
#include <mutex>

namespace strata {
namespace {

using gdal_detail::DatasetPtr;
using gdal_detail::init_gdal;

DatasetPtr make_driver_dataset(const char* driver, int w, int h, int bands, GDALDataType type) {
  init_gdal();
  GDALDriver* d = GetGDALDriverManager()->GetDriverByName(driver);
  STRATA_CHECK(d != nullptr, "GDAL has no {} driver", driver);
  DatasetPtr ds(d->Create("", w, h, bands, type, nullptr));
  STRATA_CHECK(ds != nullptr, "cannot create a {} dataset", driver);
  return ds;
}

// In-memory raster of the DTM in CRS coordinates: band 1 absolute heights
// (nodata -9999), for the contour and polygonize algorithms.
DatasetPtr dtm_dataset(const Dtm& dtm, const Eigen::Vector3d& origin, bool mask) {
  const RasterGrid& g = dtm.grid;
  DatasetPtr ds = make_driver_dataset("MEM", g.width, g.height, 1, mask ? GDT_Byte : GDT_Float64);
  double gt[6] = {origin.x() + g.x_min, g.cell, 0, origin.y() + g.y_max, 0, -g.cell};
  ds->SetGeoTransform(gt);
  GDALRasterBand* b = ds->GetRasterBand(1);
  if (mask) {
    std::vector<std::uint8_t> v(g.cells());
    for (std::size_t i = 0; i < v.size(); ++i) v[i] = std::isfinite(dtm.z[i]) ? 1 : 0;
    CPLErr e = b->RasterIO(GF_Write, 0, 0, g.width, g.height, v.data(), g.width, g.height, GDT_Byte, 0, 0, nullptr);
    STRATA_CHECK(e == CE_None, "MEM write failed");
  } else {
    std::vector<double> v(g.cells());
    for (std::size_t i = 0; i < v.size(); ++i) v[i] = std::isfinite(dtm.z[i]) ? double(dtm.z[i]) + origin.z() : -9999.0;
    b->SetNoDataValue(-9999.0);
    CPLErr e = b->RasterIO(GF_Write, 0, 0, g.width, g.height, v.data(), g.width, g.height, GDT_Float64, 0, 0, nullptr);
    STRATA_CHECK(e == CE_None, "MEM write failed");
  }
  return ds;
}

void collect_lines(const OGRGeometry* geom, double elevation, std::vector<ContourLine>& out) {
  if (!geom) return;
  const auto type = wkbFlatten(geom->getGeometryType());
  if (type == wkbLineString) {
    const auto* ls = geom->toLineString();
    ContourLine line;
    line.elevation = elevation;
    for (int i = 0; i < ls->getNumPoints(); ++i) line.points.emplace_back(ls->getX(i), ls->getY(i));
    if (line.points.size() >= 2) out.push_back(std::move(line));
  } else if (type == wkbMultiLineString) {
    for (const auto* part : *geom->toMultiLineString()) collect_lines(part, elevation, out);
  }
}

double ring_length(const std::vector<Eigen::Vector2d>& pts) {
  double s = 0;
  for (std::size_t i = 1; i < pts.size(); ++i) s += (pts[i] - pts[i - 1]).norm();
  return s;
}


}  // namespace

void ContourOptions::validate() const {
  if (!(interval_m > 0)) throw InputError(fmt::format("products.contours: interval_m must be > 0 metres, got {}", interval_m));
  if (!(min_length_m >= 0)) {
    throw InputError(fmt::format("products.contours: min_length_m must be >= 0 metres, got {}", min_length_m));
  }
}

double ContourLine::length_m() const { return ring_length(points); }

std::vector<ContourLine> dtm_contours(const Dtm& dtm, const Eigen::Vector3d& origin, const ContourOptions& o) {
  o.validate();
  std::vector<ContourLine> out;
  if (dtm.grid.cells() == 0) return out;
  DatasetPtr raster = dtm_dataset(dtm, origin, false);
  DatasetPtr vec = make_driver_dataset("Memory", 0, 0, 0, GDT_Unknown);
  OGRLayer* layer = vec->CreateLayer("contours", nullptr, wkbLineString, nullptr);
  STRATA_CHECK(layer != nullptr, "cannot create the contour layer");
  OGRFieldDefn id("ID", OFTInteger), elev("ELEV", OFTReal);
  layer->CreateField(&id);
  layer->CreateField(&elev);
  gdal_detail::Options opts;
  opts.set("LEVEL_INTERVAL", fmt::format("{}", o.interval_m));
  opts.set("LEVEL_BASE", "0");
  opts.set("ID_FIELD", "0");
  opts.set("ELEV_FIELD", "1");
  opts.set("NODATA", "-9999");
  const CPLErr e = GDALContourGenerateEx(GDALRasterBand::ToHandle(raster->GetRasterBand(1)),
                                         OGRLayer::ToHandle(layer), opts.get(), nullptr, nullptr);
  if (e != CE_None) throw ProcessingError(fmt::format("products.contours: {}", CPLGetLastErrorMsg()));
  layer->ResetReading();
  for (auto& f : *layer) {
    const double elevation = f->GetFieldAsDouble(1);
    const std::size_t before = out.size();
    collect_lines(f->GetGeometryRef(), elevation, out);
    if (o.min_length_m > 0) {
      for (std::size_t i = out.size(); i-- > before;) {
        if (out[i].length_m() < o.min_length_m) out.erase(out.begin() + std::ptrdiff_t(i));
      }
    }
  }
  return out;
}

Footprint dtm_footprint(const Dtm& dtm, const Eigen::Vector3d& origin, double min_area_m2) {
  Footprint fp;
  if (dtm.grid.cells() == 0) return fp;
  DatasetPtr mask = dtm_dataset(dtm, origin, true);
  DatasetPtr vec = make_driver_dataset("Memory", 0, 0, 0, GDT_Unknown);
  OGRLayer* layer = vec->CreateLayer("footprint", nullptr, wkbPolygon, nullptr);
  OGRFieldDefn val("valid", OFTInteger);
  layer->CreateField(&val);
  GDALRasterBandH band = GDALRasterBand::ToHandle(mask->GetRasterBand(1));
  // The band is its own mask: only valid cells (value 1) become polygons.
  if (GDALPolygonize(band, band, OGRLayer::ToHandle(layer), 0, nullptr, nullptr, nullptr) != CE_None) {
    throw ProcessingError(fmt::format("products.footprint: {}", CPLGetLastErrorMsg()));
  }
  fp.min = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  fp.max = -fp.min;
  layer->ResetReading();
  for (auto& f : *layer) {
    const OGRGeometry* geom = f->GetGeometryRef();
    if (!geom || wkbFlatten(geom->getGeometryType()) != wkbPolygon) continue;
    // Staircase outlines of cells: simplifying by half a cell keeps the shape within
    // half a cell and removes most vertices.
    std::unique_ptr<OGRGeometry> simple(geom->SimplifyPreserveTopology(0.5 * dtm.grid.cell));
    const OGRGeometry* use = simple ? simple.get() : geom;
    if (wkbFlatten(use->getGeometryType()) != wkbPolygon) continue;
    const auto* poly = use->toPolygon();
    const double area = poly->get_Area();
    if (area < min_area_m2) continue;
    FootprintPolygon out;
    for (const auto* ring : *poly) {
      std::vector<Eigen::Vector2d> pts;
      for (int i = 0; i < ring->getNumPoints(); ++i) {
        pts.emplace_back(ring->getX(i), ring->getY(i));
        fp.min = fp.min.cwiseMin(pts.back());
        fp.max = fp.max.cwiseMax(pts.back());
      }
      fp.perimeter_m += ring_length(pts);
      out.rings.push_back(std::move(pts));
    }
    fp.area_m2 += area;
    fp.polygons.push_back(std::move(out));
  }
  if (fp.polygons.empty()) fp.min = fp.max = Eigen::Vector2d::Zero();
  return fp;
}

std::vector<std::uint8_t> gpkg_multipolygon(int srs_id, const Footprint& footprint) {
  GpkgBlobWriter w(srs_id);
  w.u8(1);
  w.u32(6);  // MultiPolygon
  w.u32(std::uint32_t(footprint.polygons.size()));
  for (const auto& poly : footprint.polygons) {
    w.u8(1);
    w.u32(3);  // Polygon
    w.u32(std::uint32_t(poly.rings.size()));
    for (const auto& ring : poly.rings) w.ring(ring);
  }
  return w.take();
}

void store_site_plan(Database& db, int srs_id, const std::string& layer, double interval_m,
                     const std::vector<ContourLine>& contours, const Footprint& footprint) {
  db.prepare("DELETE FROM contours WHERE layer = ?").bind_all(layer).run();
  db.prepare("DELETE FROM footprints WHERE layer = ?").bind_all(layer).run();
  auto ins = db.prepare(
      "INSERT INTO contours(geom, layer, elevation, interval_m, length_m, min_e, min_n, max_e, max_n) "
      "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)");
  for (const ContourLine& c : contours) {
    std::vector<Eigen::Vector3d> pts;
    Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
    for (const auto& p : c.points) {
      pts.emplace_back(p.x(), p.y(), c.elevation);
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    ins.reset();
    ins.bind_blob(1, gpkg_linestring_z(srs_id, pts));
    ins.bind(2, layer).bind(3, c.elevation).bind(4, interval_m).bind(5, c.length_m());
    ins.bind(6, lo.x()).bind(7, lo.y()).bind(8, hi.x()).bind(9, hi.y());
    ins.run();
  }
  if (!footprint.polygons.empty()) {
    auto st = db.prepare(
        "INSERT INTO footprints(geom, layer, area_m2, perimeter_m, min_e, min_n, max_e, max_n) "
        "VALUES (?, ?, ?, ?, ?, ?, ?, ?)");
    st.bind_blob(1, gpkg_multipolygon(srs_id, footprint));
    st.bind(2, layer).bind(3, footprint.area_m2).bind(4, footprint.perimeter_m);
    st.bind(5, footprint.min.x()).bind(6, footprint.min.y()).bind(7, footprint.max.x()).bind(8, footprint.max.y());
    st.run();
  }
  for (const char* table : {"contours", "footprints"}) {
    db.exec(fmt::format(
        "UPDATE gpkg_contents SET (min_x, min_y, max_x, max_y, last_change) = (SELECT min(min_e), min(min_n), "
        "max(max_e), max(max_n), strftime('%Y-%m-%dT%H:%M:%fZ','now') FROM {0}) WHERE table_name = '{0}'",
        table));
  }
}

void register_site_plan_views(Database& db, int srs_id) {
  db.prepare(
        "INSERT OR IGNORE INTO gpkg_contents(table_name, data_type, identifier, description, srs_id) "
        "VALUES ('marker_residuals_view', 'features', 'marker_residuals_view', "
        "'markers with their residuals in each layer alignment (metres)', ?)")
      .bind_all(srs_id)
      .run();
  db.prepare(
        "INSERT OR IGNORE INTO gpkg_geometry_columns(table_name, column_name, geometry_type_name, srs_id, z, m) "
        "VALUES ('marker_residuals_view', 'geom', 'POINT', ?, 1, 0)")
      .bind_all(srs_id)
      .run();
  db.exec(
      "UPDATE gpkg_contents SET (min_x, min_y, max_x, max_y) = (SELECT min(e), min(n), max(e), max(n) FROM markers) "
      "WHERE table_name = 'marker_residuals_view'");
}

}  // namespace strata
