// Opening a project.gpkg someone else made: not SQLite at all, a GeoPackage of
// another program, strata's tables missing or altered, a newer schema. The input is
// the database file; the folder around it is made fresh for each input (no -wal or
// -shm file of the previous one). Project::open and what `strata info` then reads
// must either work or refuse with strata's error naming project.gpkg.
#include "fuzz/fuzz_support.hpp"
#include "fuzz/targets.hpp"
#include "project/calibration_records.hpp"
#include "project/project.hpp"
#include "project/records.hpp"

namespace fs = std::filesystem;

namespace strata::fuzz {
namespace {

void read_everything(Project& p) {
  Database& db = p.db();
  p.site();
  p.schema_version();
  list_units(db);
  list_relations(db);
  list_layers(db);
  list_cameras(db);
  list_calibrations(db);
  list_images(db);
  list_markers(db);
  list_observations(db);
  list_products(db);
}

}  // namespace

int project(const std::uint8_t* data, std::size_t size) {
  const fs::path dir = scratch_dir() / "hostile_site";
  fs::remove_all(dir);
  fs::create_directories(dir);
  write_input("hostile_site/project.gpkg", data, size);
  accepts(
      [&] {
        Project p = Project::open(dir);
        read_everything(p);
      },
      Project::kDatabaseName);
  return 0;
}

}  // namespace strata::fuzz
