// importer.markers.csv and importer.markers.odm on a project with one layer of three
// photos (the names the gcp_list seeds observe). A refused file must leave the
// project without markers; an accepted one is removed again so that every input
// meets the same project.
#include "fuzz/fuzz_support.hpp"
#include "fuzz/targets.hpp"
#include "importers/markers/marker_importer.hpp"
#include "project/records.hpp"

#include <optional>

namespace fs = std::filesystem;

namespace strata::fuzz {
namespace {

constexpr const char* kInputName = "survey_input.txt";

Project make_project() {
  Project p = Project::create(scratch_dir() / "markers_site", {"EPSG:32636", "", std::nullopt});
  Database& db = p.db();
  Transaction tx(db);
  insert_unit(db, {0, "101", "deposit", ""});
  const std::int64_t layer = insert_layer(db, {0, "L1", "101", std::nullopt});
  for (const char* name : {"IMG_0001.JPG", "IMG_0002.JPG", "IMG_0003.JPG"}) {
    ImageRecord im;
    im.layer_id = layer;
    im.name = name;
    im.sha256 = name;  // unique; no media file is read by the marker importer
    im.media_path = std::string("media/") + name;
    im.width = 4000;
    im.height = 3000;
    insert_image(db, im);
  }
  tx.commit();
  return p;
}

std::int64_t count(Database& db, const char* table) {
  return db.query_int(std::string("SELECT count(*) FROM ") + table).value_or(-1);
}

void import(const std::uint8_t* data, std::size_t size, const MarkerImportOptions& options) {
  static Project project = make_project();
  Database& db = project.db();
  const fs::path file = write_input(kInputName, data, size);
  if (accepts([&] { import_markers(project, options, file); }, kInputName)) {
    db.exec("DELETE FROM observations; DELETE FROM markers; UPDATE site SET origin_set = 0");
  } else if (count(db, "markers") != 0 || count(db, "observations") != 0) {
    throw FuzzFailure("a refused marker file left markers or observations in the project");
  }
}

}  // namespace

int markers_csv(const std::uint8_t* data, std::size_t size) {
  MarkerImportOptions options;  // format auto: a CSV, or a gcp_list that looks like one
  import(data, size, options);
  return 0;
}

int markers_odm(const std::uint8_t* data, std::size_t size) {
  MarkerImportOptions options;
  options.format = MarkerFormat::odm;
  options.layer = "L1";
  options.skip_missing_images = true;
  import(data, size, options);
  return 0;
}

}  // namespace strata::fuzz
