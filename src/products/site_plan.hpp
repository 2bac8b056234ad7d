#pragma once
// Site-plan vectors of a layer: contour lines and the reconstructed
// footprint from its DTM, and their rows in project.gpkg (tables `contours`,
// `footprints`, view `marker_residuals_view`, schema 0004). GDAL stays in the .cpp.
#include "products/dtm.hpp"
#include "project/database.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace strata {

struct ContourOptions {
  double interval_m = 0.05;  // metres between contour levels; levels are multiples of it
  double min_length_m = 0;   // metres; shorter lines (noise rings) are dropped
  void validate() const;
};

// Coordinates in the site CRS (origin added back): what the GeoPackage stores.
struct ContourLine {
  double elevation = 0;                  // metres, absolute
  std::vector<Eigen::Vector2d> points;   // E, N
  double length_m() const;
};

struct FootprintPolygon {
  std::vector<std::vector<Eigen::Vector2d>> rings;  // first outer, then holes; E, N, closed
};

struct Footprint {
  std::vector<FootprintPolygon> polygons;
  double area_m2 = 0;       // of the polygons (holes subtracted)
  double perimeter_m = 0;   // all rings
  Eigen::Vector2d min = Eigen::Vector2d::Zero(), max = Eigen::Vector2d::Zero();  // E, N
};

// Contours of the DTM's absolute heights (z + origin.z) by GDALContourGenerateEx.
std::vector<ContourLine> dtm_contours(const Dtm& dtm, const Eigen::Vector3d& origin, const ContourOptions& options);

// Outline of the valid DTM cells (GDALPolygonize), simplified by half a cell;
// islands smaller than min_area_m2 are dropped.
Footprint dtm_footprint(const Dtm& dtm, const Eigen::Vector3d& origin, double min_area_m2 = 0.01);

// GeoPackage binary geometry of a footprint: MultiPolygon (2D).
std::vector<std::uint8_t> gpkg_multipolygon(int srs_id, const Footprint& footprint);

// Replaces the layer's rows in `contours` and `footprints` and refreshes their
// extents in gpkg_contents. Runs inside the caller's transaction.
void store_site_plan(Database& db, int srs_id, const std::string& layer, double interval_m,
                     const std::vector<ContourLine>& contours, const Footprint& footprint);

// Registers marker_residuals_view as a point feature layer (idempotent).
void register_site_plan_views(Database& db, int srs_id);

}  // namespace strata
