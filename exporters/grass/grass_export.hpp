#pragma once
// GRASS GIS export (exporter.grass): the layers' GeoTIFFs copied into a folder,
// the site-plan vectors as one GeoPackage, and import.sh with the r.in.gdal /
// v.in.ogr calls and a g.region that covers every DTM at its cell size.
#include "project/project.hpp"

#include <filesystem>
#include <string>
#include <vector>

namespace strata {

struct GrassExportSummary {
  std::filesystem::path script;               // <out>/import.sh
  std::vector<std::filesystem::path> files;   // rasters and vectors written
  std::vector<std::string> rasters;           // GRASS map names of the DTMs
  double region_cell_m = 0;                   // finest DTM cell
};

// Writes into `out` (created if missing; existing files of the same names are
// replaced). Throws InputError when the project has no DTM yet.
GrassExportSummary export_grass(Project& project, const std::filesystem::path& out);

// "L1" -> "L1", "layer 2/a" -> "layer_2_a": a legal GRASS map name (letters, digits,
// underscore; starting with a letter).
std::string grass_map_name(const std::string& text);

}  // namespace strata
