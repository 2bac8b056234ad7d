// strata volume, strata check, strata export thickness|voxels|section
#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/log.hpp"
#include "exporters/section/section_writers.hpp"
#include "exporters/voxels/voxel_export.hpp"
#include "pipeline/site_section.hpp"
#include "project/project.hpp"
#include "volume/section.hpp"
#include "volume/site_volumes.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <memory>

namespace strata::cli {
namespace {
namespace fs = std::filesystem;

// Options every volume command shares: how surfaces are found and solids built.
struct ModelArgs {
  std::string dir;
  std::vector<std::string> surfaces;    // LAYER=FILE
  std::vector<std::string> footprints;  // UNIT=FILE
  double cell = 0;
  double threshold = VolumeOptions{}.noise_threshold_m;
  double voxel = VoxelOptions{}.voxel_size_m;
  double noise = SiteVolumeOptions{}.default_noise_m;
  std::string outline;                  // FILE: trench outline, the gap-fill domain
  bool no_fill = false;
  bool material_put_back = false;
  double fill_closing = GapFillOptions{}.closing_m;
  double confidence = VolumeOptions{}.confidence;
};

void add_model_options(CLI::App* cmd, ModelArgs& a) {
  cmd->add_option("DIR", a.dir, "project folder")->required();
  cmd->add_option("--surface", a.surfaces,
                  "LAYER=FILE: a GeoTIFF of absolute heights (site CRS) to use as the layer's surface "
                  "instead of its dense surface; repeatable");
  cmd->add_option("--footprint", a.footprints,
                  "UNIT=FILE: a polygon (GeoJSON, GeoPackage, shapefile; site CRS) limiting the unit's "
                  "solid instead of the noise threshold; repeatable");
  cmd->add_option("--cell", a.cell, "measurement grid cell, metres (default: the DTM's pixel, else 0.005)");
  cmd->add_option("--threshold", a.threshold, "surfaces closer than this count as not dug, metres (default 0.005)");
  cmd->add_option("--voxel-size", a.voxel, "voxel edge of the voxel model, metres (default 0.01)");
  cmd->add_option("--noise", a.noise, "surface noise when no dense quality figure exists, metres (default 0.003)");
  cmd->add_option("--outline", a.outline,
                  "FILE: trench outline / limit of excavation (first polygon, site CRS): nothing outside it counts as dug, and gaps in the layer "
                  "surfaces are filled inside it (default: the closed union of the surfaces' data)");
  cmd->add_option("--fill-closing", a.fill_closing,
                  "radius of the closing that derives the trench outline from the data, metres (default 0.25)");
  cmd->add_option("--confidence", a.confidence,
                  "confidence of the significance test that finds where a unit was dug, and of its volume's "
                  "interval (default 0.95)");
  cmd->add_flag("--no-fill", a.no_fill, "do not fill gaps in the layer surfaces (volumes lose the gaps' area)");
  cmd->add_flag("--material-put-back", a.material_put_back,
                "material was put back between recordings (backfill, spoil in the area): a surface above an earlier "
                "one is then real, not an error (by default it may not decide a unit's extent)");
}

std::map<std::string, fs::path> parse_pairs(const std::vector<std::string>& items, const std::string& option) {
  std::map<std::string, fs::path> out;
  for (const auto& item : items) {
    const auto eq = item.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == item.size())
      throw InputError(fmt::format("{} '{}': expected NAME=FILE", option, item));
    out[item.substr(0, eq)] = item.substr(eq + 1);
  }
  return out;
}

SiteVolumeOptions site_options(const ModelArgs& a) {
  SiteVolumeOptions o;
  o.cell_m = a.cell;
  o.volume.noise_threshold_m = a.threshold;
  o.voxels.voxel_size_m = a.voxel;
  o.default_noise_m = a.noise;
  o.surface_files = parse_pairs(a.surfaces, "--surface");
  o.footprint_files = parse_pairs(a.footprints, "--footprint");
  o.outline_file = a.outline;
  o.volume.fill.enabled = !a.no_fill;
  o.volume.surfaces_only_go_down = !a.material_put_back;
  o.volume.fill.closing_m = a.fill_closing;
  o.volume.confidence = a.confidence;
  o.validate();
  return o;
}

const UnitSolid& require_solid(const SiteModel& m, const std::string& unit) {
  for (const auto& s : m.solids)
    if (s.unit == unit) return s;
  for (const auto& u : m.units)
    if (u.code == unit)
      throw InputError(fmt::format("unit {} has no solid: it has no layer, or no later surface below it", unit));
  throw InputError(fmt::format("unit '{}' does not exist", unit));
}

nlohmann::ordered_json measures_json(const UnitSolid& s, const VoxelSummary& v) {
  nlohmann::ordered_json j = unit_measures_json(s);
  for (const auto& u : v.units)
    if (u.unit == s.unit) {
      j["voxel_volume_m3"] = u.fog_volume_m3;
      j["labelled_voxels"] = u.labelled_voxels;
    }
  return j;
}

void register_volume(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "volume",
      "volume, area and thickness of every excavated unit, from the layer surfaces: a unit's solid is\n"
      "the space between its layer's surface and the next recorded surface below, where they differ\n"
      "by more than --threshold. Stores the figures (table unit_volumes), the voxel model\n"
      "(products/volume/units.vdb) and thickness rasters (products/volume/thickness_UNIT.tif).");
  auto a = std::make_shared<ModelArgs>();
  auto unit = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  add_model_options(cmd, *a);
  cmd->add_option("--unit", *unit, "print only this unit");
  cmd->add_flag("--json", *json, "print a JSON list of {unit, volume_m3, area_m2, mean_thickness_m, ...}");
  cmd->callback([=] {
    const SiteVolumeOptions o = site_options(*a);
    const ProjectLock lock = lock_project(a->dir);
    Project p = Project::open(a->dir);
    const SiteModel m = load_site_model(p, o);
    if (!unit->empty()) require_solid(m, *unit);
    fault::point("volume.model_loaded");
    const VoxelSummary v = store_site_volumes(p, m, o);
    fault::point("volume.stored");
    nlohmann::ordered_json list = nlohmann::ordered_json::array();
    for (const auto& s : m.solids)
      if (unit->empty() || s.unit == *unit) list.push_back(measures_json(s, v));
    if (*json) {
      fmt::print("{}\n", list.dump(2));
      return;
    }
    const int pct = int(std::lround(100 * o.volume.confidence));
    fmt::print("{:<8} {:>10} {:>9} {:>9} {:>8} {:>9} {:>9} {:>9} {:>10}  {}\n", "unit", "volume m3",
               fmt::format("{}% +/-", pct), "area m2", "filled %", "mean m", "normal m", "p99 m", "voxels m3",
               "surfaces");
    for (const auto& s : m.solids) {
      if (!unit->empty() && s.unit != *unit) continue;
      const auto& q = s.measures;
      double vox = 0;
      for (const auto& u : v.units)
        if (u.unit == s.unit) vox = u.fog_volume_m3;
      std::string bottoms;
      for (const auto& b : s.bottom_layers) bottoms += (bottoms.empty() ? "" : ",") + b;
      fmt::print("{:<8} {:>10.4f} {:>9.4f} {:>9.3f} {:>8.1f} {:>9.3f} {:>9.3f} {:>9.3f} {:>10.4f}  {} -> {}{}\n",
                 s.unit, q.volume_m3, q.interval_high_m3 - q.volume_m3, q.area_m2, 100 * q.filled_fraction,
                 q.mean_thickness_m, q.mean_normal_thickness_m, q.max_thickness_m, vox, s.top_layer, bottoms,
                 q.filled_fraction > o.volume.fill.warn_fraction ? "  (gaps filled: uncertain)" : "");
    }
    for (const auto& s : m.solids)
      if ((unit->empty() || s.unit == *unit) && !s.measures.advice.empty())
        fmt::print("{}: {}\n", s.unit, s.measures.advice);
    fmt::print("normal: mean thickness along the unit's local normal (steep faces); p99: the thickness exceeded "
               "over 1 % of the unit's area (robust maximum; the thickest single cell is max_thickness_raw_m in "
               "--json)\n");
    log::info("wrote {}", (p.products_dir() / "volume" / "units.vdb").string());
  });
}

