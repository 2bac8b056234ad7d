// strata export dtm|ortho|qgis|grass
#include "cli/commands.hpp"
#include "core/error.hpp"
#include "core/log.hpp"
#include "crs/crs.hpp"
#include "exporters/grass/grass_export.hpp"
#include "exporters/qgis/qgis_project.hpp"
#include "pipeline/products_layer.hpp"
#include "project/project.hpp"
#include "project/records.hpp"
#include "volume/finds.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <iostream>
#include <memory>

namespace fs = std::filesystem;

namespace strata::cli {
namespace {

void check_out_file(const std::string& out, const char* what) {
  const fs::path p(out);
  if (fs::is_directory(p)) throw InputError(fmt::format("--out {}: is a folder; give the {} file name", out, what));
  const fs::path parent = p.has_parent_path() ? p.parent_path() : fs::path(".");
  if (!fs::is_directory(parent)) throw InputError(fmt::format("--out {}: folder {} does not exist", out, parent.string()));
}

// The options every layer-raster export shares.
struct RasterExportArgs {
  std::string dir, layer, out;
  double cell_m = 0.005;
  bool plain = false;  // a tiled GeoTIFF, not a COG
  bool json = false;
};

std::shared_ptr<RasterExportArgs> add_raster_export_options(CLI::App* cmd, const char* json_help) {
  auto a = std::make_shared<RasterExportArgs>();
  cmd->add_option("DIR", a->dir, "project folder")->required();
  cmd->add_option("--layer", a->layer, "the layer")->required();
  cmd->add_option("--out", a->out, "output GeoTIFF")->required();
  cmd->add_option("--cell", a->cell_m, "cell size in metres (default 0.005)");
  cmd->add_flag("--no-cog", a->plain, "plain tiled GeoTIFF instead of a Cloud-Optimized GeoTIFF");
  cmd->add_flag("--json", a->json, json_help);
  return a;
}

// The layer's DTM at the asked cell, from its fused surface.
Dtm export_dtm_of(Project& p, const RasterExportArgs& a) {
  DtmOptions o;
  o.cell_m = a.cell_m;
  return build_dtm(layer_surface_path(p, a.layer), o);
}

void register_export_dtm(CLI::App* exp) {
  auto* cmd = exp->add_subcommand(
      "dtm",
      "DTM of a layer: the uppermost fused surface seen from above, as a Float32 GeoTIFF\n"
      "(Cloud-Optimized by default) in the site CRS. Pixel values are absolute heights in\n"
      "metres; cells with no surface hold -9999 (the nodata value). The grid's edges are\n"
      "whole multiples of the cell, so DTMs of different layers stack without resampling.\n"
      "Needs the layer's dense surface ('strata process DIR --layer L --until dense').\n"
      "Example: strata export dtm site --layer L1 --out L1_dtm.tif --cell 0.01");
  const auto a = add_raster_export_options(cmd, "print the DTM's statistics as JSON");
  cmd->callback([=] {
    check_out_file(a->out, "GeoTIFF");
    Project p = Project::open(a->dir);
    const SiteInfo site = p.site();
    const Dtm dtm = export_dtm_of(p, *a);
    GeoTiffOptions t;
    t.cog = !a->plain;
    write_dtm_geotiff(a->out, dtm, {describe_crs(site.crs).wkt, site.origin}, t);
    const DtmStatistics s = dtm_statistics(dtm, site.origin.z());
    if (a->json) {
      std::cout << nlohmann::json{{"layer", a->layer}, {"path", a->out}, {"cell_m", dtm.grid.cell},
                                  {"width", dtm.grid.width}, {"height", dtm.grid.height},
                                  {"valid_cells", s.valid_cells}, {"area_m2", s.area_m2}, {"min_m", s.min},
                                  {"max_m", s.max}, {"mean_m", s.mean}}
                       .dump(2)
                << "\n";
    }
    log::info("wrote {} ({} x {} cells of {} m, heights {:.3f} .. {:.3f} m)", a->out, dtm.grid.width,
              dtm.grid.height, dtm.grid.cell, s.min, s.max);
  });
}

void register_export_ortho(CLI::App* exp) {
  auto* cmd = exp->add_subcommand(
      "ortho",
      "True orthophoto of a layer as an RGBA GeoTIFF (Cloud-Optimized by default) in the\n"
      "site CRS. Every cell is coloured from photos that see it (depth test against the\n"
      "surface, so trench sides and stones do not smear), the best view per region\n"
      "(resolution and obliqueness) with few, feathered seams, and per-photo exposure\n"
      "gains balanced by least squares over the overlaps. Alpha is 0 where nothing was seen.\n"
      "Example: strata export ortho site --layer L1 --out L1_ortho.tif");
  const auto a = add_raster_export_options(cmd, "print coverage, seams and gains as JSON");
  auto no_balance = std::make_shared<bool>(false);
  cmd->add_flag("--no-balance", *no_balance, "keep each photo's exposure as it is");
  cmd->callback([=] {
    check_out_file(a->out, "GeoTIFF");
    Project p = Project::open(a->dir);
    const SiteInfo site = p.site();
    const Dtm dtm = export_dtm_of(p, *a);
    OrthoOptions o;
    o.radiometric_balance = !*no_balance;
    OrthoSummary s;
    const RgbaRaster ortho = build_orthophoto(dtm, layer_ortho_views(p, a->layer), o, &s);
    GeoTiffOptions t;
    t.cog = !a->plain;
    write_rgba_geotiff(a->out, ortho, {describe_crs(site.crs).wkt, site.origin}, t);
    if (a->json) {
      std::cout << nlohmann::json{{"layer", a->layer},       {"path", a->out},
                                  {"coverage", s.coverage}, {"views", s.views},
                                  {"views_used", s.views_used}, {"seam_fraction", s.seam_fraction},
                                  {"balance_rms_before", s.balance_rms_before},
                                  {"balance_rms_after", s.balance_rms_after}, {"seconds", s.seconds}}
                       .dump(2)
                << "\n";
    }
    log::info("wrote {} (coverage {:.1f} % of the DTM, {} of {} photos used)", a->out, 100 * s.coverage,
              s.views_used, s.views);
  });
}

void register_export_qgis(CLI::App* exp) {
  auto* cmd = exp->add_subcommand(
      "qgis",
      "QGIS project of the whole site: per layer a group with contours, footprint,\n"
      "orthophoto and hillshade (latest layer on top and switched on), plus markers\n"
      "labelled by name, marker residuals and camera positions, the finds labelled by number\n"
      "(when the voxel model of 'strata volume' exists, those in conflict with the unit solids as\n"
      "'strata finds' reports them: larger red diamonds labelled 'ID: recorded U, lies in G'; the\n"
      "verdicts are those at the time of the export). Data sources are the\n"
      "project's own files by relative paths, so keep the project file beside (or inside)\n"
      "the project folder. .qgz is a zipped .qgs.\n"
      "Example: strata export qgis site --out site/site.qgz");
  auto dir = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  cmd->add_option("DIR", *dir, "project folder")->required();
  cmd->add_option("--out", *out, "project file, .qgs or .qgz")->required();
  cmd->callback([=] {
    check_out_file(*out, ".qgs/.qgz");
    Project p = Project::open(*dir);
    QgisProjectInput in = collect_qgis_input(p);
    std::string finds;
    if (in.finds && project_voxel_model(p)) {
      const FindsCheck check = check_project_finds(p, {});
      in.find_conflicts.emplace();
      for (const FindPlacement& f : check.finds)
        if (f.conflict) in.find_conflicts->push_back({f.find.id, f.geometric_unit.value_or("")});
      finds = fmt::format(", {} finds of which {} in conflict with the unit solids", check.finds.size(),
                          in.find_conflicts->size());
    } else if (in.finds) {
      finds = ", the finds (no voxel model yet to check them against: 'strata volume')";
    }
    write_qgis_project(in, *out);
    log::info("wrote {} ({} layers{})", *out, in.layers.size(), finds);
  });
}

void register_export_grass(CLI::App* exp) {
  auto* cmd = exp->add_subcommand(
      "grass",
      "Files for GRASS GIS: each layer's DTM and orthophoto GeoTIFFs, the site-plan\n"
      "vectors in site_plan.gpkg, and import.sh with r.in.gdal / v.in.ogr calls and a\n"
      "g.region covering every DTM at its cell size. Run it in a location with the site CRS:\n"
      "  grass -c EPSG:32636 ./grassdata/site --exec sh FOLDER/import.sh\n"
      "Example: strata export grass site --out site_grass");
  auto dir = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  cmd->add_option("DIR", *dir, "project folder")->required();
  cmd->add_option("--out", *out, "output folder (created if missing)")->required();
  cmd->callback([=] {
    if (fs::exists(*out) && !fs::is_directory(*out)) {
      throw InputError(fmt::format("--out {}: exists and is not a folder", *out));
    }
    Project p = Project::open(*dir);
    const GrassExportSummary s = export_grass(p, *out);
    log::info("wrote {} and {} files", s.script.string(), s.files.size());
  });
}

}  // namespace

void register_products_commands(CLI::App& app) {
  CLI::App* exp = app.get_subcommand("export");
  register_export_dtm(exp);
  register_export_ortho(exp);
  register_export_qgis(exp);
  register_export_grass(exp);
}

}  // namespace strata::cli
