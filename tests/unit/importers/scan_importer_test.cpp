// importer.scans: scans stored like photos, registration states, and every bad file
// refused with its position while the project stays exactly as it was.
#include "core/error.hpp"
#include "core/hash.hpp"
#include "importer_fixture.hpp"
#include "importers/scans/scan_importer.hpp"
#include "project/scan_records.hpp"
#include "scan_files.hpp"

#include <GeographicLib/UTMUPS.hpp>
#include <Eigen/Geometry>

namespace strata {
namespace {

namespace fs = std::filesystem;
using namespace test;

// GeographicLib and PROJ agree to well under a millimetre.
constexpr double kCrsAgreementMetres = 1e-3;
// Boxes computed two ways in double precision from the same points.
constexpr double kBoxTolerance = 1e-9;
constexpr int kPoints = 6;

class ScanImportTest : public ImporterTest {
 protected:
  fs::path file(const std::string& name, const std::string& bytes) {
    const fs::path p = scratch() / "in" / name;
    write_bytes(p, bytes);
    return p;
  }
  ScanImportOptions layer1() {
    ScanImportOptions o;
    o.layer = "L1";
    return o;
  }
  void fix_origin(const Eigen::Vector3d& near) {
    Transaction tx(db());
    project().set_origin_if_unset(near);
    tx.commit();
  }
  // Imports `files` and expects one InputError containing every one of `expected`,
  // with the database and media/ exactly as before.
  void expect_refused(const std::vector<fs::path>& files, const std::vector<std::string>& expected,
                      const ScanImportOptions& options) {
    const std::string rows = dump();
    const std::string media = tree_fingerprint(project().media_dir());
    try {
      import_scans(project(), options, files);
      ADD_FAILURE() << "accepted " << files.front();
    } catch (const Error& e) {
      for (const auto& want : expected)
        EXPECT_NE(std::string(e.what()).find(want), std::string::npos) << "message: " << e.what() << "\nwanted: " << want;
    }
    EXPECT_EQ(dump(), rows);
    EXPECT_EQ(tree_fingerprint(project().media_dir()), media);
  }
  void expect_refused(const fs::path& f, const std::vector<std::string>& expected) {
    expect_refused({f}, expected, layer1());
  }
  const std::vector<TestPoint> truth_ = sample_points(kPoints);
};

TEST_F(ScanImportTest, UnregisteredScanIsStoredUnchangedWithItsFigures) {
  PlyLayout layout;
  layout.normals = true;
  const fs::path ply = file("station1.ply", ply_bytes(truth_, layout));
  const auto s = import_scans(project(), layer1(), {ply});
  ASSERT_EQ(s.imported.size(), 1u);
  EXPECT_EQ(s.imported[0].info.points, std::uint64_t(kPoints));
  EXPECT_EQ(s.imported[0].registration, ScanRegistration::unregistered);
  EXPECT_FALSE(s.imported[0].bounds);

  const auto rows = list_scans(db());
  ASSERT_EQ(rows.size(), 1u);
  const ScanRecord& r = rows[0];
  EXPECT_EQ(r.layer_id, require_layer(db(), "L1").id);
  EXPECT_EQ(r.name, "station1.ply");
  EXPECT_EQ(r.sha256, sha256_file(ply));
  EXPECT_EQ(r.media_path, "media/" + r.sha256.substr(0, 2) + "/" + r.sha256 + ".ply");
  EXPECT_EQ(sha256_file(project().dir() / r.media_path), r.sha256);  // the original bytes, unmodified
  EXPECT_EQ(r.bytes, std::int64_t(fs::file_size(ply)));
  EXPECT_EQ(r.format, "ply binary_little_endian");
  EXPECT_EQ(r.points, kPoints);
  EXPECT_TRUE(r.has_colour && r.has_intensity && r.has_normals);
  EXPECT_EQ(r.sigma_m, kDefaultScanSigmaM);
  EXPECT_EQ(r.registration, ScanRegistration::unregistered);
  EXPECT_FALSE(r.crs || r.transform || r.bounds);
  EXPECT_FALSE(r.imported_at.empty());
  EXPECT_EQ(list_scans(db(), require_layer(db(), "L2").id).size(), 0u);
}

TEST_F(ScanImportTest, SameContentAgainIsAlreadyPresentAndRefusedInAnotherLayer) {
  const fs::path xyz = file("a.xyz", xyz_text(truth_, true, " "));
  ASSERT_EQ(import_scans(project(), layer1(), {xyz}).imported.size(), 1u);
  // The same bytes under another name, in the same batch twice.
  const fs::path copy = file("copy.xyz", xyz_text(truth_, true, " "));
  const auto again = import_scans(project(), layer1(), {xyz, copy});
  EXPECT_TRUE(again.imported.empty());
  ASSERT_EQ(again.already_present.size(), 2u);
  EXPECT_NE(again.already_present[0].find("already imported in layer L1"), std::string::npos);
  EXPECT_NE(again.already_present[1].find("same content as"), std::string::npos);
  EXPECT_EQ(list_scans(db()).size(), 1u);
  ScanImportOptions l2 = layer1();
  l2.layer = "L2";
  expect_refused({xyz}, {xyz.string(), "the same scan is already in layer L1"}, l2);
  // A different scan of the same name in the same layer.
  fs::create_directories(scratch() / "other");
  const fs::path other = scratch() / "other" / "a.xyz";
  write_text(other, xyz_text(sample_points(2), false, " "));
  expect_refused(other, {"a different scan named 'a.xyz' is already in layer L1"});
}

TEST_F(ScanImportTest, SurveyScanInTheSiteCrsFixesTheOriginAndRecordsItsBox) {
  ScanImportOptions o = layer1();
  o.crs = "EPSG:32636";
  o.sigma_m = 0.003;
  const auto s = import_scans(project(), o, {file("s.las", las_bytes(truth_, 4, 6))});
  ASSERT_EQ(s.imported.size(), 1u);
  // No origin yet: the scan fixes it, rounded (100 m, 1 m) from its box's centre.
  const SiteInfo site = project().site();
  EXPECT_TRUE(site.origin_set);
  EXPECT_EQ(site.origin, Eigen::Vector3d(734000, 4174000, 1450));
  const ScanRecord r = list_scans(db()).at(0);
  EXPECT_EQ(r.registration, ScanRegistration::survey);
  EXPECT_EQ(r.crs, "EPSG:32636");
  EXPECT_EQ(r.sigma_m, 0.003);
  EXPECT_EQ(r.format, "las 1.4 point format 6");
  ASSERT_TRUE(r.bounds);
  const Eigen::Vector3d lo(12.125, 4174018.5 - 0.125 * (kPoints - 1) - 4174000, 0.0);
  const Eigen::Vector3d hi(12.125 + 0.25 * (kPoints - 1), 18.5, 0.001 * (kPoints - 1) * (kPoints - 1));
  EXPECT_LT((r.bounds->min - lo).cwiseAbs().maxCoeff(), 0.5 * kLasScale);
  EXPECT_LT((r.bounds->max - hi).cwiseAbs().maxCoeff(), 0.5 * kLasScale);
}

TEST_F(ScanImportTest, SurveyScanInAnotherCrsIsTransformedWithProj) {
  fix_origin({734000, 4174000, 1400});
  // A lon/lat rectangle (its corners and centre, two heights) about the site.
  double lat0 = 0, lon0 = 0;
  GeographicLib::UTMUPS::Reverse(36, true, 734010.0, 4174010.0, lat0, lon0);
  std::vector<TestPoint> geo = sample_points(5);
  const double dlon[] = {0, 4e-4, 0, 4e-4, 2e-4}, dlat[] = {0, 0, 3e-4, 3e-4, 1.5e-4};
  for (int i = 0; i < 5; ++i) geo[std::size_t(i)].position = {lon0 + dlon[i], lat0 + dlat[i], 1450.0 + 2.0 * (i % 2)};
  ScanImportOptions o = layer1();
  o.crs = "EPSG:4326";
  import_scans(project(), o, {file("geo.xyz", xyz_text(geo, false, ","))});
  const ScanRecord r = list_scans(db()).at(0);
  EXPECT_EQ(r.crs, "EPSG:4326");
  ASSERT_TRUE(r.bounds);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(HUGE_VAL), hi = -lo;
  for (const auto& p : geo) {
    int zone = 0;
    bool north = false;
    double e = 0, n = 0;
    GeographicLib::UTMUPS::Forward(p.position.y(), p.position.x(), zone, north, e, n, 36);
    const Eigen::Vector3d site(e - 734000, n - 4174000, p.position.z() - 1400);
    lo = lo.cwiseMin(site);
    hi = hi.cwiseMax(site);
  }
  EXPECT_LT((r.bounds->min - lo).cwiseAbs().maxCoeff(), kCrsAgreementMetres);
  EXPECT_LT((r.bounds->max - hi).cwiseAbs().maxCoeff(), kCrsAgreementMetres);
  // Coordinates far from the site in the CRS named: refused, nothing imported.
  o.crs = "EPSG:32637";  // the next UTM zone: hundreds of km east
  expect_refused({file("far.xyz", xyz_text(truth_, false, " "))}, {"far.xyz", "km from the site origin"}, o);
}

TEST_F(ScanImportTest, TransformedScanRecordsTheExactBoxOfItsPointsInTheSiteFrame) {
  // Scanner frame: a few metres around the station.
  std::vector<TestPoint> local = sample_points(kPoints);
  for (auto& p : local) p.position -= Eigen::Vector3d(734012, 4174016, 1449);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.2, -0.1, 1.0).normalized()).toRotationMatrix();
  const double scale = 1.5;
  const Eigen::Vector3d t(10.0, 20.0, 3.0);
  std::string matrix = "# scanner -> site frame\n";
  for (int r = 0; r < 3; ++r)
    matrix += fmt::format("{:.17g} {:.17g} {:.17g} {:.17g}\n", scale * R(r, 0), scale * R(r, 1), scale * R(r, 2), t[r]);
  matrix += "0 0 0 1\n";
  const fs::path pose = file("pose.txt", matrix);
  const fs::path scan = file("local.pts", pts_text(local, 4));
  ScanImportOptions o = layer1();
  o.transform = pose;
  // The site frame needs its origin first.
  expect_refused({scan}, {"--transform", "the site frame has no origin yet"}, o);
  fix_origin({734000, 4174000, 1400});
  import_scans(project(), o, {scan});
  const ScanRecord r = list_scans(db()).at(0);
  EXPECT_EQ(r.registration, ScanRegistration::transform);
  ASSERT_TRUE(r.transform);
  EXPECT_LT((r.transform->topLeftCorner<3, 3>() - scale * R).cwiseAbs().maxCoeff(), kBoxTolerance);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(HUGE_VAL), hi = -lo;
  for (const auto& p : local) {
    const Eigen::Vector3d q = scale * (R * p.position) + t;
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
  }
  ASSERT_TRUE(r.bounds);
  EXPECT_LT((r.bounds->min - lo).cwiseAbs().maxCoeff(), kBoxTolerance);
  EXPECT_LT((r.bounds->max - hi).cwiseAbs().maxCoeff(), kBoxTolerance);
}

