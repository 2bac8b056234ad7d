#include "pipeline/dense_layer.hpp"

#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/hash.hpp"
#include "core/log.hpp"
#include "core/progress.hpp"
#include "core/statistics.hpp"
#include "core/temporaries.hpp"
#include "pipeline/alignment_store.hpp"
#include "pipeline/layer_scans.hpp"
#include "pipeline/stage_json.hpp"
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
  auto q = [](std::vector<double>& v, double f) { return kth_smallest(v, std::size_t(f * double(v.size() - 1))); };
  const double x0 = q(xs, 0.05), x1 = q(xs, 0.95), y0 = q(ys, 0.05), y1 = q(ys, 0.95);
  return {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
}

void warn_unregistered_scans(const LayerRecord& layer, const LayerScans& scans) {
  for (const auto& seq : scans.unregistered_depth)
    log::warn("layer {}: depth sequence '{}' has frames not registered, not fused (register them with 'strata "
              "register depth')",
              layer.name, seq);
  if (scans.unregistered.empty()) return;
  std::string names;
  for (const auto& n : scans.unregistered) names += (names.empty() ? "" : ", ") + n;
  log::warn("layer {}: {} unregistered scan(s) not fused: {} (register them with 'strata register scan' "
            "against the layer's photo surface, or import them again with --crs or --transform)",
            layer.name, scans.unregistered.size(), names);
}

// The area whose completeness is reported: the option's, else the sparse points',
// else (no photos) the box the scans cover.
std::vector<Eigen::Vector2d> completeness_area(const DenseOptions& options, const Reconstruction& rec,
                                               const LayerScans& scans) {
  if (!options.quality.area.empty()) return options.quality.area;
  std::vector<Eigen::Vector2d> area = sparse_area(rec);
  if (area.empty() && scans.bounds) {
    const Eigen::Vector3d& lo = scans.bounds->min;
    const Eigen::Vector3d& hi = scans.bounds->max;
    area = {{lo.x(), lo.y()}, {hi.x(), lo.y()}, {hi.x(), hi.y()}, {lo.x(), hi.y()}};
  }
  return area;
}

// Write into a fresh temporary folder; a failed or interrupted run removes it and
// leaves the previous products as they were.
DenseSummary run_dense_into(const fs::path& tmp_dir, const DenseOptions& options, const Reconstruction& rec,
                            const std::vector<fs::path>& photos, const LayerScans& scans, const SiteInfo& site,
                            const fs::path& cache) {
  fs::remove_all(tmp_dir);
  fs::create_directories(tmp_dir);
  try {
    return run_dense(options, rec, photos, scans.registered, site.origin, cache, tmp_dir);
  } catch (...) {
    std::error_code ec;
    fs::remove_all(tmp_dir, ec);
    throw;
  }
}

// The files are replaced in three steps, so that no record ever names a file that
// is not the one it describes, whenever the process dies: the previous surface's
// records go first (committed), then the folders are swapped, then the new
// records are committed. A crash in between costs the record of the previous
// surface, which the next run recomputes (from the depth-map cache).
void swap_in_dense(Project& project, const LayerRecord& layer, const fs::path& tmp_dir, const DenseQuality& q,
                   const std::string& inputs_key, bool georeferenced) {
  auto& db = project.db();
  const fs::path rel = fs::path(layer_product_dir(layer.name)) / "dense";
  const fs::path final_dir = project.dir() / rel;
  const std::string rel_dense = rel.string() + "/";
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
        .bind_all(layer.id, inputs_key, georeferenced ? 1 : 0, to_json(q).dump())
        .run();
    for (const auto& p : q.figures.products) {
      ProductRecord r;
      r.layer_id = layer.id;
      r.kind = p.kind;
      r.path = (rel / p.path.filename()).string();
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
  warn_unregistered_scans(layer, scans);
  if (!alignment && scans.registered.empty()) {
    throw ProcessingError(fmt::format("layer {} is not aligned and has no registered scan or depth frame; run "
                                      "'strata process --layer {} --until sparse' first",
                                      layer.name, layer.name));
  }
  // The alignment, the scans and every option (a changed option recomputes; the
  // depth-map cache below still reuses what did not change). Version 3: the fused
  // volume holds the observations' spread (per-cell height uncertainty). Version 4:
  // scans' and depth frames' colours fused; without photos, the voxel no finer than
  // the scans' point noise.
  const std::string inputs_key = CacheKey("dense v4")
                                     .add(alignment ? alignment->inputs_key : std::string("no photos"))
                                     .add(scans.key)
                                     .add(options)
                                     .hex();
  if (!force) {
    const auto stored = load_stage_record(db, layer.id, "dense");
    const auto surface = find_product(db, layer.id, "surface");
    if (stored && stored->inputs_key == inputs_key && surface && fs::exists(project.dir() / surface->path)) {
      return {true, dense_quality_from_json(stored->quality)};
    }
  }

  const Reconstruction no_photos;
  const Reconstruction& rec = alignment ? alignment->rec : no_photos;
  std::vector<fs::path> photos;
  if (alignment)
    for (const auto& im : alignment->images) photos.push_back(project.dir() / im.media_path);
  DenseOptions o = options;
  o.quality.area = completeness_area(options, rec, scans);
  const fs::path tmp_dir = project.dir() / layer_product_dir(layer.name) / "dense.tmp";
  const Temporary held(tmp_dir);  // until it is swapped in (renamed), for a stop that cannot wait
  DenseQuality q{layer.name, alignment.has_value(), scans.unregistered,
                 run_dense_into(tmp_dir, o, rec, photos, scans, project.site(),
                                project.cache_dir() / "layers" / layer.name)};
  swap_in_dense(project, layer, tmp_dir, q, inputs_key, !alignment || alignment->rec.georeferenced);
  return {false, q};
}

}  // namespace strata
