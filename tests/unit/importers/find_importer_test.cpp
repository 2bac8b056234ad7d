#include "core/error.hpp"
#include "importer_fixture.hpp"
#include "importers/finds/find_importer.hpp"

#include <GeographicLib/UTMUPS.hpp>

namespace strata {
namespace {

namespace fs = std::filesystem;
using test::ImporterTest;

// GeographicLib and PROJ agree to well under a millimetre.
constexpr double kCrsAgreementMetres = 1e-3;

class FindImportTest : public ImporterTest {
 protected:
  void SetUp() override {
    ImporterTest::SetUp();
    Transaction tx(db());
    insert_unit(db(), {0, "102", "deposit", ""});
    tx.commit();
  }
  void expect_refused(const std::string& text, const std::string& expected, FindImportOptions options = {}) {
    expect_import_refused(text, expected, [&](const fs::path& f) { import_finds(project(), options, f); });
  }
};

TEST_F(FindImportTest, CsvWithHeaderQuotesAndAnyDelimiter) {
  auto s = import_finds(project(), {}, write("a.csv", "id,E,N,Z,unit,type,description\n"
                                                      "F1,734012.1,4174018.2,1450.1,101,pottery,\"rim sherd, red slip\"\n"
                                                      "F2,734012.5,4174018.4,1450.0,102,bone,\n"));
  EXPECT_EQ(s.finds_new, 2);
  EXPECT_EQ(s.source_crs, "EPSG:32636");
  const auto f1 = find_find(db(), "F1");
  ASSERT_TRUE(f1);
  EXPECT_EQ(f1->unit, "101");
  EXPECT_EQ(f1->type, "pottery");
  EXPECT_EQ(f1->description, "rim sherd, red slip");
  EXPECT_EQ(f1->position, Eigen::Vector3d(734012.1, 4174018.2, 1450.1));
  EXPECT_EQ(f1->source, "a.csv");
  EXPECT_FALSE(f1->imported_at.empty());
  EXPECT_EQ(find_find(db(), "F2")->description, "");
  // Columns in another order and other names; semicolons.
  s = import_finds(project(), {}, write("b.txt", "# total station\ncontext;find;x;y;h\n102;F3;734013;4174019;1449.9\n"));
  EXPECT_EQ(s.finds_new, 1);
  EXPECT_EQ(find_find(db(), "F3")->unit, "102");
  EXPECT_EQ(find_find(db(), "F3")->position, Eigen::Vector3d(734013, 4174019, 1449.9));
  // No header, spaces: the description is the rest of the line.
  s = import_finds(project(), {}, write("c.txt", "F4 734013.5 4174019.5 1449.8 101 lithic burnt flint flake\n"));
  EXPECT_EQ(s.finds_new, 1);
  EXPECT_EQ(find_find(db(), "F4")->type, "lithic");
  EXPECT_EQ(find_find(db(), "F4")->description, "burnt flint flake");
  // The same file again: nothing changes. A GeoPackage 3D point for each, with an extent.
  s = import_finds(project(), {}, scratch() / "in" / "a.csv");
  EXPECT_EQ(s.finds_unchanged, 2);
  EXPECT_EQ(db().query_int("SELECT count(*) FROM finds WHERE geom IS NOT NULL"), 4);
  EXPECT_EQ(db().query_int("SELECT max_x > 734012 FROM gpkg_contents WHERE table_name = 'finds'"), 1);
}

TEST_F(FindImportTest, EveryErrorNamesFileLineAndValueAndImportsNothing) {
  import_finds(project(), {}, write("ok.csv", "F1,734012,4174018,1450,101\n"));
  expect_refused("id,E,N,Z,unit\nF5,734012,4174018,1450,101\nF6,734012,abc,1450,101\n",
                 "importer.finds.csv: " + (scratch() / "in" / "bad.csv").string() + ":3: N 'abc' is not a number");
  expect_refused("F5,734012,4174018,1450\n", "bad.csv:1: expected id,E,N,Z,unit[,type][,description], found 4 fields");
  expect_refused("F5,734012,4174018,inf,101\n", "bad.csv:1: Z 'inf' is not a finite number");
  expect_refused("id,E,N,unit\nF5,1,2,101\n", "bad.csv:1: the header has no Z column");
  expect_refused("F5,734012,4174018,1450,101\n\nF6,734012,4174018,1450,999\n",
                 "bad.csv:3: find 'F6': unit '999' is not in the project (units 101, 102); add it with 'strata unit add'");
  expect_refused("F5,734012,4174018,1450,101\nF5,734012,4174018.5,1450,101\n",
                 "bad.csv:2: find 'F5' appears again (unit 101 at (734012.0000, 4174018.5000, 1450.0000)) unlike on line 1");
  expect_refused(",734012,4174018,1450,101\n", "bad.csv:1: the find id is empty");
  expect_refused("F5,734012,4174018,1450,\n", "bad.csv:1: expected id,E,N,Z,unit");
  // A find already in the project with another position needs --update.
  expect_refused("F2,734012,4174018,1450,101\nF1,734012,4174018,1450.2,101\n",
                 "bad.csv:2: find 'F1' is already in the project (unit 101 at (734012.0000, 4174018.0000, 1450.0000)), "
                 "this gives unit 101 at (734012.0000, 4174018.0000, 1450.2000); use --update");
  FindImportOptions unknown_crs;
  unknown_crs.crs = "EPSG:999999";
  expect_refused("F5,734012,4174018,1450,101\n", "unknown CRS 'EPSG:999999'", unknown_crs);
}

TEST_F(FindImportTest, UpdateReplacesAChangedFind) {
  import_finds(project(), {}, write("a.csv", "F1,734012,4174018,1450,101,bone\n"));
  FindImportOptions update;
  update.update = true;
  const auto s = import_finds(project(), update, write("b.csv", "F1,734012,4174018,1449.9,102,bone\n"));
  EXPECT_EQ(s.finds_updated, 1);
  const auto f = find_find(db(), "F1");
  EXPECT_EQ(f->unit, "102");
  EXPECT_DOUBLE_EQ(f->position.z(), 1449.9);
  EXPECT_EQ(f->source, "b.csv");
  EXPECT_EQ(db().query_int("SELECT count(*) FROM finds"), 1);
}

TEST_F(FindImportTest, LonLatFindsAreTransformedLikeGeographicLib) {
  const double lat = 37.7012345, lon = 35.6543210;
  FindImportOptions o;
  o.crs = "EPSG:4326";
  const auto s =
      import_finds(project(), o, write("ll.csv", fmt::format("id,lon,lat,h,unit\nF1,{:.9f},{:.9f},1450.25,101\n", lon, lat)));
  EXPECT_EQ(s.source_crs, "EPSG:4326");
  int zone;
  bool north;
  double x, y;
  GeographicLib::UTMUPS::Forward(lat, lon, zone, north, x, y, 36);
  const auto f = find_find(db(), "F1");
  ASSERT_TRUE(f);
  EXPECT_NEAR(f->position.x(), x, kCrsAgreementMetres);
  EXPECT_NEAR(f->position.y(), y, kCrsAgreementMetres);
  EXPECT_DOUBLE_EQ(f->position.z(), 1450.25);
  // find add converts the same way.
  FindRecord typed;
  typed.id = "F2";
  typed.unit = "102";
  typed.position = {lon, lat, 1450.0};
  add_find(project(), o, typed);
  EXPECT_NEAR(find_find(db(), "F2")->position.x(), x, kCrsAgreementMetres);
  EXPECT_NEAR(find_find(db(), "F2")->position.y(), y, kCrsAgreementMetres);
}

TEST_F(FindImportTest, FindAddChecksLikeALineOfTheFile) {
  FindRecord f;
  f.id = "F9";
  f.unit = "103";
  f.position = {734012, 4174018, 1450};
  const std::string before = dump();
  try {
    add_find(project(), {}, f);
    ADD_FAILURE() << "unknown unit accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("find add: find 'F9': unit '103' is not in the project"), std::string::npos)
        << e.what();
  }
  f.unit = "101";
  f.position.z() = std::nan("");
  EXPECT_THROW(add_find(project(), {}, f), InputError);
  EXPECT_EQ(dump(), before);
  f.position.z() = 1450;
  EXPECT_EQ(add_find(project(), {}, f).finds_new, 1);
  EXPECT_EQ(find_find(db(), "F9")->source, "find add");
  EXPECT_EQ(add_find(project(), {}, f).finds_unchanged, 1);
}

}  // namespace
}  // namespace strata