TEST_F(ScanImportTest, TransformFilesThatAreNotSimilaritiesAreRefusedNamingTheFile) {
  fix_origin({734000, 4174000, 1400});
  const fs::path scan = file("s.xyz", xyz_text(sample_points(3), false, " "));
  struct Case {
    std::string text, expected;
  };
  for (const Case& k : {Case{"1 0 0 0\n0 1 0 0\n0 0 1 0\n", "expected 16 numbers (a 4x4 matrix, row-major), found 12"},
                        Case{"1 0.2 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n", "the 3x3 part is not a scale times a rotation"},
                        Case{"-1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n", "has determinant -1 (a reflection"},
                        Case{"1 0 0 0\n0 1 0 0\n0 0 1 0\n0.5 0 0 1\n", "the last row is 0.5 0 0 1"},
                        Case{"1 0 0 0\n0 1 x 0\n", "pose.txt: line 2: matrix entry 'x' is not a number"}}) {
    ScanImportOptions o = layer1();
    o.transform = file("pose.txt", k.text);
    expect_refused({scan}, {"importer.scans.transform: " + o.transform->string(), k.expected}, o);
  }
}

TEST_F(ScanImportTest, OptionsAreCheckedBeforeAnyFileIsRead) {
  const fs::path scan = file("s.xyz", xyz_text(sample_points(3), false, " "));
  ScanImportOptions o = layer1();
  o.sigma_m = 0;
  expect_refused({scan}, {"--sigma 0 must be a range noise in metres > 0"}, o);
  o = layer1();
  o.crs = "EPSG:32636";
  o.transform = scan;
  expect_refused({scan}, {"--crs and --transform exclude each other"}, o);
  o = layer1();
  o.crs = "EPSG:999999";
  expect_refused({scan}, {"importer.scans: --crs", "EPSG:999999"}, o);
  o = layer1();
  o.layer = "L9";
  expect_refused({scan}, {"L9"}, o);
}

