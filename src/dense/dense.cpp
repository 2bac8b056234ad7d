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

bool inside_polygon(const std::vector<Eigen::Vector2d>& poly, const Eigen::Vector2d& q) {
  bool in = false;  // even-odd crossing rule
  for (std::size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    const auto &a = poly[i], &b = poly[j];
    if ((a.y() > q.y()) != (b.y() > q.y()) &&
        q.x() < (b.x() - a.x()) * (q.y() - a.y()) / (b.y() - a.y()) + a.x()) {
      in = !in;
    }
  }
  return in;
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

DenseSummary run_dense_steps(const DenseOptions& options, const Reconstruction& rec,
                             const std::vector<std::filesystem::path>& image_paths,
                             const std::vector<RangeScanInput>& scans, const Eigen::Vector3d& site_origin,
                             const std::filesystem::path& cache_dir, const std::filesystem::path& out_dir) {
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
  const Stopwatch total;
  DenseSummary summary;
  const int n = static_cast<int>(rec.images.size());
  summary.images_total = n;
  PatchMatchOptions pm = options.patch_match;  // scale resolved below when 0
  const auto image_dir = cache_dir / "dense" / "images";
  const auto depth_dir = cache_dir / "dense" / "depth";
  std::error_code ec;
  for (const auto& d : {image_dir, depth_dir, out_dir}) {
    std::filesystem::create_directories(d, ec);
    if (ec) throw IoError(fmt::format("dense: {}: cannot create folder: {}", d.string(), ec.message()));
  }

  // ---- 1. view selection ------------------------------------------------------
  Stopwatch sw;
  const auto neighbours = dense::select_views(rec, options.views, pm.depth_margin);
  std::vector<char> needed(static_cast<std::size_t>(n), 0);  // undistorted image needed
  std::vector<int> refs;
  for (int i = 0; i < n; ++i) {
    if (neighbours[i].sources.empty()) continue;
    refs.push_back(i);
    needed[i] = 1;
    for (int s : neighbours[i].sources) needed[s] = 1;
  }
  if (refs.empty() && scans.empty()) {
    throw ProcessingError("dense: no registered image has overlapping neighbours with shared sparse points");
  }
  if (refs.empty() && n > 0) {
    log::warn("dense: no registered photo has overlapping neighbours; the surface comes from the {} scan(s) alone",
              scans.size());
  }
  if (pm.scale == 0) pm.scale = choose_scale(rec, neighbours, refs, pm.target_gsd_m);
  summary.depth_scale = pm.scale;
  summary.view_selection = figures(sw);
  fault::point("process.dense.views_selected");
  if (n > 0) log::info("dense: {} of {} images have source views; depth maps at scale {}", refs.size(), n, pm.scale);

  auto camera_of = [&](int i) {
    const auto& im = rec.images[i];
    return dense::undistorted_camera(rec.groups[im.group].intrinsics, im.pose, pm.scale);
  };

  // ---- 2. undistortion (once per image, into the cache) ------------------------
  sw = Stopwatch();
  std::vector<std::uint64_t> image_key(static_cast<std::size_t>(n), 0);
  auto image_file = [&](int i) { return image_dir / fmt::format("{:05d}.img", i); };
  {
    Progress progress("dense: undistort", static_cast<std::size_t>(std::count(needed.begin(), needed.end(), 1)));
    for (int i = 0; i < n; ++i) {
      if (!needed[i]) continue;
      check_cancelled();
      const auto& im = rec.images[i];
      const auto& intr = rec.groups[im.group].intrinsics;
      const auto size = std::filesystem::file_size(image_paths[i], ec);
      if (ec) throw IoError(fmt::format("dense.undistort: {}: cannot read the photo", image_paths[i].string()));
      CacheKey image("undistorted view v2");
      if (const std::string name = image_paths[i].filename().string(); is_content_address(name)) {
        // A photo of the media store: its name is its SHA-256 (checked before the
        // stage runs), so the key holds whatever folder the project was moved to.
        image.add(name).add(size);
      } else {
        const auto mtime = std::filesystem::last_write_time(image_paths[i], ec).time_since_epoch().count();
        image.add(image_paths[i]).add(size).add(mtime);
      }
      const std::uint64_t key = image.add(pm.scale).add(intr).add(im.pose).u64();
      image_key[i] = key;
      ViewImage cached;
      if (!options.reuse_cache || !dense::read_view_image(image_file(i), key, cached)) {
        dense::write_view_image(image_file(i), dense::undistort_image(image_paths[i], intr, im.pose, pm.scale), key);
        fault::point("process.dense.image_undistorted");
      }
      progress.step();
    }
  }
  summary.undistortion = figures(sw);

  auto load_image = [&](int i) {
    ViewImage img;
    if (!dense::read_view_image(image_file(i), image_key[i], img)) {
      throw IoError(fmt::format("dense.cache: {}: unreadable undistorted image", image_file(i).string()));
    }
    return img;
  };

  // ---- 3. depth maps (PatchMatch; one reference + sources in memory) ------------
  sw = Stopwatch();
  std::vector<std::uint64_t> raw_key(static_cast<std::size_t>(n), 0);
  auto raw_file = [&](int i) { return depth_dir / fmt::format("{:05d}.raw.dmap", i); };
  auto filtered_file = [&](int i) { return depth_dir / fmt::format("{:05d}.filtered.dmap", i); };
  std::vector<double> gsd;
  double valid_sum = 0;
  {
    Progress progress("dense: depth maps", refs.size());
    for (int i : refs) {
      check_cancelled();
      const auto& nb = neighbours[i];
      CacheKey raw("raw depth map v2");
      raw.add(image_key[i]);
      for (int s : nb.sources) raw.add(image_key[s]);
      const std::uint64_t key = raw.add(nb.depth_min).add(nb.depth_max).add(pm).u64();
      raw_key[i] = key;
      DepthMap map;
      if (options.reuse_cache && dense::read_depth_map(raw_file(i), key, map)) {
        ++summary.depth_maps_from_cache;
      } else {
        const ViewImage ref = load_image(i);
        std::vector<ViewImage> src;
        src.reserve(nb.sources.size());
        for (int s : nb.sources) src.push_back(load_image(s));
        std::vector<const ViewImage*> src_ptr;
        for (const auto& s : src) src_ptr.push_back(&s);
        map = dense::patch_match(ref, src_ptr, nb.depth_min, nb.depth_max, pm);
        dense::write_depth_map(raw_file(i), map, key);
        fault::point("process.dense.depth_map_written");
      }
      const std::size_t valid = map.valid_count();
      valid_sum += static_cast<double>(valid) / (static_cast<double>(map.width) * map.height);
      if (valid > 0) {
        std::vector<double> d;
        d.reserve(valid);
        for (float v : map.depth) if (v > 0) d.push_back(v);
        gsd.push_back(percentile(std::move(d), 0.5) / camera_of(i).fx);  // metres per pixel
      }
      progress.step();
    }
  }
  const double ref_count = static_cast<double>(std::max<std::size_t>(refs.size(), 1));
  summary.valid_depth_fraction = valid_sum / ref_count;
  summary.depth_maps = figures(sw);
  fault::point("process.dense.depth_maps_done");

  // ---- 4. geometric consistency (reads raw maps of the reference and its sources) --
  sw = Stopwatch();
  const auto& cons = options.consistency;
  std::vector<std::uint64_t> filtered_key(static_cast<std::size_t>(n), 0);
  double kept_sum = 0;
  {
    Progress progress("dense: consistency", refs.size());
    for (int i : refs) {
      check_cancelled();
      CacheKey filtered_depth("filtered depth map v2");
      filtered_depth.add(raw_key[i]);
      for (int s : neighbours[i].sources) filtered_depth.add(raw_key[s]);
      const std::uint64_t key = filtered_depth.add(cons).u64();
      filtered_key[i] = key;
      DepthMap filtered;
      if (!options.reuse_cache || !dense::read_depth_map(filtered_file(i), key, filtered)) {
        DepthMap ref;
        if (!dense::read_depth_map(raw_file(i), raw_key[i], ref)) {
          throw IoError(fmt::format("dense.cache: {}: unreadable depth map", raw_file(i).string()));
        }
        std::vector<DepthMap> maps;
        std::vector<PinholeCamera> cams;
        for (int s : neighbours[i].sources) {
          DepthMap m;
          if (raw_key[s] == 0 || !dense::read_depth_map(raw_file(s), raw_key[s], m)) continue;
          maps.push_back(std::move(m));
          cams.push_back(camera_of(s));
        }
        std::vector<dense::DepthNeighbour> nbs;
        for (std::size_t k = 0; k < maps.size(); ++k) nbs.push_back({&maps[k], &cams[k]});
        filtered = dense::filter_consistent(ref, camera_of(i), nbs, cons);
        dense::write_depth_map(filtered_file(i), filtered, key);
        fault::point("process.dense.filtered_map_written");
      }
      kept_sum += static_cast<double>(filtered.valid_count()) /
                  (static_cast<double>(filtered.width) * filtered.height);
      if (filtered.valid_count() > 0) ++summary.images_with_depth;
      progress.step();
    }
  }
  summary.consistent_depth_fraction = kept_sum / ref_count;
  summary.filtering = figures(sw);

  // ---- 5. TSDF fusion ------------------------------------------------------------
  sw = Stopwatch();
  const auto& fo = options.fusion;
  summary.gsd_m = gsd.empty() ? 0 : percentile(gsd, 0.5);
  summary.smoothing_m = options.patch_match.smoothing_m(summary.gsd_m);
  double voxel = fo.voxel_size_m;
  if (voxel == 0) {
    if (summary.gsd_m > 0) {
      voxel = std::clamp(fo.voxel_gsd_factor * summary.gsd_m, fo.min_voxel_size_m, fo.max_voxel_size_m);
    } else if (!scans.empty()) {
      // No photo depth: the scans' own point spacing takes the place of the GSD.
      const double spacing = dense::scan_point_spacing(scans);
      voxel = std::clamp(fo.voxel_gsd_factor * spacing, fo.min_voxel_size_m, fo.max_voxel_size_m);
      log::info("dense: no photo depth; voxel from the scans' median point spacing {:.1f} mm", spacing * 1e3);
    } else {
      throw ProcessingError("dense: no depth estimated, cannot choose a voxel size");
    }
  }
  summary.voxel_size_m = voxel;
  summary.truncation_m = fo.truncation_voxels * voxel;
  dense::TsdfVolume volume(voxel, summary.truncation_m);
  {
    Progress progress("dense: fusion", refs.size());
    for (int i : refs) {
      check_cancelled();
      DepthMap map;
      if (!dense::read_depth_map(filtered_file(i), filtered_key[i], map)) {
        throw IoError(fmt::format("dense.cache: {}: unreadable depth map", filtered_file(i).string()));
      }
      if (map.valid_count() > 0) volume.integrate(camera_of(i), map, load_image(i).rgb);
      progress.step();
    }
  }
  if (!scans.empty()) {
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
  volume.finalise(fo.min_weight);
  summary.floating_voxels_removed = volume.remove_small_components(fo.min_component_fraction);
  summary.active_voxels = volume.active_voxels();
  summary.fusion = figures(sw);
  fault::point("process.dense.fusion_done");
  log::info("dense: voxel {:.1f} mm, {} active voxels ({} in small floating pieces removed)", voxel * 1e3,
            summary.active_voxels, summary.floating_voxels_removed);
  if (summary.active_voxels == 0) throw ProcessingError("dense: fusion left no observed voxel");

  // ---- 6. mesh and points -----------------------------------------------------------
  sw = Stopwatch();
  DenseMesh mesh = volume.extract_mesh(0.0);
  const DenseMesh points = volume.points_from_mesh(mesh);
  if (options.mesh.adaptivity > 0) mesh = volume.extract_mesh(options.mesh.adaptivity);
  if (options.mesh.target_faces > 0 && mesh.faces.size() > options.mesh.target_faces) {
    mesh = simplify_mesh(mesh, options.mesh.target_faces);
    volume.colour_vertices(mesh);
  }
  summary.mesh_vertices = mesh.vertices.size();
  summary.mesh_faces = mesh.faces.size();
  summary.points = points.vertices.size();
  summary.meshing = figures(sw);
  fault::point("process.dense.mesh_done");

  // ---- 7. writers ---------------------------------------------------------------------
  sw = Stopwatch();
  ExportFrame frame = options.exports;
  frame.site_origin = site_origin;
  auto record = [&](const std::string& kind, const std::filesystem::path& p) {
    summary.products.push_back({kind, p, sha256_file(p)});
  };
  volume.write(out_dir / "surface.vdb", site_origin, frame.crs);
  record("surface", out_dir / "surface.vdb");
  fault::point("process.dense.surface_written");
  write_ply(out_dir / "mesh.ply", mesh, frame);
  record("mesh", out_dir / "mesh.ply");
  fault::point("process.dense.mesh_written");
  if (options.mesh.write_obj) {
    write_obj(out_dir / "mesh.obj", mesh, frame);
    record("mesh_obj", out_dir / "mesh.obj");
  }
  write_ply(out_dir / "points.ply", points, frame);
  record("points", out_dir / "points.ply");
  fault::point("process.dense.points_written");
  summary.writing = figures(sw);

  // ---- 8. quality: completeness over the area, distance to the sparse points ---------
  std::vector<Eigen::Vector2d> area = options.quality.area;
  if (area.empty()) {
    std::vector<Eigen::Vector2d> xy;
    for (const auto& p : rec.points) xy.push_back(p.X.head<2>());
    area = convex_hull(std::move(xy));
  }
  if (area.size() >= 3) {
    Eigen::Vector2d lo = area[0], hi = area[0];
    for (const auto& p : area) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    const double cell = options.quality.cell_size_m;
    const int nx = std::max(1, static_cast<int>(std::ceil((hi.x() - lo.x()) / cell)));
    const int ny = std::max(1, static_cast<int>(std::ceil((hi.y() - lo.y()) / cell)));
    const HeightField hf = volume.top_surface(lo.x() + 0.5 * cell, lo.y() + 0.5 * cell, cell, nx, ny);
    std::size_t inside = 0, covered = 0;
    for (int j = 0; j < ny; ++j) {
      for (int i = 0; i < nx; ++i) {
        if (!inside_polygon(area, {hf.x0 + i * cell, hf.y0 + j * cell})) continue;
        ++inside;
        if (std::isfinite(hf.at(i, j))) ++covered;
      }
    }
    summary.area_m2 = static_cast<double>(inside) * cell * cell;
    summary.completeness = inside > 0 ? static_cast<double>(covered) / inside : 0;
  }
  std::vector<Eigen::Vector3d> sparse;
  for (const auto& p : rec.points) sparse.push_back(p.X);
  std::vector<double> dist;
  for (double d : volume.distances(sparse)) if (std::isfinite(d)) dist.push_back(d);
  summary.sparse_points_compared = dist.size();
  summary.median_distance_sparse_m = percentile(dist, 0.5);
  summary.p95_distance_sparse_m = percentile(dist, 0.95);

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
