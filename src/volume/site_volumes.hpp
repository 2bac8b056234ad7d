#pragma once
// The volume stage on a project: layer surfaces from the database (or GeoTIFF
// DTMs the user brings), unit solids, the voxel model and thickness rasters in
// products/volume/, and the unit_volumes table. Orchestration only: the maths is
// in volume.hpp / voxels.hpp.
#include "project/project.hpp"
#include "project/records.hpp"
#include "stratigraphy/harris_matrix.hpp"
#include "volume/voxels.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace strata {

// The project file that holds the trench outline once `strata volume --outline` gave one.
inline constexpr const char* kTrenchOutlineFile = "trench_outline.geojson";

struct SiteVolumeOptions {
  VolumeOptions volume;
  VoxelOptions voxels;
  // Cell of the common measurement grid, metres. 0: the pixel size of the first
  // GeoTIFF surface if any (and its pixel centres), else 0.005 m.
  double cell_m = 0;
  // Layer name -> GeoTIFF of absolute heights in the site CRS; replaces the
  // layer's surface product (for DTMs from elsewhere, or the synthetic truth).
  std::map<std::string, std::filesystem::path> surface_files;
  // Unit code -> vector file (GeoJSON, GeoPackage, shapefile) whose first polygon,
  // in site CRS coordinates, limits the unit's solid.
  std::map<std::string, std::filesystem::path> footprint_files;
  // Vector file (first polygon, site CRS) of the trench outline / limit of
  // excavation: the domain where layer surface gaps are filled. Empty: derived
  // from the data (GapFillOptions).
  // Kept in the project folder as kTrenchOutlineFile once given; used when empty.
  std::filesystem::path outline_file;
  double default_noise_m = 0.003;  // surface noise when no dense quality figure exists, metres

  void validate() const;  // InputError naming the field
};

struct SiteModel {
  SiteInfo site;
  std::vector<LayerSurface> layers;   // capture order, on one grid
  std::vector<UnitSolid> solids;      // excavated units
  GapFillSummary fill;                // what the gap filling did (layers are filled in place)
  std::vector<UnitRecord> units;
  std::vector<RelationRecord> relations;
};

// Layers in the order they were captured, the top of the stratigraphy first: by
// captured_at when every layer has one, else by id.
std::vector<LayerRecord> capture_order(std::vector<LayerRecord> layers);

// Loads every layer's surface (surface_files, else its "surface" product .vdb,
// else its "dtm" product GeoTIFF) onto one grid, fills their gaps inside the
// trench outline (fill_surface_gaps) and builds the unit solids.
// Layers without a surface are left out with a warning. Throws InputError when
// fewer than two layers have one.
SiteModel load_site_model(Project& project, const SiteVolumeOptions& options);

// Writes products/volume/units.vdb and thickness_<unit>.tif, records them as
// products, and replaces the unit_volumes rows, in one transaction.
VoxelSummary store_site_volumes(Project& project, const SiteModel& model, const SiteVolumeOptions& options);

// Float32 GeoTIFF of a solid's thickness (metres, nodata where not dug) in the
// site CRS: products/volume/thickness_<unit>.tif and `strata export thickness`.
void write_thickness_geotiff(const std::filesystem::path& path, const UnitSolid& solid, const SiteInfo& site);

// The Harris matrix of the project's units and relations.
HarrisMatrix site_matrix(const SiteModel& model);

// The figures of one unit's solid as a user reads them (`strata volume --json`,
// unit_volumes.details_json): volume, interval and its parts, extent, thickness.
nlohmann::ordered_json unit_measures_json(const UnitSolid& solid);


}  // namespace strata
