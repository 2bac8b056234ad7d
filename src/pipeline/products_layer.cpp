#include "pipeline/products_layer.hpp"

#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/staged_files.hpp"
#include "core/hash.hpp"
#include "core/log.hpp"
#include "core/progress.hpp"
#include "core/resources.hpp"
#include "crs/crs.hpp"
#include "pipeline/alignment_store.hpp"
#include "pipeline/dense_layer.hpp"
#include "project/records.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <optional>

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
  std::nth_element(d.begin(), d.begin() + std::ptrdiff_t(d.size() / 2), d.end());
  return {d[d.size() / 2], d.size()};
}

// The surveyed markers in the site frame.
std::vector<SurveyedMarker> surveyed_markers(Database& db, const Eigen::Vector3d& origin) {
  std::vector<SurveyedMarker> out;
  for (const MarkerRecord& m : list_markers(db)) out.push_back({m.name, m.position - origin, m.kind});
  return out;
}

nlohmann::json marker_check_json(const OrthoMarkerCheck& c, const Eigen::Vector3d& origin) {
  nlohmann::json markers = nlohmann::json::array();
  for (const OrthoMarkerOffset& m : c.markers) {
    nlohmann::json j = {{"marker", m.name}, {"role", m.kind}, {"status", to_string(m.status)}};
    if (std::isfinite(m.source_pixel_m)) j["source_pixel_mm"] = 1000 * m.source_pixel_m;
    if (m.status == OrthoMarkerStatus::detected) {
      j["E"] = m.detected.x() + origin.x();  // metres, site CRS: where the orthophoto shows it
      j["N"] = m.detected.y() + origin.y();
      j["dE_mm"] = 1000 * m.de_m;
      j["dN_mm"] = 1000 * m.dn_m;
      j["offset_mm"] = 1000 * m.offset_m;
      j["offset_px"] = m.offset_px;
      j["within_tolerance"] = m.offset_px <= c.tolerance_px;
      j["detections"] = m.detections;
      j["scales"] = m.scales;
    }
    markers.push_back(std::move(j));
  }
  return {{"cell_m", c.cell_m},
          {"tolerance_px", c.tolerance_px},
          {"surveyed", c.markers.size()},
          {"detected", c.detected},
          {"over_tolerance", c.over_tolerance},
          {"max_px", c.max_px},
          {"rmse_px", c.rmse_px},
          {"max_mm", 1000 * c.max_m},
          {"rmse_mm", 1000 * c.rmse_m},
          {"unknown_target_ids", c.unknown_ids},
          {"markers", markers}};
}

nlohmann::json step_json(const Stopwatch& w) {
  return {{"seconds", w.seconds()}, {"peak_memory_mb", double(peak_memory_bytes()) / 1048576.0}};
}

}  // namespace

