#pragma once
// The dense stage: multi-view stereo depth maps on the CPU, TSDF fusion into an
// OpenVDB level set, mesh and point-cloud products.
//
// Public surface in the Ceres style: DenseOptions (validated once), DenseSummary,
// one entry function run_dense(), plus readers of the level set it writes.
// No OpenVDB/CGAL/OpenCV type appears here; those stay inside src/dense/*.cpp.
//
// Frames: every coordinate is the site frame (site CRS minus the site origin,
// metres, double) unless a name says "crs". The site origin is written into
// the .vdb metadata ("site_origin_e", "site_origin_n", "site_origin_z", "crs")
// and added back in exported PLY/OBJ vertices.
#include "core/cache_key.hpp"
#include "dense/dense_mesh.hpp"
#include "geometry/raster.hpp"
#include "geometry/reconstruction.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace strata {

namespace dense {
class TsdfVolume;
}

// Choice of source views for each reference image from the sparse covisibility
// (shared tracks) and the triangulation angle of the shared points.
struct ViewSelectionOptions {
  int max_neighbours = 8;       // source views per reference image, chosen greedily for coverage:
                                // floor next to a trench side is seen only from above and from
                                // the far side, so 4 views left 20-35 % of a trench unmatched
  int min_shared_points = 8;    // sparse points both views must see
  double min_angle_deg = 5.0;   // preferred triangulation angle range, degrees:
  double max_angle_deg = 40.0;  //   too small = poor depth, too large = poor matching
  // Reference views (those that get a depth map): 0 = every image with source views;
  // k > 0 = the fewest, chosen greedily, such that every sparse point lies inside the
  // views (in front, inside the photo and its depth range) of k reference images, or
  // of all that hold it when fewer do. Depth maps are the dense stage's largest cost,
  // and 40 photos of one trench hold each spot in 10-20 views: on the full example 5
  // keeps 24 of 40 (docs/dense.md, "Reference views").
  int reference_cover = 5;
};

// PatchMatch stereo with slanted support windows (Bleyer et al. 2011), red/black
// propagation (Galliani et al. 2015) and best-K multi-view NCC (Schönberger et al. 2016).
struct PatchMatchOptions {
  double scale = 0;               // depth-map resolution relative to the photo: 1, 0.5 or 0.25;
                                  // 0 = the coarsest of them whose GSD is <= target_gsd_m
  double target_gsd_m = 0.008;    // metres per depth-map pixel at the median sparse depth, for
                                  // scale 0 (2400 px at 1.5-2 m -> 0.25; 1000 px -> 0.5)
  int window_radius = 3;          // NCC window half-size, pixels at depth-map scale
  int window_step = 2;            // use every n-th pixel of the window (speed)
  double bilateral_sigma_colour = 0.1;  // grey levels in [0, 1]: NCC samples weighted by their
                                  // likeness to the centre pixel (sharper depth edges); 0 = off
  int iterations = 4;             // red/black propagation sweeps
  bool coarse_to_fine = true;     // solve at half resolution first and start from its planes
  int fine_iterations = 2;        // sweeps at full resolution after the coarse level, <= iterations
  int best_k = 2;                 // photometric cost = mean of the best k source costs
  double max_cost = 0.6;          // 1 - NCC above which a pixel has no depth, in [0, 2]
  double depth_margin = 0.25;     // widening of the sparse depth range, fraction of it
  double max_normal_angle_deg = 75.0;  // plane normals kept within this angle of the view ray
  std::uint64_t seed = 1;         // random initialisation; results are deterministic

  // The horizontal scale over which a depth averages the ground, metres: one sigma
  // of the Gaussian equivalent to the NCC window of (2 r + 1) pixels of `gsd_m`
  // (a box of width w has sigma w / sqrt 12). A slanted plane fitted over the window
  // follows planes exactly, but on curved ground (edges of walls and pits) the
  // depth is the window's mean: the surface is smoothed at this scale.
  double smoothing_m(double gsd_m) const;
};

// Forward-backward geometric consistency between depth maps (Schönberger et al. 2016, §4.4).
struct ConsistencyOptions {
  int min_consistent_views = 1;   // a depth survives when this many neighbours agree; 2 lost
                                  // 4-9 % of the trench (corners, next to the sides, seen by
                                  // few views) for no gain in the median error
  double max_reprojection_px = 1.0;   // pixels at depth-map scale
  double max_relative_depth = 0.01;   // |d_back - d| / d
  // Free-space test (visibility-based fusion, Merrell et al. 2007): a neighbour whose
  // own depth at the point's pixel lies more than `free_space_margin` (relative)
  // beyond the point sees through it, so the point is not there. A depth is dropped
  // when at least `max_free_space_violations` neighbours see through it and they
  // outnumber those that agree: floaters of wrong matches that one other view
  // happened to confirm (on grass at the edge of the coverage they stood 10-35 cm
  // over the markers). 0 = no free-space test.
  int max_free_space_violations = 2;
  double free_space_margin = 0.03;
};

