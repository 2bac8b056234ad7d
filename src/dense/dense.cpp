// run_dense(): the dense stage for one layer, in streaming steps (one reference view
// and its sources in memory at a time; intermediate results in the cache):
//   view selection -> undistortion -> PatchMatch depth maps -> consistency filter
//   -> TSDF fusion -> mesh / points -> writers -> quality figures.
// The maths lives in the other files of this module; this one orders the steps,
// times them, and reports progress.
#include "core/parallel.hpp"
#include "core/statistics.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/hash.hpp"
#include "core/log.hpp"
#include "core/progress.hpp"
#include "core/resources.hpp"
#include "dense/dense.hpp"
#include "dense/internal.hpp"
#include "exporters/mesh/mesh_writers.hpp"
#include "geometry/polygon.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <system_error>

namespace strata {
namespace {

using dense::DepthMap;
using dense::PinholeCamera;
using dense::ViewImage;

// A media-store file name: 64 lower-case hex digits (the SHA-256), then an extension.
bool is_content_address(const std::string& name) {
  if (name.size() < 65 || name[64] != '.') return false;
  return std::all_of(name.begin(), name.begin() + 64,
                     [](char c) { return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'); });
}

StepFigures figures(const Stopwatch& sw) { return {sw.seconds(), peak_memory_bytes()}; }

// Andrew's monotone chain: convex hull of the sparse points in XY, counter-clockwise.
std::vector<Eigen::Vector2d> convex_hull(std::vector<Eigen::Vector2d> p) {
  std::sort(p.begin(), p.end(), [](const auto& a, const auto& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  });
  if (p.size() < 3) return p;
  auto cross = [](const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
  };
  std::vector<Eigen::Vector2d> h(2 * p.size());
  std::size_t k = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    while (k >= 2 && cross(h[k - 2], h[k - 1], p[i]) <= 0) --k;
    h[k++] = p[i];
  }
  for (std::size_t i = p.size() - 1, t = k + 1; i > 0; --i) {
    while (k >= t && cross(h[k - 2], h[k - 1], p[i - 1]) <= 0) --k;
    h[k++] = p[i - 1];
  }
  h.resize(k - 1);
  return h;
}

// The coarsest depth-map scale (0.25, 0.5, 1) whose ground sampling distance at the
// median sparse depth of the reference images is at most target_gsd (metres): the
// depth maps cost time in proportion to their pixels, and a GSD finer than the
// voxel/DTM cell buys nothing.
double choose_scale(const Reconstruction& rec, const std::vector<dense::ViewNeighbours>& nb,
                    const std::vector<int>& refs, double target_gsd) {
  std::vector<double> gsd;  // metres per photo pixel
  for (int i : refs) {
    const auto& intr = rec.groups[rec.images[i].group].intrinsics;
    if (nb[i].depth_median > 0 && intr.fx > 0) gsd.push_back(nb[i].depth_median / intr.fx);
  }
  const double g = percentile(gsd, 0.5);
  if (!std::isfinite(g)) return 1.0;
  for (double s : {0.25, 0.5}) {
    if (g / s <= target_gsd) return s;
  }
  return 1.0;
}

}  // namespace

DenseSummary run_dense(const DenseOptions& options, const Reconstruction& rec,
                       const std::vector<std::filesystem::path>& image_paths,
                       const Eigen::Vector3d& site_origin, const std::filesystem::path& cache_dir,
                       const std::filesystem::path& out_dir) {
  return run_dense(options, rec, image_paths, {}, site_origin, cache_dir, out_dir);
}

namespace {

void check_inputs(const Reconstruction& rec, const std::vector<std::filesystem::path>& image_paths,
                  const std::vector<RangeScanInput>& scans) {
  for (const auto& scan : scans) {
    if (!(scan.sigma_m > 0) || !scan.read) {
      throw InputError(fmt::format("dense: scan {} needs a positive sigma_m and a reader", scan.name));
    }
  }
  if (image_paths.size() != rec.images.size()) {
    throw InputError(fmt::format("dense: {} image paths for {} images in the reconstruction",
                                 image_paths.size(), rec.images.size()));
  }
  for (const auto& im : rec.images) {
    if (im.registered && (im.group < 0 || im.group >= static_cast<int>(rec.groups.size()))) {
      throw InputError(fmt::format("dense: image {} refers to camera group {} of {}", im.name,
                                   im.group, rec.groups.size()));
    }
  }
}

// The layer's views and their files in the cache, filled in step by step: the source
// views of each reference image, then the keys of its undistorted image and of its raw
// and filtered depth maps (0: none).
struct Views {
  Views(const Reconstruction& r, const std::filesystem::path& cache_dir)
      : rec(r), image_dir(cache_dir / "dense" / "images"), depth_dir(cache_dir / "dense" / "depth") {}