ProductsLayerResult products_layer(Project& project, const std::string& layer_name, const ProductsOptions& options,
                                   bool force) {
  options.validate();
  auto& db = project.db();
  const LayerRecord layer = require_layer(db, layer_name);
  const fs::path vdb = layer_surface_path(project, layer.name);
  // A layer recorded by range scans alone has a surface but no photos: its DTM,
  // contours and footprint are made; the orthophoto and its marker check need photos.
  const auto alignment = load_alignment(db, layer);
  const SiteInfo site = project.site();
  const auto surface = find_product(db, layer.id, "surface");
  const std::vector<SurveyedMarker> surveyed = surveyed_markers(db, site.origin);

  // The surface, the photos' poses, the survey (a corrected survey re-runs the
  // orthophoto's marker check) and every option. Version: orthophoto 3, marker check 6.
  CacheKey key("products v3.6");
  key.add(surface->sha256).add(alignment ? alignment->inputs_key : std::string("no photos")).add(options);
  for (const SurveyedMarker& m : surveyed) key.add(m);
  const std::string inputs_key = key.hex();
  ProductsLayerResult result;
  if (!force) {
    auto st = db.prepare("SELECT inputs_key, quality_json FROM reconstructions WHERE layer_id = ? AND stage = 'products'");
    st.bind(1, layer.id);
    const auto dtm_rec = find_product(db, layer.id, "dtm");
    if (st.step() && st.get_text(0) == inputs_key && dtm_rec && fs::exists(project.dir() / dtm_rec->path)) {
      result.skipped = true;
      result.quality = nlohmann::json::parse(st.get_text(1));
      return result;
    }
  }

  Stopwatch total;
  nlohmann::json steps;
  const RasterGeoreference geo{describe_crs(site.crs).wkt, site.origin};
  const std::string rel_dir = layer_product_dir(layer.name);
  const fs::path out_dir = project.dir() / rel_dir;
  fs::create_directories(out_dir);
  // The new files are written beside the old ones under staged names; a stage that
  // fails (a full disk, a bad option) removes them and leaves the project as it was.
  // Once every file is complete, the old records go (committed), the staged files
  // take the final names, and the new records are committed: whenever the process
  // dies, no record names a file that is not the one it describes.
  StagedFiles staged("products");
  const auto stage_path = [&](const std::string& file) { return staged.add(out_dir / file); };

  // DTM
  Stopwatch w;
  const Dtm dtm = build_dtm(vdb, options.dtm);
  const DtmStatistics stats = dtm_statistics(dtm, site.origin.z());
  if (stats.valid_cells == 0) throw ProcessingError(fmt::format("layer {}: the surface gives an empty DTM", layer.name));
  write_dtm_geotiff(stage_path("dtm.tif"), dtm, geo, options.geotiff);
  fault::point("process.products.dtm_written");
  // Its per-cell height uncertainty (one sigma, metres) beside it, from the
  // agreement of the fused depth maps; read by `strata volume` and the report.
  nlohmann::json sigma_q;
  if (!dtm.sigma.empty()) {
    Dtm sigma{dtm.grid, dtm.sigma, {}};
    RasterGeoreference sigma_geo = geo;
    sigma_geo.origin.z() = 0;  // metres of uncertainty, not heights
    write_dtm_geotiff(stage_path("dtm_sigma.tif"), sigma, sigma_geo, options.geotiff);
    fault::point("process.products.sigma_written");
    std::vector<float> v;
    for (float x : dtm.sigma)
      if (std::isfinite(x)) v.push_back(x);
    if (!v.empty()) {
      std::sort(v.begin(), v.end());
      sigma_q = {{"path", rel_dir + "/dtm_sigma.tif"},
                 {"median_m", v[v.size() / 2]},
                 {"p95_m", v[std::min(v.size() - 1, std::size_t(0.95 * double(v.size())))]}};
    }
  }
  steps["dtm"] = step_json(w);
  check_cancelled();

  // True orthophoto
  w = Stopwatch();
  const bool photos = alignment.has_value();
  if (!photos) log::info("layer {}: no photos, so no orthophoto (the DTM comes from its scans)", layer.name);
  Dtm ortho_dtm;
  if (photos && options.ortho_cell_m > 0 && std::abs(options.ortho_cell_m - options.dtm.cell_m) > 1e-12) {
    DtmOptions o = options.dtm;
    o.cell_m = options.ortho_cell_m;
    ortho_dtm = build_dtm(vdb, o);
  }
  const std::vector<OrthoView> views = photos ? layer_ortho_views(project, layer.name) : std::vector<OrthoView>{};
  OrthoSummary os;
  const RgbaRaster ortho = [&] {
    if (!photos) return RgbaRaster{};
    try {
      return build_orthophoto(ortho_dtm.z.empty() ? dtm : ortho_dtm, views, options.ortho, &os);
    } catch (const ProcessingError& e) {
      if (alignment->rec.georeferenced) throw;
      // In an arbitrary frame "up" is arbitrary too: the DTM may be seen edge-on or
      // from below, and then no photo sees it. Say why rather than only that.
      throw ProcessingError(fmt::format("{}; layer {} is not georeferenced (no surveyed marker is seen in its "
                                        "photos), so its DTM is made along an arbitrary axis: click or detect "
                                        "3 control markers and process again",
                                        e.what(), layer.name));
    }
  }();
  if (photos) {
    write_rgba_geotiff(stage_path("ortho.tif"), ortho, geo, options.geotiff);
    fault::point("process.products.ortho_written");
    steps["ortho"] = step_json(w);
  }
  check_cancelled();

  // The orthophoto against the surveyed markers
  std::optional<OrthoMarkerCheck> marker_check;
  if (photos && options.check_ortho_markers) {
    w = Stopwatch();
    marker_check = check_ortho_markers(ortho, surveyed, options.ortho_markers, &os.source_pixel_m);
    steps["ortho_markers"] = step_json(w);
    for (const OrthoMarkerOffset& m : marker_check->markers) {
      if (m.status == OrthoMarkerStatus::detected && m.offset_px > options.ortho_markers.tolerance_px) {
        log::warn("layer {}: marker {} is {:.1f} px ({:.0f} mm) from its surveyed position in the orthophoto "
                  "(dE {:+.0f} mm, dN {:+.0f} mm; tolerance {} px)",
                  layer.name, m.name, m.offset_px, 1000 * m.offset_m, 1000 * m.de_m, 1000 * m.dn_m,
                  options.ortho_markers.tolerance_px);
      }
    }
    if (!surveyed.empty() && marker_check->detected == 0) {
      log::warn("layer {}: no surveyed marker was found in the orthophoto; its position is not checked",
                layer.name);
    }
    check_cancelled();
  }

  // Site-plan vectors
  w = Stopwatch();
  const std::vector<ContourLine> contours = dtm_contours(dtm, site.origin, options.contours);
  const Footprint footprint = dtm_footprint(dtm, site.origin, options.min_footprint_area_m2);
  steps["vectors"] = step_json(w);
  fault::point("process.products.vectors_done");

  const auto [sparse_median, sparse_n] =
      photos ? median_sparse_distance(dtm, alignment->rec) : std::pair<double, std::size_t>{0.0, 0};
  double gain_min = 1, gain_max = 1;
  for (const auto& g : os.gains) {
    for (double v : g) {
      gain_min = std::min(gain_min, v);
      gain_max = std::max(gain_max, v);
    }
  }
  nlohmann::json q;
  q["layer"] = layer.name;
  q["dtm"] = {{"path", rel_dir + "/dtm.tif"},     {"cell_m", dtm.grid.cell},       {"width", dtm.grid.width},
              {"height", dtm.grid.height},        {"valid_cells", stats.valid_cells}, {"area_m2", stats.area_m2},
              {"min_m", stats.min},               {"max_m", stats.max},            {"mean_m", stats.mean},
              {"median_distance_sparse_m", sparse_median}, {"sparse_points_compared", sparse_n}};
  if (!sigma_q.is_null()) q["dtm"]["sigma"] = sigma_q;
  if (photos) {
    q["ortho"] = {{"path", rel_dir + "/ortho.tif"},  {"cell_m", ortho.grid.cell},     {"views", os.views},
                  {"views_used", os.views_used},     {"coverage", os.coverage},       {"seam_fraction", os.seam_fraction},
                  {"balance_rms_before", os.balance_rms_before}, {"balance_rms_after", os.balance_rms_after},
                  {"gain_min", gain_min},            {"gain_max", gain_max}};
  } else {
    q["ortho"] = nullptr;  // an orthophoto drapes photos on the surface: none without photos
  }
  if (marker_check) q["ortho_markers"] = marker_check_json(*marker_check, site.origin);
  q["contours"] = {{"interval_m", options.contours.interval_m}, {"lines", contours.size()}};
  q["footprint"] = {{"area_m2", footprint.area_m2}, {"perimeter_m", footprint.perimeter_m},
                    {"polygons", footprint.polygons.size()}};

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

  // Raster tables through GDAL's own connection, with no strata transaction open;
  // before the records, so that a run killed while GDAL writes them is not taken
  // as complete (the next run replaces the tables).
  if (options.gpkg_rasters) {
    Stopwatch g;
    write_gpkg_raster(project.database_path(), out_dir / "dtm.tif", raster_table_name("dtm", layer.name),
                      GpkgRasterKind::gridded_coverage, fmt::format("DTM of layer {} (metres, {})", layer.name, site.crs));
    fault::point("process.products.gpkg_dtm_written");
    if (photos)
      write_gpkg_raster(project.database_path(), out_dir / "ortho.tif", raster_table_name("ortho", layer.name),
                        GpkgRasterKind::tiles_png, fmt::format("true orthophoto of layer {}", layer.name));
    fault::point("process.products.gpkg_ortho_written");
    steps["gpkg_rasters"] = step_json(g);
  }

  // Record everything in one transaction.
  {
    Transaction tx(db);
    steps["total"] = step_json(total);
    q["steps"] = steps;
    db.prepare(
          "INSERT INTO reconstructions(layer_id, stage, created_at, inputs_key, georeferenced, quality_json) "
          "VALUES (?, 'products', strftime('%Y-%m-%dT%H:%M:%SZ','now'), ?, ?, ?)")
        .bind_all(layer.id, inputs_key, !photos || alignment->rec.georeferenced ? 1 : 0, q.dump())
        .run();
    for (const auto& [kind, file, params] :
         {std::tuple{"dtm", "dtm.tif", nlohmann::json{{"cell_m", dtm.grid.cell}, {"nodata", kDtmNoData}}},
          std::tuple{"ortho", "ortho.tif", nlohmann::json{{"cell_m", ortho.grid.cell}}},
          std::tuple{"dtm_sigma", "dtm_sigma.tif", nlohmann::json{{"cell_m", dtm.grid.cell}, {"nodata", kDtmNoData}}}}) {
      if (std::string(kind) == "dtm_sigma" && sigma_q.is_null()) continue;
      if (std::string(kind) == "ortho" && !photos) continue;
      ProductRecord r;
      r.layer_id = layer.id;
      r.kind = kind;
      r.path = rel_dir + "/" + file;
      r.params_json = params.dump();
      record_product(db, project.dir(), r);
      fault::point("process.products.product_recorded");
    }
    store_site_plan(db, site.srs_id, layer.name, options.contours.interval_m, contours, footprint);
    register_site_plan_views(db, site.srs_id);
    fault::point("process.products.before_commit");
    tx.commit();
    fault::point("process.products.after_commit");
  }
  log::info("layer {}: DTM {} x {} at {} m, orthophoto coverage {:.1f} %, {} contour lines", layer.name,
            dtm.grid.width, dtm.grid.height, dtm.grid.cell, 100 * os.coverage, contours.size());
  result.quality = q;
  return result;
}

}  // namespace strata
