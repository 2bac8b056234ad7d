// The inputs of the volume and section steps: a surface raster (`--surface
// LAYER=FILE`, reader.dtm through GDAL: any raster format GDAL opens; the seeds are
// GeoTIFFs in the site CRS, in the next UTM zone, without a CRS, and headers that
// claim far more pixels than they hold) and the volume and section options as a user
// types them. The options targets run the real steps (load_site_model,
// cut_site_section) on a small project made once per process: two layers of 1 x 1 m
// at 2 cm, the second 5 cm lower in its middle. Memory is bounded to 256 MB
// (STRATA_MEMORY_BUDGET_MB): an input that asks for more must be refused, not tried.
#include "core/door.hpp"
#include "fuzz/fuzz_support.hpp"
#include "fuzz/targets.hpp"
#include "importers/raster/geotiff.hpp"
#include "pipeline/record_edits.hpp"
#include "pipeline/site_section.hpp"
#include "project/site_bounds.hpp"
#include "volume/site_volumes.hpp"

#include <cpl_error.h>
#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <cmath>
#include <cstdlib>
#include <sstream>
#include <string>
#include <vector>

namespace strata::fuzz {
namespace {

constexpr double kWest = 734000, kNorth = 4174001;

void quiet_and_bounded() {
  static const bool done = [] {
    CPLSetErrorHandler(CPLQuietErrorHandler);
    setenv("STRATA_MEMORY_BUDGET_MB", "256", 1);
    GDALAllRegister();
    return true;
  }();
  (void)done;
}

void write_surface(const std::filesystem::path& path, double z, double z_middle) {
  GDALDataset* ds = GetGDALDriverManager()->GetDriverByName("GTiff")->Create(path.c_str(), 50, 50, 1, GDT_Float32, nullptr);
  double gt[6] = {kWest, 0.02, 0, kNorth, 0, -0.02};
  ds->SetGeoTransform(gt);
  OGRSpatialReference srs;
  srs.importFromEPSG(32636);
  ds->SetSpatialRef(&srs);
  std::vector<float> v(50 * 50, float(z));
  for (int r = 15; r < 35; ++r)
    for (int c = 15; c < 35; ++c) v[std::size_t(r) * 50 + std::size_t(c)] = float(z_middle);
  if (ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, 50, 50, v.data(), 50, 50, GDT_Float32, 0, 0) != CE_None)
    throw FuzzFailure("site fuzz: cannot write the test surface");
  GDALClose(ds);
}

// The small project, made on first use; its surfaces are given as --surface files.
struct SmallSite {
  std::filesystem::path dir;
  SiteVolumeOptions model;
};

const SmallSite& small_site() {
  static const SmallSite site = [] {
    quiet_and_bounded();
    SmallSite s;
    s.dir = scratch_dir() / "site";
    CreateOptions o;
    o.crs = "EPSG:32636";
    o.origin = Eigen::Vector3d(kWest, kNorth - 1, 100);
    Project p = Project::create(s.dir, o);
    add_unit(p, {0, "101", "deposit", ""});
    add_unit(p, {0, "102", "deposit", ""});
    add_layer(p, {0, "L1", "101", std::nullopt});
    add_layer(p, {0, "L2", "102", std::nullopt});
    write_surface(scratch_dir() / "top.tif", 100.0, 100.0);
    write_surface(scratch_dir() / "bottom.tif", 100.0, 99.95);
    s.model.surface_files = {{"L1", scratch_dir() / "top.tif"}, {"L2", scratch_dir() / "bottom.tif"}};
    return s;
  }();
  return site;
}

// The input's numbers, whitespace- or comma-separated ("nan", "1e308" and
// hexadecimal floats included); words that are not numbers are left out.
std::vector<double> numbers(const std::uint8_t* data, std::size_t size) {
  std::string text(reinterpret_cast<const char*>(data), size);
  for (char& c : text)
    if (c == ',' || c == ';') c = ' ';
  std::istringstream in(text);
  std::vector<double> out;
  for (std::string word; in >> word && out.size() < 16;) {
    char* end = nullptr;
    const double v = std::strtod(word.c_str(), &end);
    if (end != word.c_str() && *end == '\0') out.push_back(v);
  }
  return out;
}

double at(const std::vector<double>& v, std::size_t i, double fallback) { return i < v.size() ? v[i] : fallback; }

}  // namespace

