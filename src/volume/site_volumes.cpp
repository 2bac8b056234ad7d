// The volume stage on a project: surfaces in, products and unit_volumes out.
#include "volume/site_volumes.hpp"

#include "core/atomic_file.hpp"
#include "core/door.hpp"
#include "core/error.hpp"
#include "core/log.hpp"
#include "core/staged_files.hpp"
#include "crs/crs.hpp"
#include "dense/dense.hpp"
#include "exporters/raster/geotiff.hpp"
#include "importers/raster/geotiff.hpp"
#include "importers/vector/outline.hpp"
#include "pipeline/stage_json.hpp"
#include "products/dtm.hpp"
#include "products/site_plan.hpp"
#include "project/gpkg.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <optional>

namespace strata {
namespace fs = std::filesystem;
namespace {

constexpr double kDefaultCell = 0.005;  // metres: a few GSDs of a 1.5 m hand-held photo
constexpr double kMadToSigma = 1.4826;  // median absolute deviation -> Gaussian sigma

// Where a layer's surface comes from, before sampling on the common grid.
struct SurfaceSource {
  LayerRecord layer;
  fs::path path;
  bool raster = false;
  std::optional<HeightRaster<double>> field;  // rasters: read at once
  fs::path sigma_path;               // rasters: per-cell height sigma beside it, if any
  double xmin = 0, ymin = 0, xmax = 0, ymax = 0;  // site frame extent
};

// Vertical georeference error of a layer: check-marker RMSE z when check points
// exist (independent), else control RMSE z; 0 when not georeferenced by markers.
double vertical_rmse(Database& db, std::int64_t layer_id) {
  const auto q = stored_alignment_quality(db, layer_id);
  const AxisRmse* rmse = q ? q->quoted_rmse() : nullptr;
  return rmse ? rmse->z : 0.0;
}

// The scale over which the layer's dense stage averaged the ground (its matching
// window on the ground); projects fused before it was recorded have the depth
// maps' GSD, and the window is the default one.
double surface_smoothing(Database& db, std::int64_t layer_id) {
  const auto q = stored_dense_quality(db, layer_id);
  if (!q) return 0;
  if (q->figures.smoothing_m > 0) return q->figures.smoothing_m;
  const double gsd = q->figures.gsd_m;
  return gsd > 0 ? PatchMatchOptions{}.smoothing_m(gsd) : 0.0;
}

double surface_noise(Database& db, std::int64_t layer_id, double fallback) {
  const auto q = stored_dense_quality(db, layer_id);
  if (!q) return fallback;
  const double median = q->figures.median_distance_sparse_m;
  return median > 0 ? kMadToSigma * median : fallback;
}

}  // namespace

std::vector<LayerRecord> capture_order(std::vector<LayerRecord> layers) {
  const bool timed = std::all_of(layers.begin(), layers.end(), [](const auto& l) { return l.captured_at.has_value(); });
  std::stable_sort(layers.begin(), layers.end(), [&](const LayerRecord& a, const LayerRecord& b) {
    if (timed && *a.captured_at != *b.captured_at) return *a.captured_at < *b.captured_at;
    return a.id < b.id;
  });
  return layers;
}

void SiteVolumeOptions::validate() const {
  volume.validate();
  voxels.validate();
  if (!(cell_m == 0 || (cell_m >= 0.001 && cell_m <= 1)))
    throw InputError(fmt::format("volume options: cell_m = {} is not 0 (automatic) or 0.001..1 m", cell_m));
  if (!(default_noise_m >= 0 && default_noise_m <= 1))
    throw InputError(fmt::format("volume options: default_noise_m = {} is not in 0..1 m", default_noise_m));
  for (const auto& [layer, path] : surface_files)
    if (!fs::exists(path)) throw InputError(fmt::format("volume: surface of layer {}: {} does not exist", layer, path.string()));
  for (const auto& [unit, path] : footprint_files)
    if (!fs::exists(path)) throw InputError(fmt::format("volume: footprint of unit {}: {} does not exist", unit, path.string()));
  if (!outline_file.empty() && !fs::exists(outline_file))
    throw InputError(fmt::format("volume: trench outline {} does not exist", outline_file.string()));
}

namespace {

// Where each layer's surface comes from (a GeoTIFF the user gave, else the
// layer's fused surface, else its DTM) and its extent, in capture order; layers
// without one are left out with a warning.
std::vector<SurfaceSource> surface_sources(Project& project, const SiteVolumeOptions& options,
                                           const Eigen::Vector3d& origin) {
  Database& db = project.db();
  for (const auto& [layer, path] : options.surface_files)
    if (!find_layer(db, layer)) throw InputError(fmt::format("volume: --surface names layer '{}', which does not exist", layer));
  std::vector<SurfaceSource> sources;
  for (const auto& layer : capture_order(list_layers(db))) {
    SurfaceSource s;
    s.layer = layer;
    if (auto f = options.surface_files.find(layer.name); f != options.surface_files.end()) {
      s.path = f->second;
      s.raster = true;
      // A DTM from elsewhere may bring its uncertainty as NAME_sigma.tif beside it.
      const fs::path sibling = s.path.parent_path() / (s.path.stem().string() + "_sigma" + s.path.extension().string());
      if (fs::exists(sibling)) s.sigma_path = sibling;
    } else if (auto p = find_product(db, layer.id, "surface")) {
      s.path = project.dir() / p->path;
    } else if (auto d = find_product(db, layer.id, "dtm")) {
      s.path = project.dir() / d->path;
      s.raster = true;
      if (auto sg = find_product(db, layer.id, "dtm_sigma"); sg && fs::exists(project.dir() / sg->path))
        s.sigma_path = project.dir() / sg->path;
    } else {
      log::warn("volume: layer {} has no surface yet (run 'strata process {} --layer {}'): left out", layer.name,
                project.dir().string(), layer.name);
      continue;
    }
    if (s.raster && options.surface_files.count(layer.name)) {
      s.field = read_site_height_geotiff(s.path, project.site(), fmt::format("--surface of layer {}", layer.name));
    } else if (s.raster) {
      s.field = read_height_geotiff(s.path, origin);
    }
    if (s.raster) {
      const RasterGrid& g = s.field->grid;
      s.xmin = g.x_min;
      s.ymin = g.y_min();
      s.xmax = g.x_max();
      s.ymax = g.y_max;
    } else {
      const LevelSetInfo info = read_level_set_info(s.path);
      s.xmin = info.min.x();
      s.ymin = info.min.y();
      s.xmax = info.max.x();
      s.ymax = info.max.y();
    }
    sources.push_back(std::move(s));
  }
  if (sources.size() < 2)
    throw InputError(fmt::format("volume: {} layer(s) have a surface; at least two are needed for a volume",
                                 sources.size()));
  // A surface that overlaps no other is in the wrong place (another CRS, a wrong
  // origin): it would only stretch the common grid.
  for (const auto& s : sources) {
    const bool overlaps = std::any_of(sources.begin(), sources.end(), [&](const SurfaceSource& o) {
      return &o != &s && s.xmin <= o.xmax && o.xmin <= s.xmax && s.ymin <= o.ymax && o.ymin <= s.ymax;
    });
    if (!overlaps) {
      const auto extent = [&](const SurfaceSource& x) {
        return fmt::format("layer {} ({}): E {:.1f}..{:.1f}, N {:.1f}..{:.1f}", x.layer.name, x.path.filename().string(),
                           x.xmin + origin.x(), x.xmax + origin.x(), x.ymin + origin.y(), x.ymax + origin.y());
      };
      std::string others;
      for (const auto& o : sources)
        if (&o != &s) others += (others.empty() ? "" : "; ") + extent(o);
      throw InputError(fmt::format("volume: the surface of {} overlaps no other layer's surface ({}); is one of them "
                                   "in another CRS or place?",
                                   extent(s), others));
    }
  }
  return sources;
}

// The common grid: the union of the extents, aligned to the first raster's pixel
// centres when its pixel is the cell (no resampling of DTMs), else to multiples of
// the cell.
RasterGrid common_grid(const std::vector<SurfaceSource>& sources, double cell_m) {
  double cell = cell_m;
  const SurfaceSource* first_raster = nullptr;
  for (const auto& s : sources)
    if (s.raster) {
      first_raster = &s;
      break;
    }
  if (cell == 0) cell = first_raster ? first_raster->field->grid.cell : kDefaultCell;
  double ax = 0, ay = 0;  // a cell centre the grid goes through
  if (first_raster && std::abs(first_raster->field->grid.cell - cell) < 1e-9 * cell) {
    const RasterGrid& g = first_raster->field->grid;
    ax = g.x_centre(0);
    ay = g.y_centre(g.height - 1);
  }
  double xmin = 1e300, ymin = 1e300, xmax = -1e300, ymax = -1e300;
  for (const auto& s : sources) {
    xmin = std::min(xmin, s.xmin);
    ymin = std::min(ymin, s.ymin);
    xmax = std::max(xmax, s.xmax);
    ymax = std::max(ymax, s.ymax);
  }
  // Cells whose centre ax + k*cell lies inside the union of the extents.
  const double k0 = std::ceil((xmin - ax) / cell - 1e-6), k1 = std::floor((xmax - ax) / cell + 1e-6);
  const double l0 = std::ceil((ymin - ay) / cell - 1e-6), l1 = std::floor((ymax - ay) / cell + 1e-6);
  const RasterGrid grid = RasterGrid::from_south_west_centre(ax + k0 * cell, ay + l0 * cell, cell, int(k1 - k0) + 1,
                                                             int(l1 - l0) + 1);
  constexpr double kMaxCells = 200e6;
  if (double(grid.width) * grid.height > kMaxCells)
    throw InputError(fmt::format("volume: a {} m grid over {:.1f} x {:.1f} m has too many cells; choose a larger --cell",
                                 cell, xmax - xmin, ymax - ymin));
  log::info("volume: common grid {} x {} cells of {} mm", grid.width, grid.height, 1000 * cell);
  return grid;
}

// Every surface sampled on the common grid, with its uncertainty figures.
std::vector<LayerSurface> sample_surfaces(Database& db, const std::vector<SurfaceSource>& sources,
                                          const RasterGrid& grid, const SiteVolumeOptions& options,
                                          const Eigen::Vector3d& origin) {
  std::vector<LayerSurface> layers;
  for (const auto& s : sources) {
    LayerSurface l;
    l.layer = s.layer.name;
    l.unit = s.layer.unit;
    l.source = s.path.string();
    l.z = s.raster ? resample(*s.field, grid) : sample_top_surface(s.path, grid);
    if (!s.sigma_path.empty()) {
      const Eigen::Vector3d plane(origin.x(), origin.y(), 0);  // metres of uncertainty, no height offset
      l.z.sigma = resample(read_height_geotiff(s.sigma_path, plane), grid).z;
    }
    l.noise_m = surface_noise(db, s.layer.id, options.default_noise_m);
    l.vertical_rmse_m = vertical_rmse(db, s.layer.id);
    // A DTM from elsewhere: its smoothing is not known.
    if (!options.surface_files.count(s.layer.name)) l.smoothing_m = surface_smoothing(db, s.layer.id);
    layers.push_back(std::move(l));
  }
  return layers;
}

// The volume options with the unit footprints and the trench outline read: given
// now, the outline is kept with the project; else the kept one, if any.
// Both must overlap the surfaces (`extent`), and a footprint name a unit of the project.
VolumeOptions options_with_polygons(Project& project, const SiteVolumeOptions& options, const SiteInfo& site,
                                    const SiteExtent& extent) {
  VolumeOptions vo = options.volume;
  for (const auto& [unit, path] : options.footprint_files) {
    if (!find_unit(project.db(), unit))
      throw InputError(fmt::format("volume: --footprint names unit '{}', which is not in the project", unit));
    vo.footprints[unit] = read_outline(path, site, fmt::format("--footprint of unit {}", unit), extent);
  }
  const fs::path kept = project.dir() / kTrenchOutlineFile;
  if (!options.outline_file.empty()) {
    vo.fill.outline = read_outline(options.outline_file, site, "--outline", extent);
    if (fs::absolute(options.outline_file) != fs::absolute(kept)) {
      write_bytes_atomically(kept, "volume",
                             outline_geojson(vo.fill.outline, site, fmt::format("trench outline ({})", site.crs)));
      log::info("volume: trench outline kept as {}", kept.string());
    }
  } else if (fs::exists(kept)) {
    vo.fill.outline = read_outline(kept, site, "the kept trench outline", extent);
  }
  return vo;
}

}  // namespace

SiteModel load_site_model(Project& project, const SiteVolumeOptions& options) {
  options.validate();
  Database& db = project.db();
  SiteModel model;
  model.site = project.site();
  model.units = list_units(db);
  model.relations = list_relations(db);
  const std::vector<SurfaceSource> sources = surface_sources(project, options, model.site.origin);
  const RasterGrid grid = common_grid(sources, options.cell_m);
  model.layers = sample_surfaces(db, sources, grid, options, model.site.origin);
  const SiteExtent extent{{grid.x_min, grid.y_min()}, {grid.x_max(), grid.y_max}};
  const VolumeOptions vo = options_with_polygons(project, options, model.site, extent);
  model.fill = fill_surface_gaps(model.layers, vo);
  model.solids = build_unit_solids(model.layers, vo);
  std::map<std::string, fs::path> level_sets;  // the fused layers' voxel models
  for (const auto& src : sources)
    if (!src.raster) level_sets[src.layer.name] = src.path;
  check_folds(model.solids, model.layers, level_sets, vo);
  return model;
}

namespace {

// The thickness of a solid, metres, where it was dug (NaN elsewhere), north-up as
// its GeoTIFF holds it.
Dtm thickness_raster(const UnitSolid& solid) {
  HeightRaster<double> t = solid.top;
  for (std::size_t c = 0; c < t.z.size(); ++c)
    if (solid.dug(c)) t.z[c] = solid.thickness(c);
  return convert_raster<float>(t);
}

}  // namespace

void write_thickness_geotiff(const fs::path& path, const UnitSolid& solid, const SiteInfo& site) {
  // Tiled GTiff, not COG: a thickness raster is read whole, into a GIS or a report.
  write_float_geotiff(path, thickness_raster(solid), {describe_crs(site.crs).wkt, site.origin},
                      {.description = fmt::format("thickness of unit {} (m)", solid.unit), .unit = "m", .value_offset = 0},
                      {.cog = false, .compression = "DEFLATE"});
}

nlohmann::ordered_json unit_measures_json(const UnitSolid& s) {
  const auto& m = s.measures;
  return {{"unit", s.unit},
          {"volume_m3", m.volume_m3},
          {"interval_m3", {m.interval_low_m3, m.interval_high_m3}},
          {"confidence", m.confidence},
          {"volume_sigma_m3", m.volume_sigma_m3},
          {"sigma_parts_m3",
           {{"random", m.random_sigma_m3},
            {"systematic", m.systematic_sigma_m3},
            {"fill", m.fill_sigma_m3},
            {"extent", m.extent_sigma_m3},
            {"smoothing", m.smoothing_sigma_m3},
            {"fold", m.fold_sigma_m3}}},
          {"interval_method",
           "one-sigma parts in quadrature: random (per-cell surface sigmas, from the fused depth maps' agreement, "
           "scaled per bin of stated sigma, then of coverage (share of measured cells within coverage_radius_m, 10 cm by default), on stable ground, correlated over correlation_m: Gaussian model, pi L^2), "
           "systematic (the surfaces' relative offset on stable ground, its standard error and its spread between "
           "the four quadrants; else check-marker RMSE z; over the whole area), fill (summed "
           "linearly over interpolated cells), extent (volumes with the level of detection halved and doubled, "
           "uniform), smoothing (what one more smoothing of both surfaces at their reconstruction's scale moves the "
           "volume: rounded edges and corners), fold (half what the voxel models add where the surfaces are steep; "
           "their figure replaces the height fields' there); interval = volume +/- z sigma"},
          {"measured_volume_m3", m.measured_volume_m3},
          {"filled_volume_m3", m.filled_volume_m3},
          {"area_m2", m.area_m2},
          {"extent_method", m.extent_method},
          {"median_lod_m", m.median_lod_m},
          {"mean_thickness_m", m.mean_thickness_m},
          {"min_thickness_m", m.min_thickness_m},
          {"max_thickness_m", m.max_thickness_m},
          {"max_thickness_raw_m", m.max_thickness_raw_m},
          {"mean_normal_thickness_m", m.mean_normal_thickness_m},
          {"max_normal_thickness_m", m.max_normal_thickness_m},
          {"fold_check",
           m.fold_checked ? nlohmann::ordered_json{{"area_m2", m.fold_area_m2},
                                                   {"height_field_volume_m3", m.fold_height_field_m3},
                                                   {"voxel_volume_m3", m.fold_voxel_m3},
                                                   {"difference_m3", m.fold_difference_m3()}}
                          : nlohmann::ordered_json(nullptr)},
          {"filled_area_m2", m.filled_area_m2},
          {"filled_fraction", m.filled_fraction},
          {"fill_sigma_m3", m.fill_sigma_m3},
          {"stable_ground",
           {{"area_m2", m.stable_area_m2},
            {"bias_m", m.stable_bias_m},
            {"nmad_m", m.stable_nmad_m},
            {"offset_spread_m", m.stable_offset_spread_m},
            {"noise_scale", m.noise_scale},
            {"correlation_m", m.correlation_m},
            {"per_cell_sigma", m.per_cell_sigma}}},
          {"advice", m.advice},
          {"top_layer", s.top_layer},
          {"bottom_layers", s.bottom_layers}};
}

HarrisMatrix site_matrix(const SiteModel& model) {
  std::vector<std::string> codes;
  for (const auto& u : model.units) codes.push_back(u.code);
  std::vector<CanonicalRelation> rels;
  for (const auto& r : model.relations)
    if (const auto k = relation_kind_from_string(r.kind)) rels.push_back({r.unit_a, *k, r.unit_b});
  return HarrisMatrix(codes, rels);
}

VoxelSummary store_site_volumes(Project& project, const SiteModel& model, const SiteVolumeOptions& options) {
  const fs::path rel_dir = fs::path("products") / "volume";
  const fs::path dir = project.dir() / rel_dir;
  fs::create_directories(dir);
  std::map<std::string, std::int32_t> labels;
  std::map<std::string, std::int64_t> unit_ids;
  for (const auto& u : model.units) {
    labels[u.code] = std::int32_t(u.id);
    unit_ids[u.code] = u.id;
  }
  // Every file is written under a staged name first; only when all are complete are
  // the old records retracted (committed) and the files swapped in, so a full disk
  // part-way leaves the recorded files and rows as they were (docs/reliability.md).
  StagedFiles staged("volume");
  const VoxelSummary voxels = write_unit_voxels(staged.add(dir / "units.vdb"), model.solids, labels, options.voxels,
                                                model.site.origin, model.site.crs);
  for (const auto& s : model.solids)
    write_thickness_geotiff(staged.add(dir / fmt::format("thickness_{}.tif", s.unit)), s, model.site);

  Database& db = project.db();
  {
    Transaction retract(db);
    db.exec("DELETE FROM products WHERE kind IN ('thickness', 'voxels')");
    retract.commit();
  }
  staged.swap_in();
  Transaction tx(db);
  db.exec("DELETE FROM unit_volumes");
  nlohmann::json sources = nlohmann::json::object();
  for (const auto& l : model.layers) sources[l.layer] = l.source;
  for (const auto& s : model.solids) {
    const auto id = unit_ids.find(s.unit);
    if (id == unit_ids.end()) continue;
    const VoxelUnit* vu = nullptr;
    for (const auto& v : voxels.units)
      if (v.unit == s.unit) vu = &v;
    std::string bottoms;
    for (const auto& b : s.bottom_layers) bottoms += (bottoms.empty() ? "" : ",") + b;
    const auto& m = s.measures;
    nlohmann::ordered_json details = unit_measures_json(s);
    details.update(nlohmann::ordered_json{{"cell_m", s.top.grid.cell},
                                          {"cells", m.cells},
                                          {"noise_threshold_m", options.volume.noise_threshold_m},
                                          {"max_thickness_quantile", options.volume.max_thickness_quantile},
                                          {"footprint", options.footprint_files.count(s.unit) > 0},
                                          {"gap_fill", options.volume.fill.enabled},
                                          {"trench_outline", options.outline_file.string()},
                                          {"voxel_size_m", voxels.voxel_size_m},
                                          {"voxel_fog_volume_m3", vu ? vu->fog_volume_m3 : 0.0},
                                          {"voxel_label_volume_m3", vu ? vu->label_volume_m3 : 0.0},
                                          {"sources", sources}});
    db.prepare(
          "INSERT INTO unit_volumes(unit_id, top_layer, bottom_layers, volume_m3, area_m2, mean_thickness_m, "
          "min_thickness_m, max_thickness_m, volume_sigma_m3, method, details_json, computed_at) "
          "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, 'height-field differencing', ?, strftime('%Y-%m-%dT%H:%M:%SZ','now'))")
        .bind_all(id->second, s.top_layer, bottoms, m.volume_m3, m.area_m2, m.mean_thickness_m, m.min_thickness_m,
                  m.max_thickness_m, m.volume_sigma_m3, details.dump())
        .run();
    ProductRecord r;
    r.unit_id = id->second;
    r.kind = "thickness";
    r.path = (rel_dir / fmt::format("thickness_{}.tif", s.unit)).string();
    r.params_json = nlohmann::json{{"cell_m", s.top.grid.cell}}.dump();
    record_product(db, project.dir(), r);
  }
  // The extent of every unit as polygons (the outline of its dug cells).
  db.exec("DELETE FROM unit_extents");
  for (const auto& s : model.solids) {
    if (s.measures.cells == 0) continue;
    Dtm mask = Dtm::empty(s.top.grid);
    for (std::size_t c = 0; c < mask.z.size(); ++c)
      if (s.dug(c)) mask.z[c] = 1.0f;
    const Footprint extent = dtm_footprint(mask, model.site.origin, 0);
    if (extent.polygons.empty()) continue;
    const auto& m = s.measures;
    auto st = db.prepare(
        "INSERT INTO unit_extents(geom, unit, method, area_m2, volume_m3, volume_low_m3, volume_high_m3, "
        "confidence, min_e, min_n, max_e, max_n) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
    st.bind_blob(1, gpkg_multipolygon(model.site.srs_id, extent));
    st.bind(2, s.unit).bind(3, m.extent_method).bind(4, m.area_m2).bind(5, m.volume_m3);
    st.bind(6, m.interval_low_m3).bind(7, m.interval_high_m3).bind(8, m.confidence);
    st.bind(9, extent.min.x()).bind(10, extent.min.y()).bind(11, extent.max.x()).bind(12, extent.max.y());
    st.run();
  }
  db.exec(
      "UPDATE gpkg_contents SET (min_x, min_y, max_x, max_y, last_change) = (SELECT min(min_e), min(min_n), "
      "max(max_e), max(max_n), strftime('%Y-%m-%dT%H:%M:%fZ','now') FROM unit_extents) WHERE table_name = "
      "'unit_extents'");
  ProductRecord r;
  r.kind = "voxels";
  r.path = (rel_dir / "units.vdb").string();
  r.params_json = nlohmann::json{{"voxel_size_m", voxels.voxel_size_m}, {"cell_m", model.layers.front().z.grid.cell}}.dump();
  record_product(db, project.dir(), r);
  tx.commit();
  return voxels;
}

}  // namespace strata
