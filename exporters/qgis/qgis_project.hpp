#pragma once
// QGIS project of a site (exporter.qgis): the project's rasters and vectors by
// relative paths, styled (hillshade + orthophoto + contours + labelled markers),
// one group per layer, groups ordered stratigraphically (latest capture on top).
// Written as .qgs XML, or .qgz (a zip holding the .qgs).
#include "project/project.hpp"

#include <Eigen/Core>

#include <filesystem>
#include <string>
#include <vector>

namespace strata {

struct QgisLayerGroup {
  std::string layer;                    // layer name
  std::string unit;                     // unit code
  std::filesystem::path dtm;            // absolute path or empty
  std::filesystem::path ortho;          // absolute path or empty
  bool contours = false;                // rows in `contours` for this layer
  bool footprint = false;               // a row in `footprints`
};

struct QgisProjectInput {
  std::string title;
  std::filesystem::path gpkg;           // absolute path of project.gpkg
  std::string crs_authid;               // "EPSG:32636"
  std::string crs_wkt;
  Eigen::Vector2d min = Eigen::Vector2d::Zero(), max = Eigen::Vector2d::Zero();  // map extent, CRS
  std::vector<QgisLayerGroup> layers;   // in capture order: first = earliest
  bool markers = true, camera_positions = true, marker_residuals = true;
  bool unit_extents = false;            // rows in `unit_extents` (strata volume)
};

// Gathers layers (capture order), their dtm/ortho products, vectors and extent.
QgisProjectInput collect_qgis_input(Project& project);

// The .qgs XML with data sources relative to `qgs_dir` (the folder of the file).
std::string qgis_project_xml(const QgisProjectInput& input, const std::filesystem::path& qgs_dir);

// Writes `out` (.qgs, or .qgz = zip holding <stem>.qgs). Throws InputError for
// another extension, IoError when it cannot be written.
void write_qgis_project(const QgisProjectInput& input, const std::filesystem::path& out);

}  // namespace strata
