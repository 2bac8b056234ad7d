#pragma once
// GeoPackage bookkeeping done with plain SQL, so that feature rows are written in
// the same transaction as the rest of a command: spatial reference systems,
// feature-table registration, and the GeoPackage binary geometry encoding.
#include "project/database.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace strata {

struct CrsInfo;

// Inserts the CRS into gpkg_spatial_ref_sys (id = its EPSG code, or a private id
// from 100000 up for CRSs without one) and returns the srs_id.
int register_srs(Database& db, const CrsInfo& crs);

// Registers strata's feature tables in gpkg_contents / gpkg_geometry_columns with
// the site CRS. Idempotent: safe after every migration.
void register_feature_tables(Database& db, int srs_id);

// Builds a GeoPackage binary geometry (OGC 12-128 clause 2.1.3): the header
// (magic "GP", version 0, little-endian flag, no envelope, srs_id), then the
// caller appends little-endian ISO WKB with u8/u32/f64.
class GpkgBlobWriter {
 public:
  explicit GpkgBlobWriter(int srs_id);
  void u8(std::uint8_t v) { out_.push_back(v); }
  void u32(std::uint32_t v);
  void f64(double d);
  // A linear ring of a polygon (x, y), closed if the caller did not repeat the first point.
  void ring(const std::vector<Eigen::Vector2d>& points);
  std::vector<std::uint8_t> take() { return std::move(out_); }

 private:
  std::vector<std::uint8_t> out_;
};

// GeoPackage binary geometry (OGC 12-128 clause 2.1.3): header without envelope,
// then little-endian ISO WKB.
std::vector<std::uint8_t> gpkg_point_z(int srs_id, const Eigen::Vector3d& p);
std::vector<std::uint8_t> gpkg_linestring_z(int srs_id, const std::vector<Eigen::Vector3d>& pts);
std::vector<std::uint8_t> gpkg_polygon(int srs_id, const std::vector<Eigen::Vector2d>& ring);

// The x, y of a GeoPackage binary geometry (any envelope, either byte order, ISO or
// 2D WKB, Z and M skipped) of the kinds strata writes: (Multi)Point, (Multi)LineString
// and (Multi)Polygon. One entry per part (a polygon, a line, a point), each a list of
// rings/lines. Throws IoError on a blob that is none of these or is cut short.
std::vector<std::vector<std::vector<Eigen::Vector2d>>> read_gpkg_geometry_xy(const std::vector<std::uint8_t>& blob);

// Recomputes a feature table's extent in gpkg_contents from its e/n-style columns.
void update_contents_extent(Database& db, const std::string& table, const std::string& x_col,
                            const std::string& y_col);

}  // namespace strata