void register_check(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "check",
      "Harris matrix against geometry: for every pair of units the matrix orders (above, cuts, fills,\n"
      "abuts, transitively), reports where the later unit's top lies below the earlier one's, with\n"
      "the place (E, N) and the amount. Exit status 1 when there is a conflict.");
  auto a = std::make_shared<ModelArgs>();
  auto tolerance = std::make_shared<double>(CheckOptions{}.tolerance_m);
  auto min_area = std::make_shared<double>(CheckOptions{}.min_area_m2);
  add_model_options(cmd, *a);
  cmd->add_option("--tolerance", *tolerance, "height differences below this are no conflict, metres (default 0.01)");
  cmd->add_option("--min-area", *min_area,
                  "a conflict is a contiguous region of at least this area, m2; smaller regions (outlier spikes "
                  "of the dense surfaces) are counted and listed as ignored (default 0.02)");
  cmd->callback([=] {
    const SiteVolumeOptions o = site_options(*a);
    Project p = Project::open(a->dir);
    const SiteModel m = load_site_model(p, o);
    CheckOptions co;
    co.tolerance_m = *tolerance;
    co.min_area_m2 = *min_area;
    co.validate();
    const StratigraphicCheck check = check_stratigraphy(site_matrix(m), m.layers, m.solids, co);
    for (const auto& c : check.conflicts) fmt::print("{}\n", c.describe(m.site.origin));
    for (const auto& c : check.ignored) fmt::print("{}\n", c.describe_ignored());
    if (check.ignored_regions() > 0)
      fmt::print("{} small region(s) below the minimum area of {} m2 ignored ({:.4f} m2 in all)\n",
                 check.ignored_regions(), co.min_area_m2, check.ignored_area_m2());
    if (!check.conflicts.empty())
      throw ProcessingError(fmt::format("check: {} conflict(s) between the Harris matrix and the geometry",
                                        check.conflicts.size()));
    fmt::print("no conflict between the Harris matrix and the geometry ({} units with geometry, {} layers)\n",
               m.solids.size(), m.layers.size());
  });
}