  const Reconstruction& rec;
  std::filesystem::path image_dir, depth_dir;
  double scale = 1;  // of the depth maps, relative to the photos
  std::vector<dense::ViewNeighbours> neighbours;
  std::vector<int> refs;      // the reference images: those with source views
  std::vector<char> needed;   // undistorted image needed
  std::vector<std::uint64_t> image_key, raw_key, filtered_key;

  PinholeCamera camera(int i) const {
    const auto& im = rec.images[i];
    return dense::undistorted_camera(rec.groups[im.group].intrinsics, im.pose, scale);
  }
  std::filesystem::path image_file(int i) const { return image_dir / fmt::format("{:05d}.img", i); }
  std::filesystem::path raw_file(int i) const { return depth_dir / fmt::format("{:05d}.raw.dmap", i); }
  std::filesystem::path filtered_file(int i) const { return depth_dir / fmt::format("{:05d}.filtered.dmap", i); }
  double reference_count() const { return static_cast<double>(std::max<std::size_t>(refs.size(), 1)); }
  ViewImage load_image(int i) const {
    ViewImage img;
    if (!dense::read_view_image(image_file(i), image_key[i], img)) {
      throw IoError(fmt::format("dense.cache: {}: unreadable undistorted image", image_file(i).string()));
    }
    return img;
  }
};

void create_folders(const Views& views, const std::filesystem::path& out_dir) {
  std::error_code ec;
  for (const auto& d : {views.image_dir, views.depth_dir, out_dir}) {
    std::filesystem::create_directories(d, ec);
    if (ec) throw IoError(fmt::format("dense: {}: cannot create folder: {}", d.string(), ec.message()));
  }
}

// Step 1: the source views of every image; resolves pm.scale when 0.
void select_source_views(const DenseOptions& options, const std::vector<RangeScanInput>& scans,
                         PatchMatchOptions& pm, Views& views, DenseSummary& summary) {
  const Stopwatch sw;
  const auto& rec = views.rec;
  const int n = static_cast<int>(rec.images.size());
  views.neighbours = dense::select_views(rec, options.views, pm.depth_margin);
  views.needed.assign(static_cast<std::size_t>(n), 0);
  for (int i = 0; i < n; ++i) {
    if (!views.neighbours[i].reference) continue;
    views.refs.push_back(i);
    views.needed[i] = 1;
    for (int s : views.neighbours[i].sources) views.needed[s] = 1;
  }
  if (views.refs.empty() && scans.empty()) {
    throw ProcessingError("dense: no registered image has overlapping neighbours with shared sparse points");
  }
  if (views.refs.empty() && n > 0) {
    log::warn("dense: no registered photo has overlapping neighbours; the surface comes from the {} scan(s) alone",
              scans.size());
  }
  if (pm.scale == 0) pm.scale = choose_scale(rec, views.neighbours, views.refs, pm.target_gsd_m);
  views.scale = pm.scale;
  summary.depth_scale = pm.scale;
  summary.view_selection = figures(sw);
  fault::point("process.dense.views_selected");
  if (n > 0) {
    log::info("dense: {} of {} images are reference views (depth maps at scale {})", views.refs.size(), n, pm.scale);
  }
  views.image_key.assign(static_cast<std::size_t>(n), 0);
  views.raw_key.assign(static_cast<std::size_t>(n), 0);
  views.filtered_key.assign(static_cast<std::size_t>(n), 0);
}

// The key of a photo's undistorted image.
std::uint64_t undistorted_key(const std::filesystem::path& photo, double scale, const Intrinsics& intr,
                              const Pose& pose) {
  std::error_code ec;
  const auto size = std::filesystem::file_size(photo, ec);
  if (ec) throw IoError(fmt::format("dense.undistort: {}: cannot read the photo", photo.string()));
  CacheKey image("undistorted view v2");
  if (const std::string name = photo.filename().string(); is_content_address(name)) {
    // A photo of the media store: its name is its SHA-256 (checked before the
    // stage runs), so the key holds whatever folder the project was moved to.
    image.add(name).add(size);
  } else {
    const auto mtime = std::filesystem::last_write_time(photo, ec).time_since_epoch().count();
    image.add(photo).add(size).add(mtime);
  }
  return image.add(scale).add(intr).add(pose).u64();
}

// Step 2: undistortion, once per needed image, into the cache.
void undistort_views(const DenseOptions& options, const std::vector<std::filesystem::path>& image_paths,
                     Views& views, DenseSummary& summary) {
  const Stopwatch sw;
  const auto& rec = views.rec;
  const int n = static_cast<int>(rec.images.size());
  {
    Progress progress("dense: undistort",
                      static_cast<std::size_t>(std::count(views.needed.begin(), views.needed.end(), 1)));
    for (int i = 0; i < n; ++i) {
      if (!views.needed[i]) continue;
      check_cancelled();
      const auto& im = rec.images[i];
      const auto& intr = rec.groups[im.group].intrinsics;
      const std::uint64_t key = undistorted_key(image_paths[i], views.scale, intr, im.pose);
      views.image_key[i] = key;
      ViewImage cached;
      if (!options.reuse_cache || !dense::read_view_image(views.image_file(i), key, cached)) {
        dense::write_view_image(views.image_file(i),
                                dense::undistort_image(image_paths[i], intr, im.pose, views.scale), key);
        fault::point("process.dense.image_undistorted");
      }
      progress.step();
    }
  }
  summary.undistortion = figures(sw);
}

// The ground sampling distance of a depth map: its median depth over the focal length,
// metres per pixel.
double depth_map_gsd(const DepthMap& map, const PinholeCamera& camera) {
  std::vector<double> d;
  d.reserve(map.valid_count());
  for (float v : map.depth) if (v > 0) d.push_back(v);
  return percentile(std::move(d), 0.5) / camera.fx;
}

// The raw depth map of reference image i, from the cache or PatchMatch.
DepthMap raw_depth_map(const DenseOptions& options, const PatchMatchOptions& pm, int i, Views& views,
                       DenseSummary& summary) {
  const auto& nb = views.neighbours[i];
  CacheKey raw("raw depth map v2");
  raw.add(views.image_key[i]);
  for (int s : nb.sources) raw.add(views.image_key[s]);
  const std::uint64_t key = raw.add(nb.depth_min).add(nb.depth_max).add(pm).u64();
  views.raw_key[i] = key;
  DepthMap map;
  if (options.reuse_cache && dense::read_depth_map(views.raw_file(i), key, map)) {
    ++summary.depth_maps_from_cache;
    return map;
  }
  const ViewImage ref = views.load_image(i);
  std::vector<ViewImage> src;
  src.reserve(nb.sources.size());
  for (int s : nb.sources) src.push_back(views.load_image(s));
  std::vector<const ViewImage*> src_ptr;
  for (const auto& s : src) src_ptr.push_back(&s);
  map = dense::patch_match(ref, src_ptr, nb.depth_min, nb.depth_max, pm);
  dense::write_depth_map(views.raw_file(i), map, key);
  fault::point("process.dense.depth_map_written");
  return map;
}

// Step 3: depth maps (PatchMatch; one reference and its sources in memory). Returns the
// ground sampling distance of each map with depth, metres per pixel.
std::vector<double> compute_depth_maps(const DenseOptions& options, const PatchMatchOptions& pm, Views& views,
                                       DenseSummary& summary) {
  const Stopwatch sw;
  std::vector<double> gsd;
  double valid_sum = 0;
  {
    Progress progress("dense: depth maps", views.refs.size());
    for (int i : views.refs) {
      check_cancelled();
      const DepthMap map = raw_depth_map(options, pm, i, views, summary);
      const std::size_t valid = map.valid_count();
      valid_sum += static_cast<double>(valid) / (static_cast<double>(map.width) * map.height);
      if (valid > 0) gsd.push_back(depth_map_gsd(map, views.camera(i)));
      progress.step();
    }
  }
  summary.valid_depth_fraction = valid_sum / views.reference_count();
  summary.depth_maps = figures(sw);
  fault::point("process.dense.depth_maps_done");
  return gsd;
}

// The depth map of reference image i kept by the consistency test against its sources'
// raw maps, from the cache or computed.
DepthMap filtered_depth_map(const DenseOptions& options, int i, Views& views) {
  const auto& cons = options.consistency;
  CacheKey filtered_depth("filtered depth map v2");
  filtered_depth.add(views.raw_key[i]);
  for (int s : views.neighbours[i].checks) filtered_depth.add(views.raw_key[s]);
  const std::uint64_t key = filtered_depth.add(cons).u64();
  views.filtered_key[i] = key;
  DepthMap filtered;
  if (options.reuse_cache && dense::read_depth_map(views.filtered_file(i), key, filtered)) return filtered;
  DepthMap ref;
  if (!dense::read_depth_map(views.raw_file(i), views.raw_key[i], ref)) {
    throw IoError(fmt::format("dense.cache: {}: unreadable depth map", views.raw_file(i).string()));
  }
  std::vector<DepthMap> maps;
  std::vector<PinholeCamera> cams;
  for (int s : views.neighbours[i].checks) {
    DepthMap m;
    if (views.raw_key[s] == 0 || !dense::read_depth_map(views.raw_file(s), views.raw_key[s], m)) continue;
    maps.push_back(std::move(m));
    cams.push_back(views.camera(s));
  }
  std::vector<dense::DepthNeighbour> nbs;
  for (std::size_t k = 0; k < maps.size(); ++k) nbs.push_back({&maps[k], &cams[k]});
  filtered = dense::filter_consistent(ref, views.camera(i), nbs, cons);
  dense::write_depth_map(views.filtered_file(i), filtered, key);
  fault::point("process.dense.filtered_map_written");
  return filtered;
}

// Step 4: geometric consistency (reads the raw maps of each reference and its sources).
void filter_depth_maps(const DenseOptions& options, Views& views, DenseSummary& summary) {
  const Stopwatch sw;
  double kept_sum = 0;
  {
    Progress progress("dense: consistency", views.refs.size());
    for (int i : views.refs) {
      check_cancelled();
      const DepthMap filtered = filtered_depth_map(options, i, views);
      kept_sum += static_cast<double>(filtered.valid_count()) /
                  (static_cast<double>(filtered.width) * filtered.height);
      if (filtered.valid_count() > 0) ++summary.images_with_depth;
      progress.step();
    }
  }
  summary.consistent_depth_fraction = kept_sum / views.reference_count();
  summary.filtering = figures(sw);
}

// The voxel size the options ask for, or one from the depth maps' GSD (the scans' point
// spacing and noise without photo depth).
double voxel_size(const FusionOptions& fo, double gsd_m, const std::vector<RangeScanInput>& scans) {
  if (fo.voxel_size_m != 0) return fo.voxel_size_m;
  if (gsd_m > 0) return std::clamp(fo.voxel_gsd_factor * gsd_m, fo.min_voxel_size_m, fo.max_voxel_size_m);
  if (!scans.empty()) {
    // No photo depth: the scans' own point spacing takes the place of the GSD, but the
    // voxel is no finer than one sigma of their points (overlapping depth frames are
    // dense together, each point noisy: finer voxels are left with holes).
    const dense::ScanSampling s = dense::scan_sampling(scans);
    const double voxel = std::clamp(std::max(fo.voxel_gsd_factor * s.spacing_m, s.noise_m), fo.min_voxel_size_m,
                                    fo.max_voxel_size_m);
    log::info("dense: no photo depth; voxel from the scans' median point spacing {:.1f} mm and noise {:.1f} mm",
              s.spacing_m * 1e3, s.noise_m * 1e3);
    return voxel;
  }
  throw ProcessingError("dense: no depth estimated, cannot choose a voxel size");
}

void integrate_depth_maps(const Views& views, dense::TsdfVolume& volume) {
  Progress progress("dense: fusion", views.refs.size());
  for (int i : views.refs) {
    check_cancelled();
    DepthMap map;
    if (!dense::read_depth_map(views.filtered_file(i), views.filtered_key[i], map)) {
      throw IoError(fmt::format("dense.cache: {}: unreadable depth map", views.filtered_file(i).string()));
    }
    if (map.valid_count() > 0) volume.integrate(views.camera(i), map, views.load_image(i).rgb);
    progress.step();
  }
}

void integrate_scans(const FusionOptions& fo, const std::vector<RangeScanInput>& scans, double voxel,
                     dense::TsdfVolume& volume, DenseSummary& summary) {
  // Photos and scans in one unit of weight: 1 for a confidence-1 photo depth seen
  // head-on, whose noise is photo_depth_sigma_gsd depth-map GSDs (dense.hpp).
  summary.unit_sigma_m = summary.gsd_m > 0 ? fo.photo_depth_sigma_gsd * summary.gsd_m : voxel;
  const double photo_weight = volume.total_weight();
  const dense::ScanFusionFigures f = dense::fuse_scans(volume, scans, summary.unit_sigma_m);
  summary.scans_fused = f.scans;
  summary.scan_points = f.points;
  const double all = photo_weight + f.weight;
  summary.scan_weight_share = all > 0 ? f.weight / all : 0;
  log::info("dense: {} scan(s), {} points fused ({:.0f} % of the weight; unit sigma {:.1f} mm)", f.scans, f.points,
            100 * summary.scan_weight_share, summary.unit_sigma_m * 1e3);
}

// Step 5: TSDF fusion of the filtered depth maps and the scans, then the clean-up of
// the volume.
void fuse(const DenseOptions& options, const Views& views, const std::vector<RangeScanInput>& scans,
          dense::TsdfVolume& volume, DenseSummary& summary, const Stopwatch& sw) {
  const auto& fo = options.fusion;
  integrate_depth_maps(views, volume);
  if (!scans.empty()) integrate_scans(fo, scans, summary.voxel_size_m, volume, summary);
  volume.finalise(fo.min_weight);
  summary.floating_voxels_removed = volume.remove_small_components(fo.min_component_fraction);
  summary.active_voxels = volume.active_voxels();
  summary.fusion = figures(sw);
  fault::point("process.dense.fusion_done");
  log::info("dense: voxel {:.1f} mm, {} active voxels ({} in small floating pieces removed)",
            summary.voxel_size_m * 1e3, summary.active_voxels, summary.floating_voxels_removed);
  if (summary.active_voxels == 0) throw ProcessingError("dense: fusion left no observed voxel");
}

struct Surfaces {
  DenseMesh mesh;
  DenseMesh points;
};

// Step 6: the mesh (adaptive and simplified as the options say) and the points.
Surfaces extract_surfaces(const MeshOptions& mo, dense::TsdfVolume& volume, DenseSummary& summary) {
  const Stopwatch sw;
  Surfaces s;
  s.mesh = volume.extract_mesh(0.0);
  s.points = volume.points_from_mesh(s.mesh, mo.min_point_weight, mo.min_point_observations);
  summary.points_below_weight = s.mesh.vertices.size() - s.points.vertices.size();
  if (mo.adaptivity > 0) s.mesh = volume.extract_mesh(mo.adaptivity);
  if (mo.target_faces > 0 && s.mesh.faces.size() > mo.target_faces) {
    s.mesh = simplify_mesh(s.mesh, mo.target_faces);
    volume.colour_vertices(s.mesh);
  }
  summary.mesh_vertices = s.mesh.vertices.size();
  summary.mesh_faces = s.mesh.faces.size();
  summary.points = s.points.vertices.size();
  summary.meshing = figures(sw);
  fault::point("process.dense.mesh_done");
  return s;
}

// Step 7: the products, each recorded with its checksum.
void write_products(const DenseOptions& options, const dense::TsdfVolume& volume, const Surfaces& s,
                    const Eigen::Vector3d& site_origin, const std::filesystem::path& out_dir,
                    DenseSummary& summary) {
  const Stopwatch sw;
  ExportFrame frame = options.exports;
  frame.site_origin = site_origin;
  auto record = [&](const std::string& kind, const std::filesystem::path& p) {
    summary.products.push_back({kind, p, sha256_file(p)});
  };
  volume.write(out_dir / "surface.vdb", site_origin, frame.crs);
  record("surface", out_dir / "surface.vdb");
  fault::point("process.dense.surface_written");
  write_ply(out_dir / "mesh.ply", s.mesh, frame);
  record("mesh", out_dir / "mesh.ply");
  fault::point("process.dense.mesh_written");
  if (options.mesh.write_obj) {
    write_obj(out_dir / "mesh.obj", s.mesh, frame);
    record("mesh_obj", out_dir / "mesh.obj");
  }
  write_ply(out_dir / "points.ply", s.points, frame);
  record("points", out_dir / "points.ply");
  fault::point("process.dense.points_written");
  summary.writing = figures(sw);
}

// Step 8a: completeness, the share of the area's cells that have a surface; the area is
// the convex hull of the sparse points unless the options give one.
void measure_completeness(const QualityOptions& q, const Reconstruction& rec, const dense::TsdfVolume& volume,
                          DenseSummary& summary) {
  std::vector<Eigen::Vector2d> area = q.area;
  if (area.empty()) {
    std::vector<Eigen::Vector2d> xy;
    for (const auto& p : rec.points) xy.push_back(p.X.head<2>());
    area = convex_hull(std::move(xy));
  }
  if (area.size() < 3) return;
  Eigen::Vector2d lo = area[0], hi = area[0];
  for (const auto& p : area) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double cell = q.cell_size_m;
  const int nx = std::max(1, static_cast<int>(std::ceil((hi.x() - lo.x()) / cell)));
  const int ny = std::max(1, static_cast<int>(std::ceil((hi.y() - lo.y()) / cell)));
  // South-west corner at lo.
  const RasterGrid grid{.x_min = lo.x(), .y_max = lo.y() + ny * cell, .cell = cell, .width = nx, .height = ny};
  const HeightRaster<double> hf = volume.top_surface(grid);
  std::size_t inside = 0, covered = 0;
  for (int row = 0; row < ny; ++row) {
    for (int col = 0; col < nx; ++col) {
      if (!inside_polygon(area, grid.x_centre(col), grid.y_centre(row))) continue;
      ++inside;
      if (hf.valid(col, row)) ++covered;
    }
  }
  summary.area_m2 = static_cast<double>(inside) * cell * cell;
  summary.completeness = inside > 0 ? static_cast<double>(covered) / inside : 0;
}

// Step 8b: the distance of the surface to the sparse points.
void measure_sparse_distance(const Reconstruction& rec, const dense::TsdfVolume& volume, DenseSummary& summary) {
  std::vector<Eigen::Vector3d> sparse;
  for (const auto& p : rec.points) sparse.push_back(p.X);
  std::vector<double> dist;
  for (double d : volume.distances(sparse)) if (std::isfinite(d)) dist.push_back(d);
  summary.sparse_points_compared = dist.size();
  summary.median_distance_sparse_m = percentile(dist, 0.5);
  summary.p95_distance_sparse_m = percentile(dist, 0.95);
}

DenseSummary run_dense_steps(const DenseOptions& options, const Reconstruction& rec,
                             const std::vector<std::filesystem::path>& image_paths,
                             const std::vector<RangeScanInput>& scans, const Eigen::Vector3d& site_origin,
                             const std::filesystem::path& cache_dir, const std::filesystem::path& out_dir) {
  check_inputs(rec, image_paths, scans);
  const Stopwatch total;
  DenseSummary summary;
  summary.images_total = static_cast<int>(rec.images.size());
  PatchMatchOptions pm = options.patch_match;  // scale resolved by select_source_views when 0
  Views views(rec, cache_dir);
  create_folders(views, out_dir);

  select_source_views(options, scans, pm, views, summary);
  undistort_views(options, image_paths, views, summary);
  const std::vector<double> gsd = compute_depth_maps(options, pm, views, summary);
  filter_depth_maps(options, views, summary);

  const Stopwatch fusion;
  summary.gsd_m = gsd.empty() ? 0 : percentile(gsd, 0.5);
  summary.smoothing_m = options.patch_match.smoothing_m(summary.gsd_m);
  summary.voxel_size_m = voxel_size(options.fusion, summary.gsd_m, scans);
  summary.truncation_m = options.fusion.truncation_voxels * summary.voxel_size_m;
  dense::TsdfVolume volume(summary.voxel_size_m, summary.truncation_m);
  fuse(options, views, scans, volume, summary, fusion);

  const Surfaces surfaces = extract_surfaces(options.mesh, volume, summary);
  write_products(options, volume, surfaces, site_origin, out_dir, summary);
  measure_completeness(options.quality, rec, volume, summary);
  measure_sparse_distance(rec, volume, summary);

  summary.total = figures(total);
  log::info("dense: {} faces, {} points, completeness {:.1f} %, sparse distance median {:.1f} mm, "
            "p95 {:.1f} mm, {:.1f} s",
            summary.mesh_faces, summary.points, 100 * summary.completeness,
            summary.median_distance_sparse_m * 1e3, summary.p95_distance_sparse_m * 1e3,
            summary.total.seconds);
  return summary;
}

}  // namespace

DenseSummary run_dense(const DenseOptions& options, const Reconstruction& rec,
                       const std::vector<std::filesystem::path>& image_paths,
                       const std::vector<RangeScanInput>& scans, const Eigen::Vector3d& site_origin,
                       const std::filesystem::path& cache_dir, const std::filesystem::path& out_dir) {
  options.validate();
  DenseSummary summary;
  with_threads(options.threads, [&] {
    summary = run_dense_steps(options, rec, image_paths, scans, site_origin, cache_dir, out_dir);
  });
  return summary;
}

}  // namespace strata