// Truncated signed distance fusion (Curless & Levoy 1996) in a sparse OpenVDB grid.
struct FusionOptions {
  double voxel_size_m = 0;        // metres; 0 = voxel_gsd_factor x depth-map GSD, clamped below
  double voxel_gsd_factor = 1.25; // voxel size in GSDs when chosen automatically
  double min_voxel_size_m = 0.002;  // metres, clamp of the automatic choice
  double max_voxel_size_m = 0.05;   // metres
  double truncation_voxels = 4;   // half-width of the narrow band, voxels
  double min_weight = 0.2;        // accumulated weight below which a voxel counts as unseen; every
                                  // depth already passed the multi-view consistency test, so one
                                  // grazing observation (weight ~0.3) is enough
  // Pieces of the fused band (6-connected active voxels) with fewer than this share
  // of all active voxels are removed: floaters of wrong depths that several photos
  // confirmed alike (streaky grass seen obliquely stood 10-35 cm over a marker). On
  // the full example every piece but the surface itself held under 0.025 %.
  // 0 = keep every piece.
  double min_component_fraction = 0.001;
  // The noise that the unit weight stands for (docs/range.md, "Fusion"): a photo
  // depth of confidence 1 seen head-on has weight 1 and one sigma of this many
  // depth-map GSDs along its ray (PatchMatch with a slanted window matches to about
  // a pixel). A range scan point of sigma s then weighs (unit sigma / s)^2, so photos
  // and scans are averaged by their inverse variances. A layer without photos takes
  // the voxel size as its unit sigma (only min_weight depends on it there).
  double photo_depth_sigma_gsd = 1.0;
};

// A registered range scan of the layer (terrestrial laser scanner, phone LiDAR),
// handed to the dense stage as a source of points in the site frame.
struct RangeScanInput {
  std::string name;                       // for messages: the scan's file name
  double sigma_m = 0;                     // range noise, one sigma, metres; > 0
  // The sensor's position (site frame, metres): each point is fused along its ray
  // from here. Without it (a scan registered to the survey by its own software, no
  // station known), along the point's normal when the file has normals (turned to
  // face up), else along the vertical, as if seen from straight above.
  std::optional<Eigen::Vector3d> station;
  // The noise of a point (site frame, metres) when it varies from point to point, as
  // a depth camera's grows with the square of the depth (k z^2); it then replaces
  // sigma_m for that point, and sigma_m is only the scale its weights are relative to.
  // Empty: sigma_m for every point.
  std::function<double(const Eigen::Vector3d& point)> point_sigma;
  // Reads the scan: calls `sink` with consecutive chunks of points (site frame,
  // metres), their unit normals (site frame; empty when the file has none) and their
  // colours (8-bit sRGB, as the file or the colour frame holds them; empty when it
  // has none). A scan's chunks all have colours or none do.
  using ChunkSink = std::function<void(const std::vector<Eigen::Vector3d>& points,
                                       const std::vector<Eigen::Vector3f>& normals,
                                       const std::vector<Rgb8>& colours)>;
  std::function<void(const ChunkSink& sink)> read;
};

struct MeshOptions {
  std::size_t target_faces = 0;   // CGAL edge-collapse simplification target; 0 = keep all
  double adaptivity = 0;          // openvdb::tools::volumeToMesh adaptivity, in [0, 1]
  bool write_obj = false;         // also write mesh.obj beside mesh.ply
  // A point of the exported cloud needs, at its voxel, this much fused weight (in units
  // of one confidence-1 photo depth seen head-on, FusionOptions) or this effective
  // number of observations (W^2 / sum w^2): with less, one grazing or doubtful depth
  // put the surface there. On the full example's L4 such points were 2.7 % of the
  // trench's and held half of its points over 10 mm from the truth (docs/dense.md,
  // "The point cloud"). The mesh keeps every face (it stays closed). A weight of 0
  // keeps every point.
  double min_point_weight = 1.5;
  double min_point_observations = 2;
};

struct QualityOptions {
  // Area whose completeness is measured: a polygon in site-frame XY (metres).
  // Empty: the convex hull of the sparse points.
  std::vector<Eigen::Vector2d> area;
  double cell_size_m = 0.01;      // grid cell for completeness, metres
};

struct DenseOptions {
  ViewSelectionOptions views;
  PatchMatchOptions patch_match;
  ConsistencyOptions consistency;
  FusionOptions fusion;
  MeshOptions mesh;
  ExportFrame exports;            // precision of PLY/OBJ vertices; site origin filled by run_dense
  QualityOptions quality;
  Unkeyed<int> threads = 2;       // TBB worker threads
  Unkeyed<bool> reuse_cache = true;  // reuse depth maps in the cache whose key matches

  // Throws InputError naming the first invalid field.
  void validate() const;
};

struct StepFigures {
  double seconds = 0;
  std::int64_t peak_memory_bytes = 0;  // process peak RSS at the end of the step
};

struct DenseProduct {
  std::string kind;               // "surface", "mesh", "mesh_obj", "points"
  std::filesystem::path path;
  std::string sha256;
};