void register_exports(CLI::App& app) {
  CLI::App* exp = app.get_subcommand("export");
  {
    auto* cmd = exp->add_subcommand("thickness", "thickness of a unit, Float32 GeoTIFF in metres (site CRS, nodata -9999)");
    auto a = std::make_shared<ModelArgs>();
    auto unit = std::make_shared<std::string>();
    auto out = std::make_shared<std::string>();
    add_model_options(cmd, *a);
    cmd->add_option("--unit", *unit, "the unit")->required();
    cmd->add_option("--out", *out, "output GeoTIFF")->required();
    cmd->callback([=] {
      const SiteVolumeOptions o = site_options(*a);
      Project p = Project::open(a->dir);
      const SiteModel m = load_site_model(p, o);
      const UnitSolid& s = require_solid(m, *unit);
      write_thickness_geotiff(*out, s, m.site);
      log::info("wrote {} (unit {}: {:.4f} m3 over {:.3f} m2)", *out, s.unit, s.measures.volume_m3, s.measures.area_m2);
    });
  }
  {
    auto* cmd = exp->add_subcommand(
        "voxels",
        "the voxel model of every excavated unit: .vdb (one fog grid per unit + Int32 'labels'), GRASS\n"
        "3D raster text for r3.in.ascii (.asc, with an import script .sh and a label legend), or VTK\n"
        "image data for ParaView (.vti). The format follows the extension unless --format is given.");
    auto a = std::make_shared<ModelArgs>();
    auto out = std::make_shared<std::string>();
    auto format = std::make_shared<std::string>();
    add_model_options(cmd, *a);
    cmd->add_option("--out", *out, "output file")->required();
    cmd->add_option("--format", *format, "vdb, grass or vti")->check(CLI::IsMember({"vdb", "grass", "vti"}));
    cmd->callback([=] {
      std::string f = *format;
      const std::string ext = fs::path(*out).extension().string();
      if (f.empty()) {
        if (ext == ".vdb") f = "vdb";
        else if (ext == ".vti") f = "vti";
        else if (ext == ".asc" || ext == ".txt") f = "grass";
        else throw InputError(fmt::format("export voxels: cannot tell the format of '{}'; use .vdb, .asc, .vti or --format", *out));
      }
      const SiteVolumeOptions o = site_options(*a);
      Project p = Project::open(a->dir);
      const SiteModel m = load_site_model(p, o);
      std::map<std::string, std::int32_t> labels;
      for (const auto& u : m.units) labels[u.code] = std::int32_t(u.id);
      const fs::path vdb = f == "vdb" ? fs::path(*out) : fs::path(*out).replace_extension(".vdb.tmp");
      write_unit_voxels(vdb, m.solids, labels, o.voxels, m.site.origin, m.site.crs);
      if (f == "vdb") {
        log::info("wrote {}", *out);
        return;
      }
      const LabelVolume v = read_label_volume(vdb);
      fs::remove(vdb);
      if (f == "grass") {
        const fs::path script = write_grass_ascii(*out, v);
        log::info("wrote {} ({} x {} x {} voxels of {} m) and {}", *out, v.nx, v.ny, v.nz, v.voxel_size_m,
                  script.string());
      } else {
        write_vti(*out, v);
        log::info("wrote {} ({} x {} x {} voxels of {} m)", *out, v.nx, v.ny, v.nz, v.voxel_size_m);
      }
    });
  }
  {
    auto* cmd = exp->add_subcommand(
        "section",
        "a section along the line E1,N1 -> E2,N2 through every layer surface and unit: an SVG drawing\n"
        "(1:20 by default: units filled and numbered, heights, datum, scale bar) or a GeoPackage of 3D\n"
        "lines (.gpkg), by extension.\n"
        "Finds within --finds-within metres of the section's vertical plane, whose foot falls between the\n"
        "ends, are projected onto it: in the drawing a marker with the find's number (filled: in front of\n"
        "the face, the side the drawing is seen from, right of E1,N1 -> E2,N2; open: behind it); in the\n"
        "GeoPackage the table section_finds (find_id, unit, type, chainage_m from the first end,\n"
        "height_m, offset_m from the plane, + in front, and the surveyed e, n).");
    auto a = std::make_shared<ModelArgs>();
    auto line = std::make_shared<std::string>();
    auto out = std::make_shared<std::string>();
    auto scale = std::make_shared<double>(20);
    auto title = std::make_shared<std::string>("Section");
    auto step = std::make_shared<double>(0);
    auto finds = std::make_shared<SectionFindOptions>();
    add_model_options(cmd, *a);
    cmd->add_option("--line", *line, "E1,N1,E2,N2 in the site CRS")->required();
    cmd->add_option("--out", *out, "output .svg or .gpkg")->required();
    cmd->add_option("--scale", *scale, "drawing scale 1:N (default 20)");
    cmd->add_option("--title", *title, "title of the drawing");
    cmd->add_option("--step", *step, "sampling step along the line, metres (default: one grid cell)");
    cmd->add_option("--finds-within", finds->within_m,
                    "project the finds within this distance of the section plane, metres, either side; "
                    "0: no finds")
        ->capture_default_str();
    cmd->callback([=] {
      const std::string ext = fs::path(*out).extension().string();
      if (ext != ".svg" && ext != ".gpkg")
        throw InputError(fmt::format("export section: --out '{}' must end in .svg or .gpkg", *out));
      const auto v = parse_numbers(*line, 4, "--line");
      SiteSectionRequest r;
      r.a = {v[0], v[1]};
      r.b = {v[2], v[3]};
      r.step_m = *step;
      r.finds = *finds;
      r.scale = *scale;
      r.title = *title;
      const SiteVolumeOptions o = site_options(*a);
      Project p = Project::open(a->dir);
      const SiteSection s = cut_site_section(p, o, r);
      const SectionProfile& profile = s.profile;
      if (ext == ".svg") {
        write_section_svg(*out, profile, s.site.origin, s.drawing);
      } else {
        write_section_gpkg(*out, profile, s.site.origin, s.site.crs);
      }
      log::info("wrote {} ({:.2f} m, {} samples{})", *out, profile.length(), profile.s.size(),
                finds->within_m > 0 ? fmt::format(", {} of {} finds within {:.2f} m of the plane", s.finds_projected,
                                                  s.finds_recorded, finds->within_m)
                                    : std::string());
    });
  }
}

}  // namespace

void register_volume_commands(CLI::App& app) {
  register_volume(app);
  register_check(app);
  register_exports(app);
}

}  // namespace strata::cli
