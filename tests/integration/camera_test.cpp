// Known calibrations through the real `strata` executable: `camera set --fixed` and an
// imported calibration with --fixed are honoured bit for bit by the alignment, a free calibration is refined, another
// layer's solved intrinsics can be reused, and refused values leave project.gpkg
// byte for byte unchanged.
#include "core/hash.hpp"
#include "support/test_support.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

namespace strata {
namespace {

namespace fs = std::filesystem;
using test::run_strata;

// 12 photos at 640 x 428 px: the smallest set of this scene that aligns well enough
// for the self-calibration to run (it needs 3 registered photos before the focal is
// refined; 8 photos register only 3). Measured: 11 of 12 register, ~10 s per run.
constexpr int kPhotos = 12;
constexpr int kMinRegistered = 10;
// A free calibration started this far from the truth (relative focal error) must be
// refined towards it by the self-calibrating adjustment.
constexpr double kStartFocalError = 0.04;

void ok(const test::CommandResult& r) { ASSERT_EQ(r.exit_code, 0) << r.err; }

int lines(const std::string& s) { return int(std::count(s.begin(), s.end(), '\n')); }

struct TruthCamera {
  double fx, fy, cx, cy, k1, k2;
};

// The first row of the generator's truth cameras.csv (all photos share one camera).
TruthCamera read_truth(const fs::path& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  std::getline(in, line);
  std::stringstream ss(line);
  std::string cell;
  std::vector<double> v;
  std::getline(ss, cell, ',');  // image
  while (std::getline(ss, cell, ',')) v.push_back(std::stod(cell));
  EXPECT_GE(v.size(), 6u);
  return {v[0], v[1], v[2], v[3], v[4], v[5]};
}

nlohmann::json camera_list(const std::string& site) {
  const auto r = run_strata({"camera", "list", site, "--json"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return nlohmann::json::parse(r.out);
}

std::string g17(double v) { return fmt::format("{:.17g}", v); }

TEST(CameraCalibration, FixedIsHonouredFreeIsRefinedBadValuesChangeNothing) {
  test::ScratchDir dir("camera");
  const fs::path data = dir / "data";
  const std::string site = (dir / "site").string();
  ok(run_strata({"-q", "synth", data.string(), "--size", "small", "--stages", "1", "--photos",
                 std::to_string(kPhotos), "--width", "640", "--height", "428", "--seed", "5"}));
  ok(run_strata({"-q", "init", site, "--crs", "EPSG:32636"}));
  ok(run_strata({"-q", "unit", "add", site, "101"}));
  ok(run_strata({"-q", "layer", "add", site, "L1", "--unit", "101"}));
  std::vector<std::string> import{"-q", "import", "photos", site, "--layer", "L1"};
  for (const auto& e : fs::directory_iterator(data / "photos" / "L1")) import.push_back(e.path().string());
  ok(run_strata(import));
  const TruthCamera truth = read_truth(data / "truth" / "L1" / "cameras.csv");

  auto cams = camera_list(site);
  ASSERT_EQ(cams.size(), 1u);
  const std::string id = std::to_string(cams[0]["id"].get<int>());
  EXPECT_EQ(cams[0]["photos"]["L1"], kPhotos);
  EXPECT_TRUE(cams[0]["calibration"].is_null());

  // ---- refused values: one line naming the option, project.gpkg unchanged
  const fs::path gpkg = dir / "site" / "project.gpkg";
  const std::string checksum = sha256_file(gpkg);
  const std::string tree = test::tree_fingerprint(dir / "site");
  test::write_text(dir / "bad.yml", "%YAML:1.0\n---\nimage_width: 640\nimage_height: 428\n");
  const std::vector<std::pair<std::vector<std::string>, std::string>> refused = {
      {{"camera", "set", site, id, "--focal-px=-5"}, "--focal-px: -5 is not a positive focal length"},
      {{"camera", "set", site, id, "--focal-px", "800", "--pp", "5000,10"}, "--pp: 5000,10 is outside"},
      {{"camera", "set", site, id, "--focal-px", "800", "--pp", "3,x"}, "--pp: 'x' is not a number"},
      {{"camera", "set", site, id, "--focal-px", "800", "--k", "0.1,0.2,0.3"}, "--k: the radial model takes 2"},
      {{"camera", "set", site, id, "--focal-px", "800", "--model", "fisheye", "--k", "1,2,3,4,5"},
       "--k: the fisheye model takes 2 to 4"},
      {{"camera", "set", site, id, "--focal-px", "800", "--p", "0.1,0.2"}, "--p: the radial model has no tangential"},
      {{"camera", "set", site, id, "--focal-px", "800", "--model", "pinhole"}, "--model: 'pinhole'"},
      {{"camera", "set", site, id, "--from-layer", "L1"}, "--from-layer: layer L1 has no alignment yet"},
      {{"camera", "set", site, id, "--from-layer", "L1", "--model", "brown"}, "--model: --from-layer takes"},
      {{"camera", "set", site, id, "--from-layer", "L1", "--focal-px", "800"}, "--from-layer: takes the layer's"},
      {{"camera", "set", site, "nosuch.png", "--focal-px", "800"}, "camera 'nosuch.png': no camera"},
      {{"import", "calibration", site, (dir / "bad.yml").string(), "--camera", id},
       "importer.calibration.opencv: " + (dir / "bad.yml").string() + ": <camera_matrix> is missing"},
  };
  for (const auto& [args, message] : refused) {
    const auto r = run_strata(args);
    EXPECT_EQ(r.exit_code, 1) << message;
    EXPECT_EQ(lines(r.err), 1) << r.err;
    EXPECT_NE(r.err.find(message), std::string::npos) << r.err;
    EXPECT_EQ(sha256_file(gpkg), checksum) << message;
    EXPECT_EQ(test::tree_fingerprint(dir / "site"), tree) << message;
  }

  // ---- fixed: the alignment keeps the set values bit for bit
  ok(run_strata({"-q", "camera", "set", site, id, "--focal-px", g17(truth.fx), "--fy", g17(truth.fy), "--pp",
                 g17(truth.cx) + "," + g17(truth.cy), "--k", g17(truth.k1) + "," + g17(truth.k2), "--fixed"}));
  cams = camera_list(site);
  const auto set = cams[0]["calibration"];
  ASSERT_FALSE(set.is_null());
  EXPECT_EQ(set["fixed"], true);
  EXPECT_EQ(set["source"], "camera set");
  EXPECT_EQ(set["fx"].get<double>(), truth.fx);
  auto r = run_strata({"process", site, "--layer", "L1", "--until", "sparse", "--json"});
  ok(r);
  auto q = nlohmann::json::parse(r.out.substr(r.out.find('{')));
  EXPECT_GE(q["images_registered"].get<int>(), kMinRegistered);
  cams = camera_list(site);
  auto solved = cams[0]["solved"]["L1"];
  ASSERT_TRUE(solved.is_object()) << cams.dump();
  for (const char* field : {"fx", "fy", "cx", "cy", "k1", "k2"}) {
    EXPECT_EQ(solved[field].get<double>(), set[field].get<double>()) << field;  // exactly
  }
  // Unchanged inputs: up to date.
  r = run_strata({"process", site, "--layer", "L1", "--until", "sparse"});
  ok(r);
  EXPECT_NE(r.out.find("up to date"), std::string::npos) << r.out;

  // ---- free: a changed calibration reruns the alignment, which refines it
  const double start_fx = truth.fx * (1 + kStartFocalError);
  ok(run_strata({"-q", "camera", "set", site, id, "--focal-px", g17(start_fx), "--pp",
                 g17(truth.cx) + "," + g17(truth.cy), "--k", g17(truth.k1) + "," + g17(truth.k2)}));
  r = run_strata({"process", site, "--layer", "L1", "--until", "sparse"});
  ok(r);
  EXPECT_EQ(r.out.find("up to date"), std::string::npos) << r.out;
  cams = camera_list(site);
  solved = cams[0]["solved"]["L1"];
  const double free_fx = solved["fx"].get<double>();
  EXPECT_NE(free_fx, start_fx);
  EXPECT_LT(std::abs(free_fx - truth.fx), std::abs(start_fx - truth.fx)) << "moved away from the truth";
  EXPECT_NE(solved["k1"].get<double>(), truth.k1);

  // ---- reuse: layer L1's solved intrinsics, fixed
  ok(run_strata({"-q", "camera", "set", site, id, "--from-layer", "L1", "--fixed"}));
  cams = camera_list(site);
  EXPECT_EQ(cams[0]["calibration"]["source"], "layer L1");
  for (const char* field : {"fx", "fy", "cx", "cy", "k1", "k2"}) {
    EXPECT_EQ(cams[0]["calibration"][field].get<double>(), solved[field].get<double>()) << field;
  }

  // ---- clear: self-calibrated again
  r = run_strata({"camera", "clear", site, id});
  ok(r);
  EXPECT_NE(r.out.find("calibration removed"), std::string::npos) << r.out;
  EXPECT_TRUE(camera_list(site)[0]["calibration"].is_null());

  // ---- an imported Metashape calibration, fixed, is honoured too (its principal point
  // is an offset from the image centre in corner-origin pixels)
  const fs::path xml = dir / "lens.xml";
  test::write_text(xml, fmt::format("<?xml version=\"1.0\"?>\n<calibration>\n<projection>frame</projection>\n"
                                    "<width>640</width>\n<height>428</height>\n<f>{}</f>\n<cx>{}</cx>\n<cy>{}</cy>\n"
                                    "<k1>{}</k1>\n<k2>{}</k2>\n</calibration>\n",
                                    g17(truth.fx), g17(truth.cx + 0.5 - 320), g17(truth.cy + 0.5 - 214),
                                    g17(truth.k1), g17(truth.k2)));
  ok(run_strata({"-q", "import", "calibration", site, xml.string(), "--camera", "L1_0001.jpg", "--fixed"}));
  const auto imported = camera_list(site)[0]["calibration"];
  EXPECT_EQ(imported["source"], "file lens.xml (metashape)");
  EXPECT_NEAR(imported["cx"].get<double>(), truth.cx, 1e-9);
  r = run_strata({"-q", "process", site, "--layer", "L1", "--until", "sparse"});
  ok(r);
  solved = camera_list(site)[0]["solved"]["L1"];
  for (const char* field : {"fx", "fy", "cx", "cy", "k1", "k2"}) {
    EXPECT_EQ(solved[field].get<double>(), imported[field].get<double>()) << field;  // exactly
  }
}

}  // namespace
}  // namespace strata
