// `strata register scan` through the real CLI (docs/range.md, "Registration"): a layer
// whose surface comes from one scan at its known pose; a second scan of the same
// ground from another station, imported without a pose in its own frame, is placed
// by the coarse yaw search and ICP near its true pose, stored as 'transform' with its
// fit, and fused. A scan of flat ground alone is refused and the database is
// unchanged.
#include "support/box_scan.hpp"
#include "support/test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <sqlite3.h>

#include <Eigen/Geometry>

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

TEST(ScanRegisterCli, AnUnregisteredScanIsPlacedByIcpAndAFlatOneIsRefused) {
  ScratchDir dir("scan_register");
  const std::string site = (dir / "site").string();
  auto ok = [](const CommandResult& r) { ASSERT_EQ(r.exit_code, 0) << r.err; };
  ok(run_strata({"-q", "init", site, "--crs", "EPSG:32636", "--origin", "734000,4174000,1400"}));
  ok(run_strata({"-q", "unit", "add", site, "101"}));
  ok(run_strata({"-q", "layer", "add", site, "L1", "--unit", "101"}));

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

}  // namespace
}  // namespace strata::test
