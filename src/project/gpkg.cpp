#include "project/gpkg.hpp"

#include "crs/crs.hpp"

#include <cstring>
#include <string>

namespace strata {
namespace {

// Feature tables strata maintains: name, geometry column type, has z.
struct FeatureTable {
  const char* name;
  const char* geometry_type;
  int z;
  const char* description;
};
constexpr FeatureTable kFeatureTables[] = {
    {"markers", "POINT", 1, "surveyed ground-control and check markers"},
    {"camera_positions", "POINT", 1, "positions of the aligned photos"},
    {"contours", "LINESTRING", 1, "contour lines of each layer's DTM"},
    {"footprints", "MULTIPOLYGON", 0, "reconstructed footprint of each layer"},
    {"unit_extents", "MULTIPOLYGON", 0, "excavated extent of each unit (strata volume)"},
    {"finds", "POINT", 1, "finds recorded in place, with the unit they were recorded in"},
};

bool table_exists(Database& db, const std::string& name) {
  auto st = db.prepare("SELECT 1 FROM sqlite_master WHERE type='table' AND name=?");
  st.bind(1, name);
  return st.step();
}


}  // namespace

GpkgBlobWriter::GpkgBlobWriter(int srs_id) {
  out_ = {'G', 'P', 0, 0x01};  // version 0; flags: little endian, no envelope
  u32(std::uint32_t(srs_id));
}

void GpkgBlobWriter::u32(std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out_.push_back(std::uint8_t(v >> (8 * i)));
}

void GpkgBlobWriter::f64(double d) {
  std::uint64_t bits;
  std::memcpy(&bits, &d, 8);
  for (int i = 0; i < 8; ++i) out_.push_back(std::uint8_t(bits >> (8 * i)));
}

void GpkgBlobWriter::ring(const std::vector<Eigen::Vector2d>& points) {
  const bool closed = !points.empty() && points.front() == points.back();
  u32(std::uint32_t(points.size() + (closed ? 0 : 1)));
  for (const auto& p : points) {
    f64(p.x());
    f64(p.y());
  }
  if (!closed && !points.empty()) {
    f64(points.front().x());
    f64(points.front().y());
  }
}

int register_srs(Database& db, const CrsInfo& crs) {
  int srs_id = 0;
  if (crs.authority == "EPSG" && crs.code > 0) {
    srs_id = crs.code;
  } else {
    srs_id = int(std::max<std::int64_t>(
        100000, db.query_int("SELECT max(srs_id) + 1 FROM gpkg_spatial_ref_sys").value_or(100000)));
  }
  db.prepare(
        "INSERT OR IGNORE INTO gpkg_spatial_ref_sys(srs_name, srs_id, organization, "
        "organization_coordsys_id, definition, description) VALUES (?, ?, ?, ?, ?, ?)")
      .bind_all(crs.name, srs_id, crs.code ? crs.authority : std::string("NONE"),
                crs.code ? crs.code : srs_id, crs.wkt, std::string("site CRS"))
      .run();
  return srs_id;
}

void register_feature_tables(Database& db, int srs_id) {
  for (const auto& t : kFeatureTables) {
    if (!table_exists(db, t.name)) continue;
    db.prepare(
          "INSERT OR IGNORE INTO gpkg_contents(table_name, data_type, identifier, description, "
          "srs_id) VALUES (?, 'features', ?, ?, ?)")
        .bind_all(t.name, t.name, t.description, srs_id)
        .run();
    db.prepare(
          "INSERT OR IGNORE INTO gpkg_geometry_columns(table_name, column_name, "
          "geometry_type_name, srs_id, z, m) VALUES (?, 'geom', ?, ?, ?, 0)")
        .bind_all(t.name, t.geometry_type, srs_id, t.z)
        .run();
  }
}

std::vector<std::uint8_t> gpkg_point_z(int srs_id, const Eigen::Vector3d& p) {
  GpkgBlobWriter w(srs_id);
  w.u8(1);
  w.u32(1001);  // ISO WKB Point Z
  w.f64(p.x());
  w.f64(p.y());
  w.f64(p.z());
  return w.take();
}

std::vector<std::uint8_t> gpkg_linestring_z(int srs_id, const std::vector<Eigen::Vector3d>& pts) {
  GpkgBlobWriter w(srs_id);
  w.u8(1);
  w.u32(1002);  // ISO WKB LineString Z
  w.u32(std::uint32_t(pts.size()));
  for (const auto& p : pts) {
    w.f64(p.x());
    w.f64(p.y());
    w.f64(p.z());
  }
  return w.take();
}

std::vector<std::uint8_t> gpkg_polygon(int srs_id, const std::vector<Eigen::Vector2d>& ring) {
  GpkgBlobWriter w(srs_id);
  w.u8(1);
  w.u32(3);  // Polygon
  w.u32(1);  // one ring
  w.ring(ring);
  return w.take();
}

void update_contents_extent(Database& db, const std::string& table, const std::string& x,
                            const std::string& y) {
  db.exec("UPDATE gpkg_contents SET (min_x, min_y, max_x, max_y, last_change) = (SELECT min(" + x +
          "), min(" + y + "), max(" + x + "), max(" + y +
          "), strftime('%Y-%m-%dT%H:%M:%fZ','now') FROM " + table + ") WHERE table_name = '" +
          table + "'");
}

}  // namespace strata
