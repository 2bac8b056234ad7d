#include "core/error.hpp"
#include "project/gpkg.hpp"
#include "project/project.hpp"
#include "project/records.hpp"
#include "support/test_support.hpp"

#include <gtest/gtest.h>

namespace strata {
namespace schema {
const std::vector<std::pair<std::string_view, std::string_view>>& migration_files();
}
namespace {

TEST(Project, CreateAppliesAllMigrationsToAnEmptyFile) {
  test::ScratchDir dir("p");
  Project p = Project::create(dir / "site", {"EPSG:32636", "Trench 7", std::nullopt});
  EXPECT_EQ(p.schema_version(), latest_schema_version());
  EXPECT_GE(latest_schema_version(), 1);
  // GeoPackage identification: application_id 'GPKG', user_version 1.2.0.
  EXPECT_EQ(p.db().query_int("PRAGMA application_id"), 0x47504B47);
  EXPECT_EQ(p.db().query_int("PRAGMA user_version"), 10200);
  EXPECT_EQ(p.db().query_text("PRAGMA journal_mode"), "wal");
  EXPECT_EQ(p.db().query_int("PRAGMA foreign_keys"), 1);
  EXPECT_EQ(p.db().query_int("SELECT count(*) FROM gpkg_spatial_ref_sys WHERE srs_id = 32636"), 1);
  EXPECT_EQ(p.db().query_text("SELECT srs_id FROM gpkg_contents WHERE table_name = 'markers'"), "32636");
  const SiteInfo site = p.site();
  EXPECT_EQ(site.name, "Trench 7");
  EXPECT_EQ(site.crs, "EPSG:32636");
  EXPECT_FALSE(site.origin_set);
  for (const char* sub : {"media", "cache", "products"}) EXPECT_TRUE(std::filesystem::is_directory(dir / "site" / sub));
}

TEST(Project, OpensWhileAnotherProgramReadsTheDatabase) {
  // QGIS keeps project.gpkg open with a read transaction; strata must still open
  // it (switching to WAL needs exclusive access, so it is only done once).
  // GDAL may also have put the file back into rollback-journal mode.
  test::ScratchDir dir("r");
  Project::create(dir / "site", {"EPSG:32636", "Trench 7", std::nullopt});
  Database reader(dir / "site" / "project.gpkg", false);
  reader.exec("PRAGMA journal_mode = DELETE");
  reader.exec("BEGIN");
  EXPECT_EQ(reader.query_int("SELECT count(*) FROM gpkg_contents WHERE table_name = 'markers'"), 1);
  {
    Project again = Project::open(dir / "site");
    EXPECT_EQ(again.site().name, "Trench 7");
  }
  reader.exec("COMMIT");
  // Once the other program is done, the next open restores WAL.
  Project later = Project::open(dir / "site");
  EXPECT_EQ(later.db().query_text("PRAGMA journal_mode"), "wal");
}

TEST(Project, MigrationsRunOnAnEmptyDatabaseAndAreIdempotent) {
  test::ScratchDir dir("m");
  Database db(dir / "empty.sqlite", true);
  // One per migration file (numbers may have gaps while branches land).
  EXPECT_EQ(apply_migrations(db), int(schema::migration_files().size()));
  EXPECT_EQ(apply_migrations(db), 0);
  EXPECT_EQ(db.query_text("SELECT value FROM strata_meta WHERE key = 'schema_version'"),
            std::to_string(latest_schema_version()));
}

// Schema 7 rebuilds observations to change its CHECK (detected|manual ->
// detected|clicked|guided): an older project opens with its ids kept, its 'manual'
// rows read as clicked, and a database that is still a valid GeoPackage.
TEST(Project, Migration7KeepsObservationIdsAndRenamesManualToClicked) {
  test::ScratchDir dir("m7");
  const auto site = dir / "site";
  {
    Project p = Project::create(site, {"EPSG:32636", "Trench 7", std::nullopt});
    auto& db = p.db();
    // Back to the observations table of schema 1 and a level below 7.
    db.exec("DROP TABLE observations");
    // Schema 8's, 9's, 10's, 13's and 14's tables, which a version-6 file does not have yet.
    for (const std::string table : {"unit_extents", "finds", "scans", "depth_frames", "depth_sequences", "observation_reviews"}) {
      db.exec("DELETE FROM gpkg_geometry_columns WHERE table_name = '" + table + "'");
      db.exec("DELETE FROM gpkg_contents WHERE table_name = '" + table + "'");
      db.exec("DROP TABLE " + table);
    }
    db.exec("ALTER TABLE markers DROP COLUMN sigma_stated");  // schema 15's
    db.exec("CREATE TABLE observations (id INTEGER PRIMARY KEY, marker_id INTEGER NOT NULL REFERENCES "
            "markers(fid) ON DELETE CASCADE, image_id INTEGER NOT NULL REFERENCES images(id) ON DELETE CASCADE, "
            "x REAL NOT NULL, y REAL NOT NULL, source TEXT NOT NULL CHECK (source IN ('detected', 'manual')), "
            "UNIQUE (marker_id, image_id, source))");
    db.exec("CREATE INDEX observations_image ON observations(image_id)");
    db.exec("INSERT INTO units(id, code, type) VALUES (1, '101', 'deposit')");
    db.exec("INSERT INTO layers(id, name, unit_id) VALUES (1, 'L1', 1)");
    db.exec("INSERT INTO images(id, layer_id, name, sha256, media_path, bytes, width, height, imported_at) "
            "VALUES (3, 1, 'a.jpg', 'ab', 'media/ab/ab.jpg', 10, 100, 80, '2024-01-01T00:00:00Z')");
    db.exec("INSERT INTO markers(fid, name, e, n, z, sigma_e, sigma_n, sigma_z) VALUES "
            "(2, 'GCP1', 734001, 4174002, 1450, 0.01, 0.01, 0.01)");
    db.exec("INSERT INTO observations(id, marker_id, image_id, x, y, source) VALUES "
            "(17, 2, 3, 10.5, 20.25, 'manual'), (42, 2, 3, 11.0, 21.0, 'detected')");
    db.exec("UPDATE strata_meta SET value = '6' WHERE key = 'schema_version'");
  }
  Project p = Project::open(site);
  auto& db = p.db();
  EXPECT_EQ(p.schema_version(), latest_schema_version());
  EXPECT_EQ(db.query_text("SELECT source FROM observations WHERE id = 17"), "clicked");
  EXPECT_EQ(db.query_text("SELECT source FROM observations WHERE id = 42"), "detected");
  EXPECT_EQ(db.query_text("SELECT x || ',' || y FROM observations WHERE id = 17"), "10.5,20.25");
  const auto obs = list_observations(db);
  ASSERT_EQ(obs.size(), 2u);
  EXPECT_EQ(obs[0].source == "clicked" ? obs[0].id : obs[1].id, 17);
  // The new sources are accepted, the old name is not.
  db.exec("INSERT INTO observations(marker_id, image_id, x, y, source) VALUES (2, 3, 12, 22, 'guided')");
  EXPECT_ANY_THROW(db.exec("INSERT INTO observations(marker_id, image_id, x, y, source) VALUES (2, 3, 1, 2, 'manual')"));
  // Still a consistent GeoPackage: foreign keys, integrity, identification, contents.
  EXPECT_EQ(db.query_int("SELECT count(*) FROM pragma_foreign_key_check"), 0);
  EXPECT_EQ(db.query_text("PRAGMA integrity_check"), "ok");
  EXPECT_EQ(db.query_int("PRAGMA application_id"), 0x47504B47);
  EXPECT_EQ(db.query_int("PRAGMA user_version"), 10200);
  EXPECT_EQ(db.query_int("SELECT count(*) FROM sqlite_master WHERE type = 'index' AND name = 'observations_image'"), 1);
  EXPECT_EQ(db.query_text("SELECT srs_id FROM gpkg_contents WHERE table_name = 'markers'"), "32636");
  // The finds table of schema 9 comes registered as a 3D point layer in the site CRS.
  EXPECT_EQ(db.query_text("SELECT geometry_type_name || ' ' || z || ' ' || srs_id FROM gpkg_geometry_columns "
                          "WHERE table_name = 'finds'"),
            "POINT 1 32636");
  // Deleting the marker still cascades to its observations.
  db.exec("DELETE FROM markers WHERE fid = 2");
  EXPECT_EQ(db.query_int("SELECT count(*) FROM observations"), 0);
}

// A project.gpkg someone else made or changed is refused at open with one line
// naming the file and what is wrong (found by fuzzing, tests/fuzz/corpus/project):
// a schema version that is not a number, a GeoPackage of another program, a table
// or a column of strata's that is gone.
TEST(Project, RefusesAlteredOrForeignDatabasesWithOneClearError) {
  test::ScratchDir dir("hostile");
  const auto site = dir / "site";
  Project::create(site, {"EPSG:32636", "Trench 7", std::nullopt});
  const auto db_path = site / "project.gpkg";
  std::filesystem::copy_file(db_path, dir / "good.gpkg");
  auto error_after = [&](const std::string& sql) -> std::string {
    std::filesystem::copy_file(dir / "good.gpkg", db_path, std::filesystem::copy_options::overwrite_existing);
    {
      Database db(db_path, false);
      db.exec(sql);
    }
    try {
      Project::open(site);
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(db_path.string()), std::string::npos) << e.what();
      return e.what();
    }
    return "opened";
  };
  EXPECT_NE(error_after("UPDATE strata_meta SET value = 'seven' WHERE key = 'schema_version'")
                .find("the schema version in strata_meta is 'seven', not a version number"),
            std::string::npos);
  EXPECT_NE(error_after("DELETE FROM strata_meta").find("the schema version in strata_meta is missing"),
            std::string::npos);
  EXPECT_NE(error_after("DROP TABLE strata_meta").find("a GeoPackage, but not a strata project"), std::string::npos);
  EXPECT_NE(error_after("DROP TABLE site").find("strata's table 'site' is missing"), std::string::npos);
  EXPECT_NE(error_after("ALTER TABLE markers RENAME COLUMN kind TO role")
                .find("strata's table 'markers' has no column 'kind'"),
            std::string::npos);
  EXPECT_NE(error_after("UPDATE strata_meta SET value = '99' WHERE key = 'schema_version'")
                .find("schema version 99 is newer than this strata understands"),
            std::string::npos);
  // What other programs add (a QGIS style table, a column) is no reason to refuse.
  EXPECT_EQ(error_after("CREATE TABLE layer_styles (id INTEGER PRIMARY KEY, styleQML TEXT); "
                        "ALTER TABLE units ADD COLUMN excavator TEXT"),
            "opened");
}

TEST(Project, RefusesGeographicAndUnknownCrsAndLeavesNothingBehind) {
  test::ScratchDir dir("g");
  EXPECT_THROW(Project::create(dir / "a", {"EPSG:4326", "", std::nullopt}), CrsError);
  EXPECT_FALSE(std::filesystem::exists(dir / "a"));
  EXPECT_THROW(Project::create(dir / "b", {"EPSG:999999", "", std::nullopt}), CrsError);
  EXPECT_FALSE(std::filesystem::exists(dir / "b"));
}

TEST(Project, RefusesToOverwriteAProject) {
  test::ScratchDir dir("o");
  Project::create(dir / "s", {"EPSG:32636", "", std::nullopt});
  EXPECT_THROW(Project::create(dir / "s", {"EPSG:32636", "", std::nullopt}), InputError);
}

TEST(Project, OriginIsRoundedAndFixedOnce) {
  test::ScratchDir dir("origin");
  Project p = Project::create(dir / "s", {"EPSG:32636", "", std::nullopt});
  p.set_origin_if_unset({734123.456, 4174567.891, 1450.7});
  EXPECT_EQ(p.site().origin, Eigen::Vector3d(734100, 4174500, 1450));
  p.set_origin_if_unset({1, 2, 3});
  EXPECT_EQ(p.site().origin, Eigen::Vector3d(734100, 4174500, 1450));
}

TEST(Project, TransactionRollsBackWhenNotCommitted) {
  test::ScratchDir dir("tx");
  Project p = Project::create(dir / "s", {"EPSG:32636", "", std::nullopt});
  {
    Transaction tx(p.db());
    insert_unit(p.db(), {0, "101", "deposit", ""});
  }
  EXPECT_FALSE(find_unit(p.db(), "101"));
  try {
    Transaction tx(p.db());
    insert_unit(p.db(), {0, "101", "deposit", ""});
    insert_unit(p.db(), {0, "101", "deposit", ""});  // duplicate: throws
    tx.commit();
    FAIL() << "duplicate unit accepted";
  } catch (const InputError&) {
  }
  EXPECT_FALSE(find_unit(p.db(), "101"));
}

TEST(Gpkg, PointBlobHasHeaderAndIsoWkb) {
  const auto blob = gpkg_point_z(32636, {1.0, 2.0, 3.0});
  ASSERT_EQ(blob.size(), 8u + 5u + 24u);
  EXPECT_EQ(blob[0], 'G');
  EXPECT_EQ(blob[1], 'P');
  EXPECT_EQ(blob[3], 0x01);  // little endian, no envelope
  EXPECT_EQ(blob[4] | (blob[5] << 8) | (blob[6] << 16), 32636);
  EXPECT_EQ(blob[9] | (blob[10] << 8), 1001);  // Point Z
}

}  // namespace
}  // namespace strata
