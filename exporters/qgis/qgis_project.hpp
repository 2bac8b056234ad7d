#pragma once
// QGIS project of a site (exporter.qgis): the project's rasters and vectors by
// relative paths, styled (hillshade + orthophoto + contours + labelled markers),
// one group per layer, groups ordered stratigraphically (latest capture on top);
// the finds labelled by number, those in conflict with the unit solids apart.
// Written as .qgs XML, or .qgz (a zip holding the .qgs).
#include "project/project.hpp"

#include <Eigen/Core>

#include <filesystem>
#include <optional>
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

// A find whose point contradicts its recorded unit (volume/finds.hpp decides; the
// exporter only draws the verdict).
struct QgisFindConflict {
  std::string id;              // find number (finds.find_id)
  std::string geometric_unit;  // the unit whose solid holds the point; empty: none
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
  bool finds = false;                   // rows in `finds` (strata import finds)
  // The finds against the voxel model as of the export: nothing when there is no
  // voxel model (the finds are drawn alike), else the conflicts (maybe none).
  std::optional<std::vector<QgisFindConflict>> find_conflicts;
};

// Gathers layers (capture order), their dtm/ortho products, vectors and extent.
// find_conflicts stays empty: the caller that can place the finds fills it in.
QgisProjectInput collect_qgis_input(Project& project);

// The .qgs XML with data sources relative to `qgs_dir` (the folder of the file).
std::string qgis_project_xml(const QgisProjectInput& input, const std::filesystem::path& qgs_dir);

// Writes `out` (.qgs, or .qgz = zip holding <stem>.qgs). Throws InputError for
// another extension, IoError when it cannot be written.
void write_qgis_project(const QgisProjectInput& input, const std::filesystem::path& out);

}  // namespace strata
