#pragma once
// Coordinate reference systems through PROJ: parsing what surveyors write
// ("EPSG:32636", a PROJ string, "WGS84 UTM 11N", WKT), checking that a site CRS is
// projected in metres, and transforming marker coordinates into the site CRS.
#include <Eigen/Core>

#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace strata {

struct CrsInfo {
  std::string input;       // as the user gave it
  std::string name;        // PROJ's name, e.g. "WGS 84 / UTM zone 36N"
  std::string authority;   // "EPSG" or "" when the CRS has no authority code
  int code = 0;            // authority code, 0 when none
  std::string wkt;         // WKT1 (GDAL flavour) for gpkg_spatial_ref_sys.definition
  std::string projjson;    // for exports that want it
  bool projected = false;
  bool geographic = false;
  bool metres = false;     // horizontal axis unit is the metre
  std::string label() const;  // "EPSG:32636" or the name
};

// Parses and describes a CRS. Accepts "EPSG:n", "epsg:n", a bare number, PROJ
// strings ("+proj=utm +zone=11 +datum=WGS84"), WKT, and OpenDroneMap's
// "WGS84 UTM 11N". Throws CrsError naming the text when PROJ does not know it.
CrsInfo describe_crs(const std::string& text);

// Where a CRS may be used, in degrees of longitude and latitude (WGS 84), as its
// definition states (EPSG's area of use); west > east when it crosses 180 degrees.
struct AreaOfUse {
  double west = -180, south = -90, east = 180, north = 90;
  std::string name;  // e.g. "Between 30°E and 36°E, northern hemisphere ..."
};
// nullopt when the CRS states none (a PROJ string, a custom WKT).
std::optional<AreaOfUse> area_of_use(const std::string& crs);

// Throws CrsError unless the CRS is projected with metre units (a site CRS).
void require_site_crs(const CrsInfo& crs);

// Transforms points between two CRSs, in traditional GIS axis order
// (x = easting/longitude, y = northing/latitude, z = height).
class CrsTransform {
 public:
  CrsTransform(const std::string& from, const std::string& to);
  ~CrsTransform();
  CrsTransform(CrsTransform&&) noexcept;
  CrsTransform& operator=(CrsTransform&&) noexcept;
  Eigen::Vector3d apply(const Eigen::Vector3d& p) const;
  bool identity() const { return identity_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  bool identity_ = false;
};

// The transformation from `from` (checked with describe_crs first, so an unknown
// CRS is named as such) into the site CRS; a CrsError starts with `context`
// (e.g. "importer.finds.csv: finds.csv").
CrsTransform transform_into_site(const std::string& from, const std::string& site_crs, const std::string& context);

}  // namespace strata