struct DenseSummary {
  int images_total = 0;
  int images_with_depth = 0;      // reference images that produced a depth map
  int depth_maps_from_cache = 0;
  double depth_scale = 0;         // as used
  double gsd_m = 0;               // median depth-map ground sampling distance, metres
  double smoothing_m = 0;         // PatchMatchOptions::smoothing_m at gsd_m, metres
  double voxel_size_m = 0;        // as used
  double truncation_m = 0;
  double valid_depth_fraction = 0;    // after PatchMatch, mean over images
  double consistent_depth_fraction = 0;  // after geometric filtering, mean over images
  std::size_t active_voxels = 0;
  std::size_t floating_voxels_removed = 0;  // in pieces of the band smaller than fusion.min_component_fraction
  std::size_t mesh_vertices = 0;
  std::size_t mesh_faces = 0;
  std::size_t points = 0;
  std::size_t points_below_weight = 0;  // mesh vertices left out of the point cloud (MeshOptions::min_point_*)

  // Quality (design.md "Quality figures")
  double completeness = 0;        // fraction of area cells with surface, [0, 1]
  double area_m2 = 0;             // area measured for completeness
  double median_distance_sparse_m = 0;  // |surface - sparse point|, metres
  double p95_distance_sparse_m = 0;
  std::size_t sparse_points_compared = 0;

  // Range scans fused beside the depth maps (docs/range.md, "Fusion").
  int scans_fused = 0;
  std::uint64_t scan_points = 0;
  double unit_sigma_m = 0;        // noise of one unit of fusion weight, metres (FusionOptions)
  double scan_weight_share = 0;   // share of all fused weight that came from scans, [0, 1]

  StepFigures view_selection, undistortion, depth_maps, filtering, fusion, meshing, writing;
  StepFigures total;
  std::vector<DenseProduct> products;
};

// Runs the whole dense stage for one aligned layer. image_paths[i] is the photo of
// reconstruction.images[i]. site_origin is the site origin (E, N, Z in the site CRS,
// metres). Depth maps and undistorted images go to cache_dir (deletable);
// out_dir receives surface.vdb, mesh.ply, points.ply (and mesh.obj on request),
// each written to a temporary file and renamed.
DenseSummary run_dense(const DenseOptions& options, const Reconstruction& reconstruction,
                       const std::vector<std::filesystem::path>& image_paths,
                       const Eigen::Vector3d& site_origin,
                       const std::filesystem::path& cache_dir,
                       const std::filesystem::path& out_dir);
// The same with the layer's registered range scans fused into the same volume. A
// layer may have photos only, scans only (a reconstruction without images) or both.
DenseSummary run_dense(const DenseOptions& options, const Reconstruction& reconstruction,
                       const std::vector<std::filesystem::path>& image_paths,
                       const std::vector<RangeScanInput>& scans,
                       const Eigen::Vector3d& site_origin,
                       const std::filesystem::path& cache_dir,
                       const std::filesystem::path& out_dir);

// ---- reading the level set back ------------------------------------------------

struct LevelSetInfo {
  double voxel_size_m = 0;
  Eigen::Vector3d site_origin = Eigen::Vector3d::Zero();  // E, N, Z of the site CRS
  std::string crs;
  Eigen::Vector3d min = Eigen::Vector3d::Zero();  // active bounding box, site frame, metres
  Eigen::Vector3d max = Eigen::Vector3d::Zero();
};

LevelSetInfo read_level_set_info(const std::filesystem::path& vdb);
// The uppermost zero crossing of the "surface" grid above each cell centre of
// `grid` (the visible top of the layer, what a DTM needs); NaN where there is
// none. With the height uncertainty per cell (metres, one sigma) when the level
// set holds the depth maps' agreement (fusion.cpp). Throws IoError when unreadable.
HeightRaster<double> sample_top_surface(const std::filesystem::path& vdb, const RasterGrid& grid);
// A layer's fused surface (surface.vdb) opened for sampling in 3D, where a height
// field cannot look: under an overhang, along a vertical face. Site frame, metres.
class LevelSetProbe {
 public:
  explicit LevelSetProbe(const std::filesystem::path& vdb);  // throws IoError when unreadable
  ~LevelSetProbe();
  LevelSetProbe(LevelSetProbe&&) noexcept;
  double voxel_size_m() const;
  double truncation_m() const;  // distances are clamped to +-this
  // out[k], k < n: the signed distance at (x, y, z0 + k dz), > 0 above the surface
  // (air), < 0 in the ground, NaN where the voxels around were not all observed.
  // Safe to call from several threads at once.
  void column(double x, double y, double z0, double dz, int n, double* out) const;

 private:
  std::unique_ptr<dense::TsdfVolume> volume_;
};

// Volume enclosed by a closed level set, cubic metres (openvdb::tools::levelSetVolume).
double level_set_volume_m3(const std::filesystem::path& vdb);
// Zero level set of a .vdb as triangles (site frame), unseen voxels masked out.
DenseMesh level_set_mesh(const std::filesystem::path& vdb, double adaptivity = 0);

}  // namespace strata
