#pragma once
// Crash injection: named kill points on the write paths.
//
// With the environment variable STRATA_CRASH_AT=<name>[:<n>] the process kills
// itself with SIGKILL the n-th time (default: the first) it passes the point of that
// name, exactly as a crash or a pulled plug would: no destructor, no rollback code,
// no buffered output flushed. Without the variable a point costs one load and a
// compare (the variable is read once).
//
// kCrashPoints is the registry of every point: bench/crash_matrix.py reads it from
// this header, kills strata at each one and checks that nothing was lost
// (docs/reliability.md, "Crash injection"). A point not listed here is refused
// (a typo would otherwise be a point that can never fire).
#include <string_view>

namespace strata::fault {

struct CrashPoint {
  std::string_view name;   // <command family>.<stage>.<event>
  std::string_view where;  // what has happened when the process dies there
};

// One line each, in the order a command passes them: the bench script parses the
// name-and-where pairs of this list.
inline constexpr CrashPoint kCrashPoints[] = {
    // ---- strata init, unit add, layer add, relation add
    {"init.database_created", "project.gpkg exists, the schema not yet migrated"},
    {"init.before_commit", "schema and site rows written, not committed"},
    {"db.migration_applied", "one schema migration run inside its transaction, not committed"},
    {"db.before_commit", "any command's transaction: every statement run, COMMIT not issued"},
    {"db.after_commit", "any command's transaction committed, the command not finished"},
    {"stratigraphy.unit_before_commit", "a unit row inserted, not committed"},
    {"stratigraphy.layer_before_commit", "a layer row inserted, not committed"},
    {"stratigraphy.relation_before_commit", "a relation row inserted, not committed"},
    // ---- strata import photos
    {"import.photos.checked", "every photo read and hashed, nothing written"},
    {"import.photos.media_part_written", "a photo copied to its .part name in media/, not renamed"},
    {"import.photos.media_stored", "a photo renamed into media/, its row not inserted"},
    {"import.photos.row_inserted", "a photo's images row inserted, not committed"},
    {"import.photos.before_commit", "every photo stored and inserted, not committed"},
    {"import.photos.after_commit", "committed; the media batch not yet released"},
    // ---- strata import markers
    {"import.markers.parsed", "the file read and transformed, nothing written"},
    {"import.markers.marker_written", "a marker row written, not committed"},
    {"import.markers.observation_written", "an observation row written, not committed"},
    {"import.markers.before_commit", "every row written, not committed"},
    // ---- strata import scan
    {"import.scans.checked", "every scan read, checked and hashed, nothing written"},
    {"import.scans.media_stored", "a scan renamed into media/, its row not inserted"},
    {"import.scans.row_inserted", "a scan's row inserted, not committed"},
    {"import.scans.before_commit", "every scan stored and inserted, not committed"},
    {"import.scans.after_commit", "committed; the media batch not yet released"},
    // ---- strata import depth
    {"import.depth.checked", "every frame read, checked and hashed, nothing written"},
    {"import.depth.sequence_inserted", "the sequence row inserted, no frame stored, not committed"},
    {"import.depth.frame_inserted", "a frame stored in media/ and its row inserted, not committed"},
    {"import.depth.before_commit", "every frame stored and inserted, not committed"},
    {"import.depth.after_commit", "committed; the media batch not yet released"},
    // ---- strata import finds, strata find add
    {"import.finds.parsed", "the finds read, their units checked, nothing written"},
    {"import.finds.find_written", "a find row written, not committed"},
    {"import.finds.before_commit", "every find written and the finds extent updated, not committed"},
    // ---- strata import units, strata import relations
    {"import.units.parsed", "the register read and checked, nothing written"},
    {"import.units.unit_written", "a unit row inserted or updated, not committed"},
    {"import.units.before_commit", "every unit written, not committed"},
    {"import.relations.parsed", "the relations read, nothing written"},
    {"import.relations.relation_written", "a relation row inserted, not committed"},
    {"import.relations.before_commit", "every relation written, not committed"},
    // ---- strata import calibration, strata camera set
    {"import.calibration.before_commit", "the camera's calibration row written, not committed"},
    {"camera.set.before_commit", "the camera's calibration row written, not committed"},
    // ---- strata process: alignment
    {"process.features.file_temp_written", "a feature or match cache file written to its temporary name"},
    {"process.features.image_done", "one photo's features in the cache"},
    {"process.features.done", "every photo's features in the cache"},
    {"process.matching.pair_done", "one pair's verified matches in the cache"},
    {"process.matching.done", "every pair matched, nothing in the database"},
    {"process.targets.done", "coded targets detected, nothing in the database"},
    {"process.sfm.done", "the incremental reconstruction in memory"},
    {"process.georeference.done", "georeferenced and adjusted in memory"},
    {"process.align.observations_replaced", "detected observations replaced, not committed"},
    {"process.align.reconstruction_inserted", "the sparse reconstruction row inserted, not committed"},
    {"process.align.poses_written", "cameras and poses written, not committed"},
    {"process.align.points_written", "sparse points written, not committed"},
    {"process.align.before_commit", "the whole alignment written, not committed"},
    {"process.align.after_commit", "the alignment committed, the dense stage not begun"},
    // ---- strata process: dense surface
    {"process.dense.views_selected", "source views chosen, nothing written"},
    {"process.dense.cache_temp_written", "a dense cache file (image, depth map) written to its temporary name"},
    {"process.dense.image_undistorted", "one undistorted photo in the cache"},
    {"process.dense.depth_map_written", "one raw depth map in the cache"},
    {"process.dense.depth_maps_done", "every raw depth map in the cache"},
    {"process.dense.filtered_map_written", "one filtered depth map in the cache"},
    {"process.dense.fusion_done", "the TSDF fused in memory"},
    {"process.dense.mesh_done", "mesh and points extracted in memory"},
    {"process.dense.product_temp_written", "a surface, mesh or point file written to its temporary name"},
    {"process.dense.surface_written", "surface.vdb in the staging folder"},
    {"process.dense.mesh_written", "mesh.ply in the staging folder"},
    {"process.dense.points_written", "points.ply in the staging folder"},
    {"process.dense.records_retracted", "the layer's dense and product records removed (committed), files not swapped"},
    {"process.dense.old_moved_aside", "the previous dense folder renamed to .old, the new one not in place"},
    {"process.dense.swapped", "the new dense folder in place, not recorded"},
    {"process.dense.before_commit", "the dense rows written, not committed"},
    {"process.dense.after_commit", "committed; the previous folder not yet deleted"},
    // ---- strata process: products
    {"products.geotiff.temp_written", "a DTM or orthophoto GeoTIFF (products or export) at its temporary name"},
    {"process.products.dtm_written", "dtm.next.tif staged beside dtm.tif, nothing recorded or replaced"},
    {"process.products.sigma_written", "dtm_sigma.next.tif staged, nothing recorded or replaced"},
    {"process.products.ortho_written", "ortho.next.tif staged, nothing recorded or replaced"},
    {"process.products.vectors_done", "contours and footprint in memory"},
    {"process.products.records_retracted",
     "every staged file complete; the layer's product records removed (committed), the staged files not renamed"},
    {"products.gpkg_raster.table_dropped", "a GeoPackage raster table dropped (committed), GDAL not yet writing it"},
    {"process.products.gpkg_dtm_written", "the DTM raster table written into project.gpkg, the orthophoto's not"},
    {"process.products.gpkg_ortho_written", "both raster tables written, no product recorded"},
    {"process.products.product_recorded", "one product row written, not committed"},
    {"process.products.before_commit", "every product row written, not committed"},
    {"process.products.after_commit", "the layer's products committed"},
    // ---- strata volume
    {"volume.model_loaded", "surfaces read and unit solids built in memory, nothing written"},
    {"volume.stored", "volumes, voxels and thickness rasters stored and committed"},
    // ---- strata register scan
    {"register.scans.fitted", "every scan fitted (ICP or targets) in memory, nothing written"},
    {"register.scans.scan_written", "a scan's pose, bounds and fit written, not committed"},
    {"register.scans.before_commit", "every scan's registration written, not committed"},
    // ---- strata register depth
    {"register.depth.registered", "every sequence registered in memory, nothing written"},
    {"register.depth.frame_written", "a frame's pose, bounds and fit written, not committed"},
    {"register.depth.before_commit", "every frame's registration written, not committed"},
    // ---- strata export
    {"export.cameras.temp_written", "the cameras file written to its temporary name"},
    {"export.copy.temp_written", "a mesh or point cloud copied to its temporary name"},
    {"export.qgis.temp_written", "the QGIS project (.qgs) written to its temporary name"},
    {"export.qgz.temp_written", "the zipped QGIS project (.qgz) written to its temporary name"},
    {"export.grass.raster_copied", "one GeoTIFF copied into the GRASS folder"},
    {"export.grass.vectors_written", "site_plan.gpkg written into the GRASS folder"},
    {"export.grass.script_temp_written", "import.sh written to its temporary name"},
    {"export.report.temp_written", "the HTML report written to its temporary name"},
    {"export.gltf.staged", "the .glb (export model) complete at its staged name (.next.glb), not renamed"},
    {"export.obj.staged", "the .obj, .mtl and texture atlases complete at their staged names, none renamed"},
    {"export.obj.file_renamed", "one of the OBJ's files renamed into place (atlases, .mtl, then .obj), the others not"},
    {"export.viewer.staged", "the viewer page complete at its staged name (.next.html), not renamed"},
};

// Kills the process with SIGKILL if STRATA_CRASH_AT arms this point and this is the
// armed hit. Thread-safe; `name` must be in kCrashPoints (else InternalError).
void point(std::string_view name);

// The point STRATA_CRASH_AT arms ("" when none), for tests of this facility.
std::string_view armed();

}  // namespace strata::fault