// One bad file of each format: one message naming the file and where it goes
// wrong; nothing imported, even the good file given before it.
TEST_F(ScanImportTest, EveryBadFileIsRefusedNamingFileAndPositionAndImportsNothing) {
  const fs::path good = file("good.xyz", xyz_text(truth_, false, " "));
  auto refused = [&](const fs::path& bad, const std::vector<std::string>& expected) {
    std::vector<std::string> all{bad.string()};
    all.insert(all.end(), expected.begin(), expected.end());
    expect_refused({good, bad}, all, layer1());
  };
  // PLY: cut short (binary, byte offset), NaN (ascii, line), wrong header.
  const std::string ply = ply_bytes(truth_, PlyLayout{});
  const std::string cut_ply = ply.substr(0, ply.size() - 10);
  refused(file("cut.ply", cut_ply), {"importer.scans.ply", fmt::format("byte {}: the file ends inside vertex 5 of the 6 "
                                                                       "declared", cut_ply.size())});
  PlyLayout ascii;
  ascii.encoding = PlyEncoding::ascii;
  std::string nan_ply = ply_bytes(truth_, ascii);
  // Header lines 1-15, vertex 0 on line 16: the x of vertex 1 (line 17) becomes nan.
  const std::size_t line17 = nan_ply.find('\n', nan_ply.find("end_header\n") + 11) + 1;
  nan_ply.replace(line17, nan_ply.find(' ', line17) - line17, "nan");
  refused(file("nan.ply", nan_ply), {"line 17: point 1: coordinate x is nan"});
  refused(file("wrong.ply", "ply\nformat binary_middle_endian 1.0\nend_header\n"),
          {"line 2: unknown encoding 'binary_middle_endian'"});
  refused(file("noxyz.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n1 2\n"),
          {"line 3: the vertex element lacks an x, y or z property"});
  refused(file("notply.ply", "PLY\n"), {"line 1: not a PLY file"});
  // PTS: fewer points than declared, NaN, no count.
  refused(file("cut.pts", "5\n1 2 3\n4 5 6\n"), {"importer.scans.pts", "line 3: the file ends after 2 of the 5 points "
                                                                       "declared on line 1"});
  refused(file("nan.pts", "2\n1 2 3 10\n1 nan 3 11\n"), {"line 3: point 1: coordinate y is nan"});
  refused(file("nocount.pts", "1 2 3\n"), {"line 1: expected the point count of a PTS block"});
  // XYZ: infinite, a field count unlike the first line's, not a number, empty.
  refused(file("inf.xyz", "# scan\n1 2 3\n4 5 inf\n"), {"importer.scans.xyz", "line 3: point 1: coordinate z is inf"});
  refused(file("ragged.xyz", "1 2 3 4 5 6\n1 2 3\n"), {"line 2: 3 fields, but the first point (line 1) has 6"});
  refused(file("word.xyz", "1 2 3\n1 two 3\n"), {"line 2: y 'two' is not a number"});
  refused(file("empty.xyz", "# nothing here\n\n"), {"the file holds no points"});
  // LAS: cut short, an unknown version, not LAS at all.
  const std::string las = las_bytes(truth_, 2, 3);
  const std::string cut_las = las.substr(0, las.size() - 40);
  refused(file("cut.las", cut_las), {"importer.scans.las", fmt::format("byte {}: the file ends inside point 4 of the 6 "
                                                                       "declared", cut_las.size())});
  std::string v10 = las;
  v10[25] = 0;
  refused(file("v10.las", v10), {"byte 24: LAS version 1.0 is not read"});
  std::string f5 = las;
  f5[104] = 5;
  refused(file("f5.las", f5), {"byte 104: point data format 5 is not read"});
  refused(file("notlas.las", "LASX" + las.substr(4)), {"byte 0: not a LAS file"});
  refused(file("empty.las", las_bytes({}, 2, 0)), {"the file holds no points"});
  // E57 and LAZ: refused with what to convert to.
  refused(file("station.e57", "ASTM-E57"), {"E57 is not read by strata", "convert it to LAS or PLY"});
  refused(file("station.laz", las), {"LAZ (compressed LAS) is not read by strata"});
  EXPECT_TRUE(list_scans(db()).empty());
}

}  // namespace
}  // namespace strata