int geotiff(const std::uint8_t* data, std::size_t size) {
  quiet_and_bounded();
  constexpr const char* kInputName = "surface_input.tif";
  const auto file = write_input(kInputName, data, size);
  SiteInfo site;
  site.crs = "EPSG:32636";
  site.origin = {kWest, kNorth - 1, 100};
  site.origin_set = true;
  HeightRaster<double> r;
  if (!accepts([&] { r = read_site_height_geotiff(file, site, "--surface of layer L1"); }, kInputName)) return 0;
  if (r.z.size() != r.grid.cells()) throw FuzzFailure("reader.dtm: accepted a raster whose heights do not fill its grid");
  if (!(r.grid.cell > 0)) throw FuzzFailure("reader.dtm: accepted a raster without a positive pixel size");
  if (double(r.z.size()) * sizeof(double) > double(door::memory_budget_bytes()))
    throw FuzzFailure("reader.dtm: read a raster larger than the memory budget");
  return 0;
}

// E1 N1 E2 N2 (metres from the site's south-west corner, or absolute when large)
// step scale finds-within: the options of `strata export section`.
int section_options(const std::uint8_t* data, std::size_t size) {
  const SmallSite& s = small_site();
  const auto v = numbers(data, size);
  const auto coordinate = [](double x, double base) { return std::abs(x) < 1e4 ? base + x : x; };
  SiteSectionRequest r;
  r.a = {coordinate(at(v, 0, 0.1), kWest), coordinate(at(v, 1, 0.5), kNorth - 1)};
  r.b = {coordinate(at(v, 2, 0.9), kWest), coordinate(at(v, 3, 0.5), kNorth - 1)};
  r.step_m = at(v, 4, 0);
  r.scale = at(v, 5, 20);
  r.finds.within_m = at(v, 6, 0.25);
  Project p = Project::open(s.dir);
  SiteSection section;
  try {
    section = cut_site_section(p, s.model, r);
  } catch (const InputError&) {
    return 0;  // refused in one line naming the option; there is no file
  }
  const auto& profile = section.profile;
  if (profile.s.empty() || !std::isfinite(profile.length()))
    throw FuzzFailure("section: accepted options that give no samples or an infinite line");
  if (double(profile.s.size()) * sizeof(double) > double(door::memory_budget_bytes()))
    throw FuzzFailure("section: sampled more than the memory budget allows");
  return 0;
}

// cell threshold voxel-size noise fill-closing confidence: the options of `strata volume`.
int volume_options(const std::uint8_t* data, std::size_t size) {
  const SmallSite& s = small_site();
  const auto v = numbers(data, size);
  SiteVolumeOptions o = s.model;
  o.cell_m = at(v, 0, 0);
  o.volume.noise_threshold_m = at(v, 1, o.volume.noise_threshold_m);
  o.voxels.voxel_size_m = at(v, 2, o.voxels.voxel_size_m);
  o.default_noise_m = at(v, 3, o.default_noise_m);
  o.volume.fill.closing_m = at(v, 4, o.volume.fill.closing_m);
  o.volume.confidence = at(v, 5, o.volume.confidence);
  Project p = Project::open(s.dir);
  SiteModel m;
  try {
    m = load_site_model(p, o);
  } catch (const InputError&) {
    return 0;
  }
  for (const auto& solid : m.solids) {
    const double volume = solid.measures.volume_m3;
    if (!std::isfinite(volume) || volume < 0 || volume > 1.0)  // the site is 1 x 1 m, at most 5 cm deep
      throw FuzzFailure("volume: accepted options that give a volume that is not finite or larger than the site");
  }
  return 0;
}

}  // namespace strata::fuzz
