#pragma once
// Internal building blocks of the dense stage (not for other modules; tests use
// them). Plain structs, Eigen and std only: OpenCV lives in images.cpp, OpenVDB
// in fusion.cpp, CGAL in simplify.cpp.
#include "dense/dense.hpp"
#include "geometry/camera.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace strata::dense {

// An undistorted pinhole camera at depth-map resolution. Pixel (0,0) is the
// centre of the top-left pixel, as in geometry/camera.hpp.
struct PinholeCamera {
  int width = 0, height = 0;       // pixels
  double fx = 0, fy = 0, cx = 0, cy = 0;  // pixels
  Pose pose;                       // world (site frame) -> camera

  // Point in the camera frame at the given depth (z_cam, metres) through pixel (u, v).
  Eigen::Vector3d ray_point(double u, double v, double depth) const {
    return {(u - cx) / fx * depth, (v - cy) / fy * depth, depth};
  }
  Eigen::Vector3d to_world(const Eigen::Vector3d& Xc) const {
    return pose.R.transpose() * (Xc - pose.t);
  }
};

// The pinhole camera that undistort_image() resamples to: same focal length and
// principal point as the photo, scaled (centre-of-pixel convention kept exact).
PinholeCamera undistorted_camera(const Intrinsics& intrinsics, const Pose& pose, double scale);

// One undistorted photo at depth-map resolution.
struct ViewImage {
  PinholeCamera camera;
  std::vector<float> gray;          // [0, 1], NaN outside the photo
  std::vector<std::uint8_t> rgb;    // interleaved, 0 outside the photo
  float gray_at(int x, int y) const { return gray[static_cast<std::size_t>(y) * camera.width + x]; }
};

// Reads a photo and resamples it without distortion (cv::remap through the strata
// radial model) at `scale`. Throws IoError("dense.undistort: <path>: ...").
ViewImage undistort_image(const std::filesystem::path& photo, const Intrinsics& intrinsics,
                          const Pose& pose, double scale);

// Depth + normal per pixel; depth 0 = no estimate.
struct DepthMap {
  int width = 0, height = 0;
  std::vector<float> depth;       // metres along the camera z axis
  std::vector<float> normal;      // 3 per pixel, camera frame, facing the camera
  std::vector<float> confidence;  // [0, 1]: 1 - photometric cost, then consistency share
  void resize(int w, int h) {
    width = w;
    height = h;
    const auto n = static_cast<std::size_t>(w) * h;
    depth.assign(n, 0.f);
    normal.assign(3 * n, 0.f);
    confidence.assign(n, 0.f);
  }
  std::size_t valid_count() const;
};

// Neighbours of one reference image and its expected depth range from the sparse points.
struct ViewNeighbours {
  std::vector<int> sources;   // image indices, best first
  bool reference = false;     // gets a depth map (ViewSelectionOptions::reference_cover)
  std::vector<int> checks;    // reference views whose depth maps check this one's, best first
  double depth_min = 0;       // metres
  double depth_max = 0;
  double depth_median = 0;    // metres, median sparse depth (0 when none)
};

// For every image of the reconstruction: its source views (empty when the image is
// unregistered or has no usable neighbour), depth range, whether it is a reference
// view and, if so, the reference views that check its depth map.
std::vector<ViewNeighbours> select_views(const Reconstruction& rec, const ViewSelectionOptions& opt,
                                         double depth_margin);

// PatchMatch stereo for one reference view against its sources (see patch_match.cpp).
DepthMap patch_match(const ViewImage& ref, const std::vector<const ViewImage*>& sources,
                     double depth_min, double depth_max, const PatchMatchOptions& opt);

// Keeps the depths that at least opt.min_consistent_views neighbour depth maps confirm
// by forward-backward reprojection; confidence is scaled by the agreeing share.
struct DepthNeighbour {
  const DepthMap* depth;
  const PinholeCamera* camera;
};
DepthMap filter_consistent(const DepthMap& ref, const PinholeCamera& ref_camera,
                           const std::vector<DepthNeighbour>& neighbours,
                           const ConsistencyOptions& opt);

// ---- cache files (binary, little-endian, versioned, keyed) ----------------------
// Each file holds the 64-bit CacheKey of its inputs (core/cache_key.hpp): a stale
// file is recomputed. hash_bytes (FNV-1a) is the checksum of a file's body, which
// finds a torn or corrupt file; it is not a key.
std::uint64_t hash_bytes(const void* data, std::size_t size, std::uint64_t seed = 0);
void write_depth_map(const std::filesystem::path& path, const DepthMap& map, std::uint64_t key);
bool read_depth_map(const std::filesystem::path& path, std::uint64_t key, DepthMap& out);
void write_view_image(const std::filesystem::path& path, const ViewImage& image, std::uint64_t key);
bool read_view_image(const std::filesystem::path& path, std::uint64_t key, ViewImage& out);

// ---- TSDF volume (OpenVDB inside fusion.cpp) -------------------------------------
class TsdfVolume {
 public:
  TsdfVolume(double voxel_size_m, double truncation_m);
  ~TsdfVolume();
  TsdfVolume(const TsdfVolume&) = delete;
  TsdfVolume& operator=(const TsdfVolume&) = delete;

  // Reads surface.vdb written by write().
  static std::unique_ptr<TsdfVolume> read(const std::filesystem::path& vdb, LevelSetInfo* info);

