#pragma once
// Polygons handed to strata (reader.outline): a trench outline, a unit's footprint,
// the region of a colour check. GDAL reads any vector format it knows; the first
// polygon (or the first part of a multipolygon) of the first layer that has one is
// taken. The checks at the door for geometries (docs/reliability.md):
//  - a polygon that declares a CRS other than the site's is transformed into it (a
//    GeoJSON whose coordinates cannot be degrees is read as not declaring one);
//  - one that declares none is taken in the site CRS, and refused when it does not
//    overlap the site (`site_extent`, when the caller knows it);
//  - every vertex a finite place of the site (project/site_bounds.hpp);
//  - at least three distinct vertices, a non-zero area, no edge crossing another:
//    refused, not repaired (a crossing outline has no one inside; which part was
//    meant is the user's to say), naming the edges and where they cross.
#include "project/project.hpp"

#include <Eigen/Core>

#include <filesystem>
#include <optional>
#include <string_view>
#include <vector>

namespace strata {

// A rectangle of the site frame (site CRS minus the origin), metres.
struct SiteExtent {
  Eigen::Vector2d min = Eigen::Vector2d::Zero(), max = Eigen::Vector2d::Zero();
};

inline constexpr std::size_t kMaxOutlineVertices = 100'000;

// The polygon's outer ring in the site frame (x = E - origin E, y = N - origin N), as
// the file orders it. `what` names it in refusals ("--footprint of unit 102").
// Throws InputError / IoError / CrsError naming the file.
std::vector<Eigen::Vector2d> read_outline(const std::filesystem::path& path, const SiteInfo& site,
                                          std::string_view what,
                                          const std::optional<SiteExtent>& site_extent = std::nullopt);

// The same checks on a ring already in the site frame (the field station's drawn
// outlines); `what` names it.
void check_outline(const std::vector<Eigen::Vector2d>& ring, const SiteInfo& site, std::string_view what,
                   const std::optional<SiteExtent>& site_extent = std::nullopt);

// A GeoJSON FeatureCollection of one polygon in the site CRS, naming the CRS (so that
// GDAL and QGIS read it in the site CRS, not as longitude and latitude).
std::string outline_geojson(const std::vector<Eigen::Vector2d>& ring, const SiteInfo& site, std::string_view name);

}  // namespace strata
