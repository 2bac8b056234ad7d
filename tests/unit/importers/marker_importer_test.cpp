#include "core/error.hpp"
#include "importer_fixture.hpp"
#include "importers/markers/marker_importer.hpp"
#include "importers/photos/photo_importer.hpp"

#include <GeographicLib/UTMUPS.hpp>

namespace strata {
namespace {

namespace fs = std::filesystem;
using test::ImporterTest;

// GeographicLib and PROJ agree to well under a millimetre (markers are surveyed to about 1 mm).
constexpr double kCrsAgreementMetres = 1e-3;

class MarkerImportTest : public ImporterTest {
 protected:
  void expect_refused(const std::string& text, const std::string& expected, MarkerImportOptions options = {}) {
    expect_import_refused(text, expected, [&](const fs::path& f) { import_markers(project(), options, f); });
  }
};

TEST_F(MarkerImportTest, CsvWithAndWithoutHeaderAndAnyDelimiter) {
  auto s = import_markers(project(), {}, write("a.csv", "GCP1,734001.1,4174002.2,1450.3\n"
                                                        "GCP2,734005.1,4174002.2,1450.1,0.003,check\n"));
  EXPECT_EQ(s.markers_new, 2);
  auto m = find_marker(db(), "GCP2");
  ASSERT_TRUE(m);
  EXPECT_EQ(m->kind, "check");
  EXPECT_DOUBLE_EQ(m->sigma.x(), 0.003);
  EXPECT_DOUBLE_EQ(find_marker(db(), "GCP1")->sigma.z(), 0.01);

  s = import_markers(project(), {}, write("b.txt", "# total station export\nname;E;N;Z;kind\n"
                                                   "GCP3;734003.0;4174001.0;1449.9;control\n"));
  EXPECT_EQ(s.markers_new, 1);
  s = import_markers(project(), {}, write("c.txt", "GCP4\t734003.5\t4174004.0\t1450.0\n"));
  EXPECT_EQ(s.markers_new, 1);
  s = import_markers(project(), {}, write("d.txt", "GCP5   734002.5   4174004.5   1450.0\n"));
  EXPECT_EQ(s.markers_new, 1);
  // The site origin is fixed from the first markers, rounded.
  EXPECT_EQ(project().site().origin, Eigen::Vector3d(734000, 4174000, 1450));
  // Same file again: nothing changes.
  s = import_markers(project(), {}, scratch() / "in" / "a.csv");
  EXPECT_EQ(s.markers_unchanged, 2);
  // markers feature table carries the site SRS and an extent.
  EXPECT_EQ(db().query_int("SELECT count(*) FROM markers WHERE geom IS NOT NULL"), 5);
  EXPECT_EQ(db().query_int("SELECT min_x IS NOT NULL FROM gpkg_contents WHERE table_name='markers'"), 1);
}

TEST_F(MarkerImportTest, EveryErrorNamesFileAndLine) {
  expect_refused("GCP1,734001,4174002,1450\nGCP2,734001,abc,1450\n", "bad.csv:2: N 'abc' is not a number");
  expect_refused("GCP1,734001,4174002\n", "bad.csv:1: expected name,E,N,Z[,sigma][,kind], found 3 fields");
  expect_refused("GCP1,734001,4174002,1450\n\nGCP1,734001,4174002.5,1450\n",
                 "bad.csv:3: marker 'GCP1' appears again with different coordinates");
  expect_refused("GCP1,734001,4174002,nan\n", "bad.csv:1: Z 'nan' is not a finite number");
  expect_refused("GCP1,734001,4174002,1450,0.01,maybe\n", "bad.csv:1: kind 'maybe'");
  expect_refused("name,E,Z\nGCP1,1,2\n", "bad.csv:1: the header has no N column");
  MarkerImportOptions unknown_crs;
  unknown_crs.crs = "EPSG:999999";
  expect_refused("GCP1,734001,4174002,1450\n", "unknown CRS 'EPSG:999999'", unknown_crs);
}

TEST_F(MarkerImportTest, ChangedCoordinatesNeedUpdate) {
  import_markers(project(), {}, write("a.csv", "GCP1,734001,4174002,1450\n"));
  expect_refused("GCP1,734001,4174002.2,1450\n", "already in the project");
  MarkerImportOptions update;
  update.update = true;
  const auto s = import_markers(project(), update, write("b.csv", "GCP1,734001,4174002.2,1450\n"));
  EXPECT_EQ(s.markers_updated, 1);
  EXPECT_DOUBLE_EQ(find_marker(db(), "GCP1")->position.y(), 4174002.2);
}

TEST_F(MarkerImportTest, LatLonMarkersAreTransformedLikeGeographicLib) {
  const double lat = 37.7012345, lon = 35.6543210;
  MarkerImportOptions o;
  o.crs = "EPSG:4326";
  import_markers(project(), o, write("ll.csv", fmt::format("name,lon,lat,h\nGCP1,{:.9f},{:.9f},1450.25\n", lon, lat)));
  int zone;
  bool north;
  double x, y;
  GeographicLib::UTMUPS::Forward(lat, lon, zone, north, x, y, 36);
  const auto m = find_marker(db(), "GCP1");
  ASSERT_TRUE(m);
  EXPECT_NEAR(m->position.x(), x, kCrsAgreementMetres);
  EXPECT_NEAR(m->position.y(), y, kCrsAgreementMetres);
  EXPECT_DOUBLE_EQ(m->position.z(), 1450.25);
}

TEST_F(MarkerImportTest, OdmObservationOfAnUnknownImageIsRefused) {
  import_photos(project(), {"L1", false}, {make_photo("IMG_1.jpg", 1)});
  const fs::path f = write("gcp_list.txt",
                           "EPSG:32636\n"
                           "734001.0 4174002.0 1450.0 10.5 20.5 IMG_1.jpg GCP1\n"
                           "734001.0 4174002.0 1450.0 11.5 21.5 IMG_2.jpg GCP1\n");
  const std::string before = dump();
  try {
    import_markers(project(), {}, f);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("gcp_list.txt:3: image 'IMG_2.jpg' is not in the project"),
              std::string::npos)
        << e.what();
  }
  EXPECT_EQ(dump(), before);
}

TEST_F(MarkerImportTest, OdmObservationsOfMissingImagesCanBeSkipped) {
  import_photos(project(), {"L1", false}, {make_photo("IMG_1.jpg", 1)});
  const fs::path f = write("gcp_list.txt",
                           "EPSG:32636\n"
                           "734001.0 4174002.0 1450.0 10.5 20.5 IMG_1.jpg GCP1\n"
                           "734001.0 4174002.0 1450.0 11.5 21.5 IMG_2.jpg GCP1\n");
  MarkerImportOptions o;
  o.skip_missing_images = true;
  const auto s = import_markers(project(), o, f);
  EXPECT_EQ(s.observations_new, 1);
  ASSERT_EQ(s.skipped.size(), 1u);
  EXPECT_NE(s.skipped[0].find("gcp_list.txt:3: image 'IMG_2.jpg'"), std::string::npos) << s.skipped[0];

  // A file none of whose photos is in the project is still refused, and changes nothing.
  const fs::path other = write("other.txt",
                               "EPSG:32636\n"
                               "734001.0 4174002.0 1450.0 10.5 20.5 IMG_8.jpg GCP2\n"
                               "734001.0 4174002.0 1450.0 11.5 21.5 IMG_9.jpg GCP2\n");
  const std::string before = dump();
  try {
    import_markers(project(), o, other);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("none of the 2 observed images is in the project"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(dump(), before);
}

TEST_F(MarkerImportTest, OdmFileOfTheCoprSet) {
  const fs::path dir = test::shared_data_dir() / "copr";
  if (!fs::exists(dir)) GTEST_SKIP() << "shared data not present: " << dir;
  std::vector<fs::path> photos;
  for (const auto& e : fs::directory_iterator(dir / "images")) photos.push_back(e.path());
  import_photos(project(), {"L1", false}, photos);
  // The copr survey is in UTM 11N; a site in 11N takes it without transformation.
  test::ScratchDir other("copr");
  Project p = Project::create(other.path() / "copr", {"EPSG:32611", "", std::nullopt});
  {
    Transaction tx(p.db());
    insert_unit(p.db(), {0, "1", "deposit", ""});
    insert_layer(p.db(), {0, "L1", "1", std::nullopt});
    tx.commit();
  }
  import_photos(p, {"L1", false}, photos);
  const auto s = import_markers(p, {}, dir / "gcp_list.txt");
  EXPECT_EQ(s.format, "odm");
  EXPECT_EQ(s.markers_new, 10);
  EXPECT_EQ(s.observations_new, 27);
  EXPECT_EQ(list_markers(p.db()).size(), 10u);
  EXPECT_EQ(list_observations(p.db()).size(), 27u);
  const auto m = find_marker(p.db(), "gcp02");
  ASSERT_TRUE(m);
  EXPECT_DOUBLE_EQ(m->position.x(), 235269.88);
  EXPECT_DOUBLE_EQ(m->position.y(), 3811198.11);
}

}  // namespace
}  // namespace strata