  // Curless & Levoy (1996) running weighted average of truncated distances along
  // the view rays of one depth map; colours averaged with the same weights. Every
  // depth map is integrated before the first scan.
  void integrate(const PinholeCamera& camera, const DepthMap& depth,
                 const std::vector<std::uint8_t>& rgb);
  // One range scan (a laser scanner's or phone LiDAR's points, site frame), fused
  // along each point's own ray: `dirs[i]` is the unit direction of point i's ray,
  // from the sensor towards the point. Call add_scan_points() with every chunk of
  // the scan, then end_scan() once. Within the scan, each voxel within the narrow
  // band of a ray (the 2 x 2 x 2 voxels around samples every half voxel along it)
  // collects the signed distance of its centre along that ray, weighted by a
  // Gaussian of its distance from the ray (one voxel sigma); end_scan() then adds
  // to the voxel one observation: the weighted mean distance, with the weight
  // `weight_per_point` x n_eff, n_eff = (sum g)^2 / sum g^2 the effective number of
  // points averaged (the inverse variance of their mean, in the fusion's unit
  // weight).
  // Points of unequal noise (a depth camera's k z^2) carry `relative_weights`, the
  // inverse variance of each relative to the scan's sigma: a voxel then sums w g,
  // w g d and w g^2, so its mean is inverse-variance weighted and n_eff = (sum w g)^2
  // / sum w g^2 is the inverse variance of that mean in units of the scan's sigma
  // (equal weights: as without). Empty: every point weighs 1.
  // Colour: points with `colours` (a depth camera's colour frame, a PLY/LAS scan's
  // RGB; all of a scan's chunks or none) give the voxel's observation the colour
  // sum w g rgb / sum w g, averaged into the voxel's colour with the observation's
  // weight, over every coloured scan. Photos' colour comes first: a voxel that a
  // photo coloured (integrate() before any scan) keeps it. Voxels neither photos nor
  // coloured scans saw are mid grey.
  void add_scan_points(const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector3d>& dirs,
                       const std::vector<double>& relative_weights = {}, const std::vector<Rgb8>& colours = {});
  struct ScanFusion {
    std::size_t voxels = 0;  // voxels that received an observation from the scan
    double weight = 0;       // sum of the weights added
  };
  ScanFusion end_scan(double weight_per_point);
  // Sum of the accumulated weight over the observed voxels.
  double total_weight() const;
  // Drops voxels seen with less than min_weight; call once after integration.
  void finalise(double min_weight);
  // Drops the connected pieces of the narrow band (6-connected active voxels) with
  // fewer than `min_fraction` of all active voxels: floaters of wrong depths that
  // survived the consistency tests, away from the surface. Returns the voxels removed.
  std::size_t remove_small_components(double min_fraction);

  double voxel_size() const;
  std::size_t active_voxels() const;
  // Zero level set as triangles; faces next to unseen voxels are dropped (they are
  // the border of the narrow band, not the surface). Coloured when colour exists.
  DenseMesh extract_mesh(double adaptivity) const;
  // Colours vertices from the colour grid (after simplification).
  void colour_vertices(DenseMesh& mesh) const;
  // The point cloud of a mesh from extract_mesh(0): its vertices (one per surface
  // cell, on the zero level set) with colour and the level-set gradient as normal.
  // The vertices of the unsimplified mesh whose voxel holds at least `min_weight` of
  // fused weight or `min_observations` effective observations, with the level set's
  // gradient as normals.
  DenseMesh points_from_mesh(const DenseMesh& full_mesh, double min_weight, double min_observations) const;
  // Uppermost zero crossing per cell (see sample_top_surface()).
  HeightRaster<double> top_surface(const RasterGrid& grid) const;
  // |signed distance| to the surface at each point, metres; NaN outside the band.
  std::vector<double> distances(const std::vector<Eigen::Vector3d>& points) const;
  // Signed distances (trilinear) at (x, y, z0 + k dz), k < n: > 0 in front of the
  // surface (air), < 0 behind it (ground); NaN where the 2x2x2 voxels around are not
  // all observed. Safe to call from several threads at once.
  void signed_column(double x, double y, double z0, double dz, int n, double* out) const;
  double truncation() const;
  // Writes grids "surface" (level set), "weight", "colour", with the site origin and CRS
  // as metadata; temp file then rename.
  void write(const std::filesystem::path& vdb, const Eigen::Vector3d& site_origin,
             const std::string& crs) const;
  double level_set_volume() const;

  struct Impl;

 private:
  explicit TsdfVolume(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// ---- range scans (range_scans.cpp; the volume maths is in fusion.cpp) -------------
// Unit ray directions (sensor towards point) of a chunk of a scan's points: from
// its station when known, else against the point's normal turned to face up, else
// straight down (RangeScanInput::station).
std::vector<Eigen::Vector3d> scan_ray_directions(const RangeScanInput& scan,
                                                 const std::vector<Eigen::Vector3d>& points,
                                                 const std::vector<Eigen::Vector3f>& normals);
// How finely the scans sample the ground, what a layer without photos takes its
// voxel from (docs/range.md, "Voxel size").
struct ScanSampling {
  // Median spacing of all the scans' points over the ground, metres: per 1 cm cell of
  // the XY plane that holds points, 1 cm / sqrt(points in it); the median over cells.
  double spacing_m = 0;
  // The points' noise, one sigma, metres: per scan the median of its points' sigmas
  // (RangeScanInput::point_sigma, else sigma_m); the median over the scans.
  double noise_m = 0;
};
// Reads every scan once; throws ProcessingError when they hold no point.
ScanSampling scan_sampling(const std::vector<RangeScanInput>& scans);
struct ScanFusionFigures {
  int scans = 0;
  std::uint64_t points = 0;
  double weight = 0;  // sum of the weights the scans added
};
// Fuses every scan into `volume`, each point weighing (unit_sigma_m / sigma)^2, sigma
// its scan's sigma_m or, when the scan has one, its point_sigma.
ScanFusionFigures fuse_scans(TsdfVolume& volume, const std::vector<RangeScanInput>& scans, double unit_sigma_m);

}  // namespace strata::dense
