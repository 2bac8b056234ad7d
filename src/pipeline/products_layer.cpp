#include "pipeline/products_layer.hpp"

#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/staged_files.hpp"
#include "core/hash.hpp"
#include "core/log.hpp"
#include "core/progress.hpp"
#include "core/resources.hpp"
#include "core/statistics.hpp"
#include "crs/crs.hpp"
#include "exporters/raster/gpkg_raster.hpp"
#include "pipeline/alignment_store.hpp"
#include "pipeline/dense_layer.hpp"
#include "pipeline/stage_json.hpp"
#include "project/records.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <tuple>

namespace fs = std::filesystem;

namespace strata {

void ProductsOptions::validate() const {
  dtm.validate();
  ortho.validate();
  contours.validate();
  if (check_ortho_markers) ortho_markers.validate();
  if (!(ortho_cell_m >= 0)) {
    throw InputError(fmt::format("products: ortho_cell_m must be >= 0 metres (0 = DTM cell), got {}", ortho_cell_m));
  }
  if (!(min_footprint_area_m2 >= 0)) {
    throw InputError(fmt::format("products: min_footprint_area_m2 must be >= 0, got {}", min_footprint_area_m2));
  }
}

fs::path layer_surface_path(Project& project, const std::string& layer_name) {
  const LayerRecord layer = require_layer(project.db(), layer_name);
  const auto surface = find_product(project.db(), layer.id, "surface");
  if (!surface || !fs::exists(project.dir() / surface->path)) {
    throw ProcessingError(fmt::format(
        "layer {} has no fused surface; run 'strata process {} --layer {} --until dense' first", layer.name,
        project.dir().string(), layer.name));
  }
  return project.dir() / surface->path;
}

std::vector<OrthoView> layer_ortho_views(Project& project, const std::string& layer_name) {
  const LayerRecord layer = require_layer(project.db(), layer_name);
  const auto a = load_alignment(project.db(), layer);
  if (!a) {
    throw ProcessingError(fmt::format("layer {} is not aligned; run 'strata process {} --layer {}' first", layer.name,
                                      project.dir().string(), layer.name));
  }
  std::vector<OrthoView> views;
  for (std::size_t i = 0; i < a->rec.images.size(); ++i) {
    const RegisteredImage& im = a->rec.images[i];
    if (!im.registered) continue;
    OrthoView v;
    v.name = a->images[i].name;
    v.camera.intrinsics = a->rec.groups.at(std::size_t(im.group)).intrinsics;
    v.camera.pose = im.pose;
    v.photo = project.dir() / a->images[i].media_path;
    views.push_back(std::move(v));
  }
  return views;
}

namespace {

// |DTM - sparse point| where a sparse point falls on a valid cell: an independent
// check of the surface against the bundle adjustment (metres).
std::pair<double, std::size_t> median_sparse_distance(const Dtm& dtm, const Reconstruction& rec) {
  std::vector<double> d;
  const RasterGrid& g = dtm.grid;
  for (const SparsePoint& p : rec.points) {
    const int c = int(std::floor((p.X.x() - g.x_min) / g.cell)), r = int(std::floor((g.y_max - p.X.y()) / g.cell));
    if (c < 0 || r < 0 || c >= g.width || r >= g.height || !dtm.valid(c, r)) continue;
    d.push_back(std::abs(double(dtm.at(c, r)) - p.X.z()));
  }
  if (d.empty()) return {0.0, 0};
  return {median_in_place(d), d.size()};
}

// The surveyed markers in the site frame.
std::vector<SurveyedMarker> surveyed_markers(Database& db, const Eigen::Vector3d& origin) {
  std::vector<SurveyedMarker> out;
  for (const MarkerRecord& m : list_markers(db)) out.push_back({m.name, m.position - origin, m.kind});
  return out;
}

OrthoMarkerCheckFigures marker_check_figures(const OrthoMarkerCheck& c, const Eigen::Vector3d& origin) {
  OrthoMarkerCheckFigures f{c.cell_m,   c.tolerance_px, c.markers.size(), c.detected,     c.over_tolerance,
                            c.max_px,   c.rmse_px,      1000 * c.max_m,   1000 * c.rmse_m, c.unknown_ids, {}};
  for (const OrthoMarkerOffset& m : c.markers) {
    OrthoMarkerFigures k;
    k.marker = m.name;
    k.role = m.kind;
    k.status = m.status;
    if (std::isfinite(m.source_pixel_m)) k.source_pixel_mm = 1000 * m.source_pixel_m;
    k.e_m = m.detected.x() + origin.x();  // site CRS: where the orthophoto shows it
    k.n_m = m.detected.y() + origin.y();
    k.de_mm = 1000 * m.de_m;
    k.dn_mm = 1000 * m.dn_m;
    k.offset_mm = 1000 * m.offset_m;
    k.offset_px = m.offset_px;
    k.within_tolerance = m.offset_px <= c.tolerance_px;
    k.detections = m.detections;
    k.scales = m.scales;
    f.markers.push_back(k);
  }
  return f;
}

StepFigures step_figures(const Stopwatch& w) { return {w.seconds(), std::int64_t(peak_memory_bytes())}; }

// What a products run reads and writes, and where.
struct ProductsRun {
  Project& project;
  const ProductsOptions& options;
  LayerRecord layer;
  SiteInfo site;
  fs::path vdb;
  std::optional<StoredAlignment> alignment;  // none: a layer of range scans alone
  std::vector<SurveyedMarker> surveyed;
  RasterGeoreference geo;
  std::string rel_dir;                       // products/<layer>, relative to the project
  fs::path out_dir;
  bool photos() const { return alignment.has_value(); }
};

// The surface, the photos' poses, the survey (a corrected survey re-runs the
// orthophoto's marker check) and every option. Version: orthophoto 3, marker check 6.
std::string products_key(Database& db, const ProductsRun& run) {
  const auto surface = find_product(db, run.layer.id, "surface");
  CacheKey key("products v3.6");
  key.add(surface->sha256).add(run.alignment ? run.alignment->inputs_key : std::string("no photos")).add(run.options);
  for (const SurveyedMarker& m : run.surveyed) key.add(m);
  return key.hex();
}

std::optional<ProductsQuality> up_to_date_products(const ProductsRun& run, const std::string& inputs_key) {
  Database& db = run.project.db();
  const auto stored = load_stage_record(db, run.layer.id, "products");
  const auto dtm_rec = find_product(db, run.layer.id, "dtm");
  if (stored && stored->inputs_key == inputs_key && dtm_rec && fs::exists(run.project.dir() / dtm_rec->path)) {
    return products_quality_from_json(stored->quality);
  }
  return std::nullopt;
}

// The DTM, and its per-cell height uncertainty (one sigma, metres) beside it from
// the agreement of the fused depth maps; read by `strata volume` and the report.
Dtm make_dtm(const ProductsRun& run, StagedFiles& staged, ProductsQuality& q) {
  Stopwatch w;
  const Dtm dtm = build_dtm(run.vdb, run.options.dtm);
  const DtmStatistics stats = dtm_statistics(dtm, run.site.origin.z());
  if (stats.valid_cells == 0) throw ProcessingError(fmt::format("layer {}: the surface gives an empty DTM", run.layer.name));
  write_dtm_geotiff(staged.add(run.out_dir / "dtm.tif"), dtm, run.geo, run.options.geotiff);
  fault::point("process.products.dtm_written");
  q.dtm = {run.rel_dir + "/dtm.tif", dtm.grid.cell, dtm.grid.width, dtm.grid.height, stats.valid_cells,
           stats.area_m2, stats.min, stats.max, stats.mean, 0.0, 0, std::nullopt};
  if (!dtm.sigma.empty()) {
    Dtm sigma{dtm.grid, dtm.sigma, {}};
    RasterGeoreference sigma_geo = run.geo;
    sigma_geo.origin.z() = 0;  // metres of uncertainty, not heights
    write_dtm_geotiff(staged.add(run.out_dir / "dtm_sigma.tif"), sigma, sigma_geo, run.options.geotiff);
    fault::point("process.products.sigma_written");
    std::vector<float> v;
    for (float x : dtm.sigma)
      if (std::isfinite(x)) v.push_back(x);
    if (!v.empty()) {
      const float p50 = median_in_place(v);
      const float p95 = kth_smallest(v, std::min(v.size() - 1, std::size_t(0.95 * double(v.size()))));
      q.dtm.sigma = DtmSigmaFigures{run.rel_dir + "/dtm_sigma.tif", p50, p95};
    }
  }
  q.steps.dtm = step_figures(w);
  if (run.photos()) {
    std::tie(q.dtm.median_distance_sparse_m, q.dtm.sparse_points_compared) =
        median_sparse_distance(dtm, run.alignment->rec);
  }
  check_cancelled();
  return dtm;
}

// The true orthophoto, on its own cell when one is asked for.
RgbaRaster make_orthophoto(const ProductsRun& run, const Dtm& dtm, StagedFiles& staged, OrthoSummary& os,
                           ProductsQuality& q) {
  Stopwatch w;
  const ProductsOptions& options = run.options;
  Dtm ortho_dtm;
  if (options.ortho_cell_m > 0 && std::abs(options.ortho_cell_m - options.dtm.cell_m) > 1e-12) {
    DtmOptions o = options.dtm;
    o.cell_m = options.ortho_cell_m;
    ortho_dtm = build_dtm(run.vdb, o);
  }
  const std::vector<OrthoView> views = layer_ortho_views(run.project, run.layer.name);
  RgbaRaster ortho;
  try {
    ortho = build_orthophoto(ortho_dtm.z.empty() ? dtm : ortho_dtm, views, options.ortho, &os);
  } catch (const ProcessingError& e) {
    if (run.alignment->rec.georeferenced) throw;
    // In an arbitrary frame "up" is arbitrary too: the DTM may be seen edge-on or
    // from below, and then no photo sees it. Say why rather than only that.
    throw ProcessingError(fmt::format("{}; layer {} is not georeferenced (no surveyed marker is seen in its "
                                      "photos), so its DTM is made along an arbitrary axis: click or detect "
                                      "3 control markers and process again",
                                      e.what(), run.layer.name));
  }
  write_rgba_geotiff(staged.add(run.out_dir / "ortho.tif"), ortho, run.geo, options.geotiff);
  fault::point("process.products.ortho_written");
  q.steps.ortho = step_figures(w);
  OrthoFigures f{run.rel_dir + "/ortho.tif", ortho.grid.cell, os.views, os.views_used, os.coverage,
                 os.seam_fraction, os.balance_rms_before, os.balance_rms_after, 1.0, 1.0};
  for (const auto& g : os.gains) {
    for (double v : g) {
      f.gain_min = std::min(f.gain_min, v);
      f.gain_max = std::max(f.gain_max, v);
    }
  }
  q.ortho = f;
  check_cancelled();
  return ortho;
}

// The orthophoto against the surveyed markers.
void check_markers_in_orthophoto(const ProductsRun& run, const RgbaRaster& ortho, OrthoSummary& os,
                                 ProductsQuality& q) {
  Stopwatch w;
  const auto& options = run.options.ortho_markers;
  const OrthoMarkerCheck check = check_ortho_markers(ortho, run.surveyed, options, &os.source_pixel_m);
  q.steps.ortho_markers = step_figures(w);
  for (const OrthoMarkerOffset& m : check.markers) {
    if (m.status == OrthoMarkerStatus::detected && m.offset_px > options.tolerance_px) {
      log::warn("layer {}: marker {} is {:.1f} px ({:.0f} mm) from its surveyed position in the orthophoto "
                "(dE {:+.0f} mm, dN {:+.0f} mm; tolerance {} px)",
                run.layer.name, m.name, m.offset_px, 1000 * m.offset_m, 1000 * m.de_m, 1000 * m.dn_m,
                options.tolerance_px);
    }
  }
  if (!run.surveyed.empty() && check.detected == 0) {
    log::warn("layer {}: no surveyed marker was found in the orthophoto; its position is not checked",
              run.layer.name);
  }
  q.ortho_markers = marker_check_figures(check, run.site.origin);
  check_cancelled();
}

// Raster tables through GDAL's own connection, with no strata transaction open;
// before the records, so that a run killed while GDAL writes them is not taken
// as complete (the next run replaces the tables).
void write_raster_tables(const ProductsRun& run, ProductsQuality& q) {
  Stopwatch g;
  const fs::path gpkg = run.project.database_path();
  const std::string& name = run.layer.name;
  write_gpkg_raster(gpkg, run.out_dir / "dtm.tif", raster_table_name("dtm", name), GpkgRasterKind::gridded_coverage,
                    fmt::format("DTM of layer {} (metres, {})", name, run.site.crs));
  fault::point("process.products.gpkg_dtm_written");
  if (run.photos()) {
    write_gpkg_raster(gpkg, run.out_dir / "ortho.tif", raster_table_name("ortho", name), GpkgRasterKind::tiles_png,
                      fmt::format("true orthophoto of layer {}", name));
  }
  fault::point("process.products.gpkg_ortho_written");
  q.steps.gpkg_rasters = step_figures(g);
}

// The quality, the product files and the site-plan vectors, in one transaction.
void record_products(const ProductsRun& run, const std::string& inputs_key, const ProductsQuality& q,
                     const std::vector<ContourLine>& contours, const Footprint& footprint) {
  Database& db = run.project.db();
  Transaction tx(db);
  db.prepare(
        "INSERT INTO reconstructions(layer_id, stage, created_at, inputs_key, georeferenced, quality_json) "
        "VALUES (?, 'products', strftime('%Y-%m-%dT%H:%M:%SZ','now'), ?, ?, ?)")
      .bind_all(run.layer.id, inputs_key, !run.photos() || run.alignment->rec.georeferenced ? 1 : 0,
                to_json(q).dump())
      .run();
  std::vector<std::pair<std::string, nlohmann::json>> files = {
      {"dtm", {{"cell_m", q.dtm.cell_m}, {"nodata", kDtmNoData}}}};
  if (q.ortho) files.push_back({"ortho", {{"cell_m", q.ortho->cell_m}}});
  if (q.dtm.sigma) files.push_back({"dtm_sigma", {{"cell_m", q.dtm.cell_m}, {"nodata", kDtmNoData}}});
  for (const auto& [kind, params] : files) {
    ProductRecord r;
    r.layer_id = run.layer.id;
    r.kind = kind;
    r.path = run.rel_dir + "/" + kind + ".tif";
    r.params_json = params.dump();
    record_product(db, run.project.dir(), r);
    fault::point("process.products.product_recorded");
  }
  store_site_plan(db, run.site.srs_id, run.layer.name, run.options.contours.interval_m, contours, footprint);
  register_site_plan_views(db, run.site.srs_id);
  fault::point("process.products.before_commit");
  tx.commit();
  fault::point("process.products.after_commit");
}

}  // namespace

ProductsLayerResult products_layer(Project& project, const std::string& layer_name, const ProductsOptions& options,
                                   bool force) {
  options.validate();
  auto& db = project.db();
  const LayerRecord layer = require_layer(db, layer_name);
  const SiteInfo site = project.site();
  // A layer recorded by range scans alone has a surface but no photos: its DTM,
  // contours and footprint are made; the orthophoto and its marker check need photos.
  ProductsRun run{project, options, layer, site, layer_surface_path(project, layer.name), load_alignment(db, layer),
                  surveyed_markers(db, site.origin), RasterGeoreference{describe_crs(site.crs).wkt, site.origin},
                  layer_product_dir(layer.name), {}};
  run.out_dir = project.dir() / run.rel_dir;
  const std::string inputs_key = products_key(db, run);
  if (!force) {
    if (auto stored = up_to_date_products(run, inputs_key)) return {true, *stored};
  }

  Stopwatch total;
  fs::create_directories(run.out_dir);
  // The new files are written beside the old ones under staged names; a stage that
  // fails (a full disk, a bad option) removes them and leaves the project as it was.
  // Once every file is complete, the old records go (committed), the staged files
  // take the final names, and the new records are committed: whenever the process
  // dies, no record names a file that is not the one it describes.
  StagedFiles staged("products");
  ProductsQuality q;
  q.layer = layer.name;
  const Dtm dtm = make_dtm(run, staged, q);
  OrthoSummary os;
  if (run.photos()) {
    const RgbaRaster ortho = make_orthophoto(run, dtm, staged, os, q);
    if (options.check_ortho_markers) check_markers_in_orthophoto(run, ortho, os, q);
  } else {
    log::info("layer {}: no photos, so no orthophoto (the DTM comes from its scans)", layer.name);
  }

  Stopwatch w;
  const std::vector<ContourLine> contours = dtm_contours(dtm, site.origin, options.contours);
  const Footprint footprint = dtm_footprint(dtm, site.origin, options.min_footprint_area_m2);
  q.steps.vectors = step_figures(w);
  fault::point("process.products.vectors_done");
  q.contours = {options.contours.interval_m, contours.size()};
  q.footprint = {footprint.area_m2, footprint.perimeter_m, footprint.polygons.size()};

  {
    Transaction tx(db);
    db.prepare("DELETE FROM reconstructions WHERE layer_id = ? AND stage = 'products'").bind_all(layer.id).run();
    db.prepare("DELETE FROM products WHERE layer_id = ? AND kind IN ('dtm', 'ortho', 'dtm_sigma')")
        .bind_all(layer.id)
        .run();
    tx.commit();
  }
  fault::point("process.products.records_retracted");
  staged.swap_in();
  if (options.gpkg_rasters) write_raster_tables(run, q);
  q.steps.total = step_figures(total);
  record_products(run, inputs_key, q, contours, footprint);
  log::info("layer {}: DTM {} x {} at {} m, orthophoto coverage {:.1f} %, {} contour lines", layer.name,
            dtm.grid.width, dtm.grid.height, dtm.grid.cell, 100 * os.coverage, contours.size());
  return {false, q};
}

}  // namespace strata
