#include "project/gpkg.hpp"

#include "core/error.hpp"
#include "crs/crs.hpp"

#include <fmt/format.h>

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

namespace {

// Reads ISO / 2D WKB (OGC 06-103r4), one geometry at a time.
class WkbReader {
 public:
  WkbReader(const std::vector<std::uint8_t>& b, std::size_t at) : b_(b), at_(at) {}

  // Appends the parts of the geometry at the cursor.
  void geometry(std::vector<std::vector<std::vector<Eigen::Vector2d>>>& parts) {
    little_ = byte() == 1;
    const std::uint32_t code = u32();
    const std::uint32_t base = code % 1000;  // 1000s: Z, 2000s: M, 3000s: ZM
    dims_ = code >= 3000 ? 4 : code >= 1000 ? 3 : 2;
    switch (base) {
      case 1: parts.push_back({points(1)}); break;
      case 2: parts.push_back({points(u32())}); break;
      case 3: {
        std::vector<std::vector<Eigen::Vector2d>> rings(u32());
        for (auto& r : rings) r = points(u32());
        parts.push_back(std::move(rings));
        break;
      }
      case 4:
      case 5:
      case 6: {
        const std::uint32_t n = u32();
        for (std::uint32_t i = 0; i < n; ++i) geometry(parts);
        break;
      }
      default: throw IoError(fmt::format("gpkg: geometry type {} is not read (point, line or polygon)", code));
    }
  }

 private:
  void need(std::size_t n) const {
    if (at_ + n > b_.size()) throw IoError("gpkg: a geometry blob is cut short");
  }
  std::uint8_t byte() {
    need(1);
    return b_[at_++];
  }
  std::uint32_t u32() {
    need(4);
    std::uint32_t v = 0;
    for (int i = 0; i < 4; ++i) v |= std::uint32_t(b_[at_ + (little_ ? i : 3 - i)]) << (8 * i);
    at_ += 4;
    return v;
  }
  double f64() {
    need(8);
    std::uint64_t bits = 0;
    for (int i = 0; i < 8; ++i) bits |= std::uint64_t(b_[at_ + (little_ ? i : 7 - i)]) << (8 * i);
    at_ += 8;
    double d;
    std::memcpy(&d, &bits, 8);
    return d;
  }
  std::vector<Eigen::Vector2d> points(std::uint32_t n) {
    need(std::size_t(n) * 8 * std::size_t(dims_));  // bounds a corrupt count before reserving
    std::vector<Eigen::Vector2d> pts;
    pts.reserve(n);
    for (std::uint32_t i = 0; i < n; ++i) {
      const double x = f64(), y = f64();
      for (int d = 2; d < dims_; ++d) f64();
      pts.emplace_back(x, y);
    }
    return pts;
  }

  const std::vector<std::uint8_t>& b_;
  std::size_t at_;
  bool little_ = true;
  int dims_ = 2;
};

}  // namespace

std::vector<std::vector<std::vector<Eigen::Vector2d>>> read_gpkg_geometry_xy(const std::vector<std::uint8_t>& blob) {
  // Header (OGC 12-128 clause 2.1.3): "GP", version, flags, srs_id, then an envelope
  // of 0, 4, 6, 6 or 8 doubles by the flags' bits 1-3.
  if (blob.size() < 8 || blob[0] != 'G' || blob[1] != 'P') throw IoError("gpkg: not a GeoPackage geometry blob");
  static constexpr std::size_t kEnvelopeDoubles[] = {0, 4, 6, 6, 8};
  const unsigned envelope = (blob[3] >> 1) & 0x7;
  if (envelope > 4) throw IoError(fmt::format("gpkg: geometry envelope code {} is not one of 0..4", envelope));
  std::vector<std::vector<std::vector<Eigen::Vector2d>>> parts;
  WkbReader(blob, 8 + 8 * kEnvelopeDoubles[envelope]).geometry(parts);
  return parts;
}

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
