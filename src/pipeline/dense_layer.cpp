#include "pipeline/dense_layer.hpp"

#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/hash.hpp"
#include "core/log.hpp"
#include "core/progress.hpp"
#include "pipeline/alignment_store.hpp"
#include "pipeline/layer_scans.hpp"
#include "project/records.hpp"

#include <fmt/format.h>

#include <algorithm>

namespace fs = std::filesystem;

namespace strata {
namespace {

// The area whose completeness is reported: the XY box of the central 90 % of the
// sparse points (robust to stray points far outside the excavation).
std::vector<Eigen::Vector2d> sparse_area(const Reconstruction& rec) {
  std::vector<double> xs, ys;
  for (const auto& p : rec.points) {
    xs.push_back(p.X.x());
    ys.push_back(p.X.y());
  }
  if (xs.size() < 10) return {};
  auto q = [](std::vector<double>& v, double f) {
    const auto k = std::size_t(f * double(v.size() - 1));
    std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(k), v.end());
    return v[k];
  };
  const double x0 = q(xs, 0.05), x1 = q(xs, 0.95), y0 = q(ys, 0.05), y1 = q(ys, 0.95);
  return {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
}

}  // namespace

std::string layer_product_dir(const std::string& layer) { return "products/" + layer; }

DenseLayerResult dense_layer(Project& project, const std::string& layer_name, const DenseOptions& options,
                             bool force) {
  options.validate();
  auto& db = project.db();
  const LayerRecord layer = require_layer(db, layer_name);
  const auto alignment = load_alignment(db, layer);
  const LayerScans scans = layer_scans(project, layer);
  if (!scans.unregistered.empty()) {
    std::string names;
    for (const auto& n : scans.unregistered) names += (names.empty() ? "" : ", ") + n;
    log::warn("layer {}: {} unregistered scan(s) not fused: {} (register them with 'strata register scan' "
              "against the layer's photo surface, or import them again with --crs or --transform)",
              layer.name, scans.unregistered.size(), names);
  }
  if (!alignment && scans.registered.empty()) {
    throw ProcessingError(fmt::format("layer {} is not aligned and has no registered scan; run 'strata process "
                                      "--layer {} --until sparse' first",
                                      layer.name, layer.name));
  }
  const SiteInfo site = project.site();
  DenseOptions o = options;
  DenseLayerResult result;
  // The alignment, the scans and every option (a changed option recomputes; the
  // depth-map cache below still reuses what did not change). Version 3: the fused
  // volume holds the observations' spread (per-cell height uncertainty).
  const std::string inputs_key = CacheKey("dense v3")
                                     .add(alignment ? alignment->inputs_key : std::string("no photos"))
                                     .add(scans.key)
                                     .add(options)
                                     .hex();
  if (!force) {
    auto st = db.prepare("SELECT inputs_key, quality_json FROM reconstructions WHERE layer_id = ? AND stage = 'dense'");
    st.bind(1, layer.id);
    if (st.step() && st.get_text(0) == inputs_key && find_product(db, layer.id, "surface") &&
        fs::exists(project.dir() / find_product(db, layer.id, "surface")->path)) {
      result.skipped = true;
      result.quality = nlohmann::json::parse(st.get_text(1));
      return result;
    }
  }

  std::vector<fs::path> paths;
  const Reconstruction no_photos;
  const Reconstruction& rec = alignment ? alignment->rec : no_photos;
  if (alignment)
    for (const auto& im : alignment->images) paths.push_back(project.dir() / im.media_path);
  if (o.quality.area.empty()) o.quality.area = sparse_area(rec);
  if (o.quality.area.empty() && scans.bounds) {
    // No photos: completeness over the box the scans cover.
    const Eigen::Vector3d& lo = scans.bounds->min;
    const Eigen::Vector3d& hi = scans.bounds->max;
    o.quality.area = {{lo.x(), lo.y()}, {hi.x(), lo.y()}, {hi.x(), hi.y()}, {lo.x(), hi.y()}};
  }

  // Write into a fresh temporary folder, then swap it into place: a failed or
  // interrupted run leaves the previous products as they were.
  const fs::path final_dir = project.dir() / layer_product_dir(layer.name) / "dense";
  const fs::path tmp_dir = final_dir.string() + ".tmp";
  fs::remove_all(tmp_dir);
  fs::create_directories(tmp_dir);
  DenseSummary s;
  try {
    s = run_dense(o, rec, paths, scans.registered, site.origin, project.cache_dir() / "layers" / layer.name, tmp_dir);
  } catch (...) {
    std::error_code ec;
    fs::remove_all(tmp_dir, ec);
    throw;
  }
  nlohmann::json q;
  q["layer"] = layer.name;
  q["images_total"] = s.images_total;
  q["images_with_depth"] = s.images_with_depth;
  q["depth_scale"] = s.depth_scale;
  q["gsd_m"] = s.gsd_m;
  q["smoothing_m"] = s.smoothing_m;
  q["voxel_size_m"] = s.voxel_size_m;
  q["active_voxels"] = s.active_voxels;
  q["floating_voxels_removed"] = s.floating_voxels_removed;
  q["mesh_faces"] = s.mesh_faces;
  q["points"] = s.points;
  q["completeness"] = s.completeness;
  q["area_m2"] = s.area_m2;
  q["median_distance_sparse_m"] = s.median_distance_sparse_m;
  q["p95_distance_sparse_m"] = s.p95_distance_sparse_m;
  q["photos"] = alignment.has_value();
  q["scans_fused"] = s.scans_fused;
  q["scans_unregistered"] = scans.unregistered;
  q["scan_points"] = s.scan_points;
  q["scan_weight_share"] = s.scan_weight_share;
  q["unit_sigma_m"] = s.unit_sigma_m;
  auto step = [](const StepFigures& f) {
    return nlohmann::json{{"seconds", f.seconds}, {"peak_memory_mb", double(f.peak_memory_bytes) / 1048576.0}};
  };
  q["steps"] = {{"view_selection", step(s.view_selection)}, {"undistortion", step(s.undistortion)},
                {"depth_maps", step(s.depth_maps)},         {"filtering", step(s.filtering)},
                {"fusion", step(s.fusion)},                 {"meshing", step(s.meshing)},
                {"writing", step(s.writing)},               {"total", step(s.total)}};

  // The files are replaced in three steps, so that no record ever names a file that
  // is not the one it describes, whenever the process dies: the previous surface's
  // records go first (committed), then the folders are swapped, then the new
  // records are committed. A crash in between costs the record of the previous
  // surface, which the next run recomputes (from the depth-map cache).
  const std::string rel_dense = (fs::path(layer_product_dir(layer.name)) / "dense").string() + "/";
  {
    Transaction tx(db);
    db.prepare("DELETE FROM reconstructions WHERE layer_id = ? AND stage IN ('dense', 'products')")
        .bind_all(layer.id)
        .run();
    db.prepare("DELETE FROM products WHERE layer_id = ? AND substr(path, 1, length(?)) = ?")
        .bind_all(layer.id, rel_dense, rel_dense)
        .run();
    tx.commit();
  }
  fault::point("process.dense.records_retracted");
  const fs::path old_dir = final_dir.string() + ".old";
  fs::remove_all(old_dir);
  if (fs::exists(final_dir)) fs::rename(final_dir, old_dir);
  fault::point("process.dense.old_moved_aside");
  fs::rename(tmp_dir, final_dir);
  fault::point("process.dense.swapped");
  try {
    Transaction tx(db);
    db.prepare(
          "INSERT INTO reconstructions(layer_id, stage, created_at, inputs_key, georeferenced, quality_json) "
          "VALUES (?, 'dense', strftime('%Y-%m-%dT%H:%M:%SZ','now'), ?, ?, ?)")
        .bind_all(layer.id, inputs_key, !alignment || alignment->rec.georeferenced ? 1 : 0, q.dump())
        .run();
    for (const auto& p : s.products) {
      ProductRecord r;
      r.layer_id = layer.id;
      r.kind = p.kind;
      r.path = (fs::path(layer_product_dir(layer.name)) / "dense" / p.path.filename()).string();
      record_product(db, project.dir(), r);
    }
    fault::point("process.dense.before_commit");
    tx.commit();
    fault::point("process.dense.after_commit");
  } catch (...) {
    // Put the previous files back (no longer recorded: the next run remakes them).
    std::error_code ec;
    fs::remove_all(final_dir, ec);
    if (fs::exists(old_dir)) fs::rename(old_dir, final_dir, ec);
    throw;
  }
  fs::remove_all(old_dir);
  result.quality = q;
  return result;
}

}  // namespace strata
