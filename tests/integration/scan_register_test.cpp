// `strata register scan` through the real CLI (docs/range.md, "Registration"): a layer
// whose surface comes from one scan at its known pose; a second scan of the same
// ground from another station, imported without a pose in its own frame, is placed
// by the coarse yaw search and ICP near its true pose, stored as 'transform' with its
// fit, and fused. A scan of flat ground alone is refused and the database is
// unchanged. A scan registered on the surveyed markers its scanner measured: blunders
// named and left out, wrong units and too few known names refused.
#include "support/box_scan.hpp"
#include "support/test_support.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <sqlite3.h>

#include <Eigen/Geometry>

#include <random>

namespace strata::test {
namespace {

namespace fs = std::filesystem;

// The scene, site frame (metres): the plane z = 0.2 and a 30 x 20 cm block 12 cm tall,
// off the middle of the scanned rectangle (no symmetry of the whole).
const BoxOnPlane kScene{{10.9, 9.85, 0.2}, {11.2, 10.05, 0.32}, {10.4, 9.4}, {11.6, 10.6}};
constexpr double kScanSigma = 0.002;  // metres, range noise
constexpr double kStep = 4e-3;        // radians between rays
// The reference is the fused surface of the first scan (voxels of a few mm) and
// the second station is 1-2 m from its points: a few millimetres and milliradians.
constexpr double kStationTol = 0.005;   // metres
constexpr double kRotationTol = 0.005;  // radians

struct Station {
  Eigen::Vector3d origin;
  double yaw;  // radians, scanner x from site east
  Eigen::Matrix3d R() const { return Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix(); }
};

void write_scan(const fs::path& xyz, const BoxOnPlane& scene, const Station& s, double az0, double az1,
                unsigned seed) {
  write_text(xyz, scanner_frame_xyz(box_scene_scan(scene, s.origin, -1.35, -0.5, az0, az1, kStep, kScanSigma, seed),
                                    s.R(), s.origin));
}

// Every column of the scans table, row by row: what the database says of the scans.
std::string scans_table(const fs::path& gpkg) {
  sqlite3* db = nullptr;
  EXPECT_EQ(sqlite3_open_v2(gpkg.c_str(), &db, SQLITE_OPEN_READONLY, nullptr), SQLITE_OK);
  sqlite3_stmt* st = nullptr;
  sqlite3_prepare_v2(db, "SELECT * FROM scans ORDER BY id", -1, &st, nullptr);
  std::string out;
  while (sqlite3_step(st) == SQLITE_ROW) {
    for (int c = 0; c < sqlite3_column_count(st); ++c) {
      const unsigned char* t = sqlite3_column_text(st, c);
      out += t ? reinterpret_cast<const char*>(t) : "NULL";
      out += '|';
    }
    out += '\n';
  }
  sqlite3_finalize(st);
  sqlite3_close(db);
  return out;
}

// A project with its origin fixed, unit 101 and layer L1.
void make_site(const std::string& site) {
  for (const auto& args : std::vector<std::vector<std::string>>{
           {"-q", "init", site, "--crs", "EPSG:32636", "--origin", "734000,4174000,1400"},
           {"-q", "unit", "add", site, "101"},
           {"-q", "layer", "add", site, "L1", "--unit", "101"}}) {
    const CommandResult r = run_strata(args);
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
}

TEST(ScanRegisterCli, AnUnregisteredScanIsPlacedByIcpAndAFlatOneIsRefused) {
  ScratchDir dir("scan_register");
  const std::string site = (dir / "site").string();
  auto ok = [](const CommandResult& r) { ASSERT_EQ(r.exit_code, 0) << r.err; };
  make_site(site);

  // The reference surface: station A at its true pose, fused.
  const Station a{{10.0, 9.5, 1.7}, 0.5};
  write_scan(dir / "a.xyz", kScene, a, -0.4, 1.3, 7);
  write_text(dir / "a_pose.txt", pose_file_text(a.R(), a.origin));
  ok(run_strata({"-q", "import", "scan", site, "--layer", "L1", "--transform", (dir / "a_pose.txt").string(),
                 "--sigma", "0.002", (dir / "a.xyz").string()}));
  ok(run_strata({"-q", "process", site, "--layer", "L1"}));

  // Station B south of A, turned 120 degrees, imported in its own frame. Both see the
  // block's west and south faces: a face only one station sees fixes nothing.
  const Station b{{10.6, 8.9, 1.6}, 2.0944};
  write_scan(dir / "b.xyz", kScene, b, 0.3, 2.1, 8);
  ok(run_strata({"-q", "import", "scan", site, "--layer", "L1", "--sigma", "0.002", (dir / "b.xyz").string()}));
  const CommandResult r = run_strata({"-q", "register", "scan", site, "--layer", "L1", "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto q = nlohmann::json::parse(r.out);
  ASSERT_EQ(q["scans"].size(), 1u);
  const auto& s = q["scans"][0];
  EXPECT_EQ(s["scan"], "b.xyz");
  Eigen::Matrix4d m;
  for (int k = 0; k < 16; ++k) m(k / 4, k % 4) = s["transform"][k].get<double>();
  EXPECT_LT((m.topRightCorner<3, 1>() - b.origin).norm(), kStationTol) << m;
  EXPECT_LT(Eigen::AngleAxisd(b.R().transpose() * m.topLeftCorner<3, 3>()).angle(), kRotationTol) << m;
  EXPECT_GT(s["inlier_share"].get<double>(), 0.5);
  EXPECT_LT(s["rms_m"].get<double>(), 3 * kScanSigma);
  EXPECT_GT(s["sigma_translation_m"].get<double>(), 0);

  const CommandResult fused = run_strata({"process", site, "--layer", "L1", "--json"});
  ASSERT_EQ(fused.exit_code, 0) << fused.err;
  const auto d = nlohmann::json::parse(fused.out.substr(fused.out.find('{')))["dense"];
  EXPECT_EQ(d["scans_fused"].get<int>(), 2);

  // Flat ground only (west of the block): its in-plane position is unobservable.
  const fs::path gpkg = dir / "site" / "project.gpkg";
  BoxOnPlane flat = kScene;
  flat.crop_max = {10.8, 10.6};
  write_scan(dir / "flat.xyz", flat, a, -0.4, 1.3, 9);
  ok(run_strata({"-q", "import", "scan", site, "--layer", "L1", "--sigma", "0.002", (dir / "flat.xyz").string()}));
  const std::string before = scans_table(gpkg);
  const CommandResult refused = run_strata({"-q", "register", "scan", site, "--layer", "L1"});
  EXPECT_NE(refused.exit_code, 0);
  EXPECT_NE(refused.err.find("flat.xyz: cannot register it"), std::string::npos) << refused.err;
  EXPECT_NE(refused.err.find("degenerate"), std::string::npos) << refused.err;
  EXPECT_NE(refused.err.find("--transform"), std::string::npos) << refused.err;
  EXPECT_EQ(scans_table(gpkg), before);
}

// Surveyed markers around the block (site frame) and the scanner's measurements of
// them (its frame, 2 mm of noise); `scale` multiplies the measurements (1000: a file
// in millimetres).
const std::vector<std::pair<std::string, Eigen::Vector3d>> kMarkers = {
    {"M1", {10.45, 9.45, 0.2}}, {"M2", {11.55, 9.45, 0.2}}, {"M3", {11.55, 10.55, 0.2}},
    {"M4", {10.45, 10.55, 0.2}}, {"M5", {11.0, 9.45, 0.2}}, {"M6", {11.05, 9.95, 0.32}}};

std::string targets_csv(const Station& s, const std::vector<std::string>& names, double scale, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.002);
  std::string out = "name,x,y,z\n";
  for (std::size_t i = 0; i < kMarkers.size() && i < names.size(); ++i) {
    const Eigen::Vector3d p = s.R().transpose() * (kMarkers[i].second - s.origin) +
                              Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    out += fmt::format("{},{:.5f},{:.5f},{:.5f}\n", names[i], scale * p.x(), scale * p.y(), scale * p.z());
  }
  return out;
}

TEST(ScanRegisterCli, AScanIsPlacedOnItsTargetsAndBadTargetFilesAreRefused) {
  ScratchDir dir("scan_register_targets");
  const std::string site = (dir / "site").string();
  auto ok = [](const CommandResult& r) { ASSERT_EQ(r.exit_code, 0) << r.err; };
  make_site(site);
  std::string markers = "name,E,N,Z,sigma,kind\n";
  for (const auto& [name, p] : kMarkers)
    markers += fmt::format("{},{:.4f},{:.4f},{:.4f},0.002,control\n", name, 734000 + p.x(), 4174000 + p.y(),
                           1400 + p.z());
  write_text(dir / "markers.csv", markers);
  ok(run_strata({"-q", "import", "markers", site, (dir / "markers.csv").string()}));
  const Station b{{10.6, 8.9, 1.6}, 2.0944};
  write_scan(dir / "b.xyz", kScene, b, 0.3, 2.1, 8);
  ok(run_strata({"-q", "import", "scan", site, "--layer", "L1", "--sigma", "0.002", (dir / "b.xyz").string()}));
  const fs::path gpkg = dir / "site" / "project.gpkg";
  const std::string before = scans_table(gpkg);
  auto refused = [&](const std::vector<std::string>& names, double scale, const std::string& why) {
    write_text(dir / "bad.csv", targets_csv(b, names, scale, 3));
    const CommandResult r = run_strata({"-q", "register", "scan", site, "--layer", "L1", "--scan", "b.xyz",
                                        "--targets", (dir / "bad.csv").string()});
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.err.find(why), std::string::npos) << r.err;
    EXPECT_EQ(scans_table(gpkg), before);
  };
  refused({"M1", "M2", "M3", "M4", "M5", "M6"}, 1000, "not in metres");
  refused({"M1", "X2", "M3", "X4"}, 1, "2 of the 4 targets");
  refused({"M1", "M2", "M3", "M4", "M1"}, 1, "target 'M1' is listed again (first on line 2)");
  const CommandResult no_scan =
      run_strata({"-q", "register", "scan", site, "--layer", "L1", "--targets", (dir / "bad.csv").string()});
  EXPECT_NE(no_scan.exit_code, 0);
  EXPECT_NE(no_scan.err.find("--scan"), std::string::npos) << no_scan.err;

  // M2 and M5 with each other's names, and T9 that no marker is called.
  write_text(dir / "targets.csv", targets_csv(b, {"M1", "M5", "M3", "M4", "M2", "M6"}, 1, 4) + "T9,1,2,3\n");
  const CommandResult r = run_strata({"-q", "register", "scan", site, "--layer", "L1", "--scan", "b.xyz",
                                      "--targets", (dir / "targets.csv").string(), "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto q = nlohmann::json::parse(r.out);
  EXPECT_EQ(q["method"], "targets");
  EXPECT_EQ(q["inliers"].get<int>(), 4);
  for (const auto& t : q["targets"]) {
    const bool swapped = t["name"] == "M2" || t["name"] == "M5";
    EXPECT_EQ(t["inlier"].get<bool>(), !swapped) << t;
    if (swapped) {
      EXPECT_GT(t["residual_m"].get<double>(), 0.4) << t;
    }
  }
  EXPECT_EQ(q["unmatched"], nlohmann::json::array({"T9"}));
  EXPECT_NEAR(q["scale"].get<double>(), 1.0, 0.005);
  EXPECT_LT(q["rms_m"].get<double>(), 0.006);
  Eigen::Matrix4d m;
  for (int k = 0; k < 16; ++k) m(k / 4, k % 4) = q["transform"][k].get<double>();
  // Four targets of 2 mm over a metre: a few millimetres at the station 1 m away.
  EXPECT_LT((m.topRightCorner<3, 1>() - b.origin).norm(), 0.008) << m;
  const Eigen::Matrix3d sR = m.topLeftCorner<3, 3>();
  EXPECT_LT(Eigen::AngleAxisd(b.R().transpose() * sR / std::cbrt(sR.determinant())).angle(), 0.008) << m;
  EXPECT_NE(scans_table(gpkg).find("targets|targets.csv|"), std::string::npos) << scans_table(gpkg);
}

}  // namespace
}  // namespace strata::test
