#pragma once
// The site-plan vectors of a layer as the products stage stored them in project.gpkg
// (tables `contours` and `footprints`, schema 0004; written by store_site_plan in
// src/products/site_plan.cpp), read back for display. Coordinates in the site CRS.
#include "project/database.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace strata {

struct ContourRecord {
  std::string layer;
  double elevation = 0;                 // metres, absolute
  std::vector<Eigen::Vector2d> points;  // E, N, site CRS metres
};

// A polygon's rings: the outer first, then holes; E, N, site CRS metres, closed.
using PolygonRings = std::vector<std::vector<Eigen::Vector2d>>;

struct FootprintRecord {
  std::string layer;
  double area_m2 = 0;
  std::vector<PolygonRings> polygons;
};

// The layer's contour lines, ordered by elevation.
std::vector<ContourRecord> list_contours(Database& db, const std::string& layer);
// The layer's footprints (one row per products run: at most one).
std::vector<FootprintRecord> list_footprints(Database& db, const std::string& layer);

}  // namespace strata
