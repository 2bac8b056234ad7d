// A layer recorded by a laser scan alone, through the real CLI (docs/range.md,
// "Fusion"): a scan of a block on a plane in its scanner's frame, imported with its
// pose (--transform), gives the layer a fused surface and a DTM with the block's
// height, and no orthophoto; a scan imported without registration is left out with
// one warning naming it.
#include "support/box_scan.hpp"
#include "support/test_support.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <Eigen/Geometry>


namespace strata::test {
namespace {

namespace fs = std::filesystem;

// ---- the scene, site frame (metres): the plane z = 0.2 and a 20 cm block 10 cm tall --
constexpr double kPlaneZ = 0.2, kBlockTop = 0.3;
constexpr double kBlockX0 = 10.9, kBlockX1 = 11.1, kBlockY0 = 9.9, kBlockY1 = 10.1;
constexpr double kX0 = 10.4, kX1 = 11.6, kY0 = 9.4, kY1 = 10.6;  // the scanned square
constexpr double kScanSigma = 0.002;  // metres, range noise
constexpr double kStep = 4e-3;        // radians between rays
// The DTM's lowest and highest cells against the plane and the block's top: the noise
// averages out, the extremes are single 5 mm cells at the edges of the band.
constexpr double kHeightTol = 0.005;  // metres

// The scan as an XYZ file in the scanner's frame, and its pose as the 4x4 file.
void write_scan(const fs::path& xyz, const fs::path& pose) {
  const Eigen::Vector3d station(10.0, 10.0, 1.7);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const BoxOnPlane scene{{kBlockX0, kBlockY0, kPlaneZ}, {kBlockX1, kBlockY1, kBlockTop}, {kX0, kY0}, {kX1, kY1}};
  write_text(xyz, scanner_frame_xyz(box_scene_scan(scene, station, -1.3, -0.6, -0.9, 0.9, kStep, kScanSigma, 7), R,
                                    station));
  write_text(pose, pose_file_text(R, station));
}

TEST(ScanFusionCli, AScansOnlyLayerGetsASurfaceAndADtmAndAnUnregisteredScanIsSkipped) {
  ScratchDir dir("scan_fusion");
  const std::string site = (dir / "site").string();
  auto ok = [](const CommandResult& r) { ASSERT_EQ(r.exit_code, 0) << r.err; };
  ok(run_strata({"-q", "init", site, "--crs", "EPSG:32636", "--origin", "734000,4174000,1400"}));
  ok(run_strata({"-q", "unit", "add", site, "101"}));
  ok(run_strata({"-q", "layer", "add", site, "L1", "--unit", "101"}));
  write_scan(dir / "station1.xyz", dir / "station1_pose.txt");
  ok(run_strata({"-q", "import", "scan", site, "--layer", "L1", "--transform", (dir / "station1_pose.txt").string(),
                 "--sigma", "0.002", (dir / "station1.xyz").string()}));
  // The same kind of scan without a pose: kept, counted, not usable yet.
  write_text(dir / "raw.xyz", "0 0 0\n1 0 0\n0 1 0\n");
  ok(run_strata({"-q", "import", "scan", site, "--layer", "L1", (dir / "raw.xyz").string()}));

  const CommandResult r = run_strata({"process", site, "--layer", "L1", "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string warning = "layer L1: 1 unregistered scan(s) not fused: raw.xyz (register them with 'strata "
                              "register scan'";
  EXPECT_NE(r.err.find(warning), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find(warning), r.err.rfind(warning)) << "one warning, once";
  const auto q = nlohmann::json::parse(r.out.substr(r.out.find('{')));
  const auto& d = q["dense"];
  EXPECT_FALSE(d["photos"].get<bool>());
  EXPECT_EQ(d["scans_fused"].get<int>(), 1);
  EXPECT_GT(d["scan_points"].get<int>(), 10000);
  EXPECT_DOUBLE_EQ(d["scan_weight_share"].get<double>(), 1.0);
  EXPECT_EQ(d["scans_unregistered"], nlohmann::json::array({"raw.xyz"}));
  EXPECT_GT(d["completeness"].get<double>(), 0.9) << "of the scans' box";
  const auto& dtm = q["products"]["dtm"];
  EXPECT_NEAR(dtm["min_m"].get<double>(), 1400 + kPlaneZ, kHeightTol);
  EXPECT_NEAR(dtm["max_m"].get<double>(), 1400 + kBlockTop, kHeightTol);
  EXPECT_GT(dtm["area_m2"].get<double>(), 0.9 * (kX1 - kX0) * (kY1 - kY0));
  EXPECT_TRUE(q["products"]["ortho"].is_null()) << "an orthophoto needs photos";
  EXPECT_TRUE(fs::exists(dir / "site" / "products" / "L1" / "dense" / "surface.vdb"));
  EXPECT_TRUE(fs::exists(dir / "site" / "products" / "L1" / "dtm.tif"));
  EXPECT_FALSE(fs::exists(dir / "site" / "products" / "L1" / "ortho.tif"));

  // Unchanged inputs: nothing is fused again.
  const CommandResult again = run_strata({"process", site, "--layer", "L1"});
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_NE(again.out.find("dense surface (up to date, not recomputed)"), std::string::npos) << again.out;
  EXPECT_NE(again.out.find("orthophoto          none: the layer has no photos"), std::string::npos) << again.out;

  // A mesh option is part of the dense stage's key: the surface is fused again and
  // the mesh simplified to the new target (an up-to-date layer once kept its old mesh).
  const int faces = d["mesh_faces"].get<int>();
  ASSERT_GT(faces, 4000);
  const CommandResult coarser = run_strata({"process", site, "--layer", "L1", "--target-faces", "2000", "--json"});
  ASSERT_EQ(coarser.exit_code, 0) << coarser.err;
  const auto c = nlohmann::json::parse(coarser.out.substr(coarser.out.find('{')));
  EXPECT_LE(c["dense"]["mesh_faces"].get<int>(), 2000) << "was " << faces;
}

}  // namespace
}  // namespace strata::test
