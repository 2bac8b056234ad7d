// Alignment of one synthetic layer end to end with the real `strata` executable:
// synth -> init -> import photos and markers -> process --until sparse -> export
// cameras, checked against the generator's truth (cameras.csv, same header).
#include "support/test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace strata {
namespace {

namespace fs = std::filesystem;
using test::run_strata;

// The scene: one stage (layers L1, L2), 20 photos per layer at 1000 px. Fewer or
// smaller photos than this leave pairs more than ~35 degrees apart in viewing
// direction, where SIFT stops matching (see docs/sfm.md, "photo sets").
constexpr int kPhotos = 20;
constexpr int kWidth = 1000;

// Tolerances. The generator perturbs the surveyed markers by 3 mm (1 sigma); the
// georeference rests on 4-6 of them, so a few millimetres of datum error remain.
constexpr double kMaxReprojectionPx = 0.5;   // the alignment acceptance (docs/sfm.md)
constexpr double kMaxCheckRmseM = 0.015;     // metres, 3D: 3 mm survey noise x ~3
constexpr double kMaxCentreErrorM = 0.010;   // metres: datum error of a 3 mm survey
constexpr double kMaxFocalError = 0.002;     // relative

void ok(const test::CommandResult& r) { ASSERT_EQ(r.exit_code, 0) << r.err; }

std::vector<std::string> split(const std::string& line, char sep) {
  std::vector<std::string> out;
  std::stringstream ss(line);
  std::string cell;
  while (std::getline(ss, cell, sep)) out.push_back(cell);
  return out;
}

// image -> row of a cameras.csv (header image,fx,...,X,Y,Z).
std::map<std::string, std::vector<double>> read_cameras(const fs::path& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "image,fx,fy,ppx,ppy,k1,k2,r11,r12,r13,r21,r22,r23,r31,r32,r33,X,Y,Z");
  std::map<std::string, std::vector<double>> rows;
  while (std::getline(in, line)) {
    const auto cells = split(line, ',');
    if (cells.size() != 19) continue;
    std::vector<double> v;
    for (std::size_t i = 1; i < cells.size(); ++i) v.push_back(std::stod(cells[i]));
    rows[cells[0]] = v;
  }
  return rows;
}

TEST(Align, SyntheticLayerMatchesTruth) {
  test::ScratchDir dir("align");
  const fs::path data = dir / "data";
  const std::string site = (dir / "site").string();
  ok(run_strata({"-q", "synth", data.string(), "--size", "small", "--stages", "1", "--photos",
                 std::to_string(kPhotos), "--width", std::to_string(kWidth)}));
  ok(run_strata({"-q", "init", site, "--crs", "EPSG:32636"}));
  ok(run_strata({"-q", "unit", "add", site, "101"}));
  ok(run_strata({"-q", "layer", "add", site, "L1", "--unit", "101"}));
  std::vector<std::string> import{"-q", "import", "photos", site, "--layer", "L1"};
  for (const auto& e : fs::directory_iterator(data / "photos" / "L1")) import.push_back(e.path().string());
  ok(run_strata(import));
  // The generator's gcp_list.txt gives hand-placed observations of every marker in
  // view (coded-target detection alone may miss small or oblique targets at this
  // resolution); markers.csv then sets the control / check roles and sigmas.
  // Only the lines of L1's photos (the importer refuses photos not in the project).
  test::write_gcp_lines_of(data / "gcp_list.txt", "L1_", dir / "gcp_l1.txt");
  ok(run_strata({"-q", "import", "markers", site, (dir / "gcp_l1.txt").string(), "--format", "odm"}));
  ok(run_strata({"-q", "import", "markers", site, (data / "markers.csv").string()}));

  const auto r = run_strata({"process", site, "--layer", "L1", "--until", "sparse", "--json"});
  ok(r);
  const auto q = nlohmann::json::parse(r.out.substr(r.out.find('{')));
  EXPECT_EQ(q["images_registered"], kPhotos) << q["unregistered"];
  EXPECT_LT(q["reprojection_rmse_px"].get<double>(), kMaxReprojectionPx);
  EXPECT_TRUE(q["georeferenced"].get<bool>());
  EXPECT_GE(q["check_rmse"]["markers"].get<int>(), 1);
  EXPECT_LT(q["check_rmse"]["xyz_m"].get<double>(), kMaxCheckRmseM) << q["markers"];

  const fs::path out = dir / "cameras.csv";
  ok(run_strata({"-q", "export", "cameras", site, "--layer", "L1", "--out", out.string()}));
  const auto got = read_cameras(out);
  const auto truth = read_cameras(data / "truth" / "L1" / "cameras.csv");
  ASSERT_EQ(truth.size(), std::size_t(kPhotos));
  for (const auto& [image, t] : truth) {
    const auto it = got.find(image);
    ASSERT_NE(it, got.end()) << image;
    const auto& g = it->second;
    const double d = std::hypot(g[15] - t[15], g[16] - t[16], g[17] - t[17]);
    EXPECT_LT(d, kMaxCentreErrorM) << image;
    EXPECT_NEAR(g[0], t[0], kMaxFocalError * t[0]) << image;
  }
}

}  // namespace
}  // namespace strata
