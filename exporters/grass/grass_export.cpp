#include "exporters/grass/grass_export.hpp"

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/log.hpp"
#include "exporters/raster/gdal_util.hpp"
#include "project/records.hpp"

#include <gdal_priv.h>
#include <gdal_utils.h>

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <fstream>
#include <memory>

namespace fs = std::filesystem;

namespace strata {
namespace {

double raster_cell(const fs::path& tif) {
  gdal_detail::init_gdal();
  GDALDatasetH ds = GDALOpen(tif.string().c_str(), GA_ReadOnly);
  if (!ds) throw IoError(fmt::format("exporter.grass: {}: {}", tif.string(), CPLGetLastErrorMsg()));
  double gt[6] = {0, 0, 0, 0, 0, 0};
  GDALGetGeoTransform(ds, gt);
  GDALClose(ds);
  return gt[1];
}

// Copies the project's site-plan tables into one GeoPackage (GDALVectorTranslate).
void write_vectors(const fs::path& gpkg, const fs::path& out, const std::vector<std::string>& tables) {
  GDALDatasetH src = GDALOpenEx(gpkg.string().c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY, nullptr, nullptr, nullptr);
  if (!src) throw IoError(fmt::format("exporter.grass: {}: {}", gpkg.string(), CPLGetLastErrorMsg()));
  std::vector<std::string> args = {"-f", "GPKG", "-overwrite"};
  for (const auto& t : tables) args.push_back(t);
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  const std::unique_ptr<GDALVectorTranslateOptions, decltype(&GDALVectorTranslateOptionsFree)> opt(
      GDALVectorTranslateOptionsNew(argv.data(), nullptr), &GDALVectorTranslateOptionsFree);
  const std::unique_ptr<void, decltype(&GDALClose)> source(src, &GDALClose);
  // Through a temporary name: a folder never holds a half-written site_plan.gpkg.
  write_atomically(out, "exporter.grass", [&](const fs::path& tmp) {
    fs::remove(tmp);
    int usage_error = 0;
    GDALDatasetH dst = GDALVectorTranslate(tmp.string().c_str(), nullptr, 1, &src, opt.get(), &usage_error);
    if (!dst) throw IoError(fmt::format("exporter.grass: {}: {}", out.string(), CPLGetLastErrorMsg()));
    CPLErrorReset();
    GDALClose(dst);  // GPKG commits here; a full disk shows in GDAL's error state
    if (gdal_detail::gdal_failed()) {
      throw IoError(fmt::format("exporter.grass: {}: {}", out.string(), CPLGetLastErrorMsg()));
    }
  });
}

}  // namespace

std::string grass_map_name(const std::string& text) {
  std::string s;
  for (char c : text) s += std::isalnum(static_cast<unsigned char>(c)) ? c : '_';
  if (s.empty() || !std::isalpha(static_cast<unsigned char>(s[0]))) s = "L" + s;
  return s;
}

GrassExportSummary export_grass(Project& project, const fs::path& out) {
  auto& db = project.db();
  const SiteInfo site = project.site();
  fs::create_directories(out);
  GrassExportSummary sum;
  std::string rasters_sh, colours_sh;
  std::vector<std::string> dtm_maps;
  double cell = 0;
  for (const LayerRecord& l : list_layers(db)) {
    const std::string base = grass_map_name(l.name);
    for (const char* kind : {"dtm", "ortho"}) {
      const auto p = find_product(db, l.id, kind);
      if (!p) continue;
      const fs::path src = project.dir() / p->path;
      if (!fs::exists(src)) {
        log::warn("exporter.grass: {} is recorded but missing; skipped", src.string());
        continue;
      }
      const std::string file = fmt::format("{}_{}.tif", base, kind);
      copy_atomically(src, out / file, "exporter.grass");
      fault::point("export.grass.raster_copied");
      sum.files.push_back(out / file);
      const std::string map = fmt::format("{}_{}", base, kind);
      if (std::string(kind) == "dtm") {
        rasters_sh += fmt::format("r.in.gdal --overwrite --quiet input={} output={}\n", file, map);
        colours_sh += fmt::format("r.colors --quiet map={} color=elevation\n", map);
        dtm_maps.push_back(map);
        const double c = raster_cell(src);
        cell = cell > 0 ? std::min(cell, c) : c;
      } else {
        // RGBA becomes <map>.red, .green, .blue, .alpha.
        rasters_sh += fmt::format("r.in.gdal --overwrite --quiet input={} output={}\n", file, map);
      }
    }
  }
  if (dtm_maps.empty()) {
    throw InputError(fmt::format("exporter.grass: {} has no DTM yet; run 'strata process {} --all' first",
                                 project.dir().string(), project.dir().string()));
  }
  sum.rasters = dtm_maps;
  sum.region_cell_m = cell;

  // Vector tables that exist and have rows.
  std::vector<std::string> tables;
  for (const char* t : {"markers", "camera_positions", "contours", "footprints"}) {
    auto st = db.prepare(fmt::format("SELECT count(*) FROM {}", t));
    if (st.step() && st.get_int(0) > 0) tables.push_back(t);
  }
  std::string vectors_sh;
  if (!tables.empty()) {
    write_vectors(project.database_path(), out / "site_plan.gpkg", tables);
    fault::point("export.grass.vectors_written");
    sum.files.push_back(out / "site_plan.gpkg");
    for (const auto& t : tables) {
      vectors_sh += fmt::format("v.in.ogr --overwrite --quiet input=site_plan.gpkg layer={0} output={0}\n", t);
    }
  }

  std::string list;
  for (const auto& m : dtm_maps) list += (list.empty() ? "" : ",") + m;
  const std::string script = fmt::format(
      "#!/bin/sh\n"
      "# GRASS GIS import of the strata site '{0}' (CRS {1}), written by 'strata export grass'.\n"
      "# Run it inside a GRASS session whose location has the site CRS, e.g.\n"
      "#   grass -c {1} ./grassdata/site --exec sh import.sh      (new location)\n"
      "#   grass --tmp-location {1} --exec sh import.sh           (throw-away)\n"
      "# Heights are metres in {1}; orthophotos arrive as <map>.red/.green/.blue/.alpha\n"
      "# (combine with: r.composite red=<map>.red green=<map>.green blue=<map>.blue output=<map>_rgb).\n"
      "set -e\n"
      "cd \"$(dirname \"$0\")\"\n\n"
      "# rasters\n{2}\n{3}\n"
      "# site-plan vectors\n{4}\n"
      "# region: the union of the DTMs at the finest DTM cell ({5} m), aligned to their cells\n"
      "g.region raster={6}\n"
      "g.region res={5} -a\n"
      "g.region -p\n",
      site.name, site.crs, rasters_sh, colours_sh, vectors_sh, fmt::format("{}", cell), list);
  // The script last, through a temporary name like every file here: whenever the
  // process dies, each file in the folder is whole (the old one or the new one).
  sum.script = out / "import.sh";
  write_atomically(
      sum.script, "exporter.grass",
      [&](const fs::path& tmp) {
        std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
        f << script;
        f.close();  // the flush can fail (a full disk) as well as the write
        if (!f) throw IoError(fmt::format("exporter.grass: {}: cannot write", sum.script.string()));
        fs::permissions(tmp, fs::perms::owner_exec | fs::perms::group_exec | fs::perms::others_exec,
                        fs::perm_options::add);
      },
      "export.grass.script_temp_written");
  return sum;
}

}  // namespace strata
