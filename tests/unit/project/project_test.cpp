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
