// The same photos, markers and options give the same sparse result whatever the
// number of threads (strata --threads): the same features, matches, registered photos
// and marker decisions, compared through the exported cameras (a
// thread-dependent FLANN tree once moved a fisheye photo 2.7 m on a CI machine).
// Not bit for bit: Ceres sums the adjustment's residuals in threads, and the order of
// those floating-point sums moves the last digits (measured 2026-12-02: focal 4e-12
// px, rotation entries 4e-14, centres below the printed 1e-10 m). The bound tested
// is a million times that and still far below any survey figure.
#include "support/test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

namespace strata {
namespace {

namespace fs = std::filesystem;
using test::run_strata;

void ok(const test::CommandResult& r) { ASSERT_EQ(r.exit_code, 0) << r.err; }

// A fresh project of the layer (fresh caches: every stage runs), processed to the
// sparse stage with `threads`; its cameras as exported.
std::string sparse_cameras(const fs::path& root, const fs::path& data, int threads) {
  const std::string site = (root / ("site" + std::to_string(threads))).string();
  const std::string t = std::to_string(threads);
  ok(run_strata({"-q", "init", site, "--crs", "EPSG:32636"}));
  ok(run_strata({"-q", "unit", "add", site, "101"}));
  ok(run_strata({"-q", "layer", "add", site, "L1", "--unit", "101"}));
  std::vector<std::string> photos;
  for (const auto& e : fs::directory_iterator(data / "photos" / "L1")) photos.push_back(e.path().string());
  std::sort(photos.begin(), photos.end());
  std::vector<std::string> import{"-q", "import", "photos", site, "--layer", "L1"};
  import.insert(import.end(), photos.begin(), photos.end());
  ok(run_strata(import));
  // L1's lines of the generator's gcp_list.txt (the clicks), then the roles.
  test::write_gcp_lines_of(data / "gcp_list.txt", "L1_", root / "gcp_l1.txt");
  ok(run_strata({"-q", "import", "markers", site, (root / "gcp_l1.txt").string(), "--format", "odm"}));
  ok(run_strata({"-q", "import", "markers", site, (data / "markers.csv").string()}));
  const auto r = run_strata({"-q", "--threads", t, "process", site, "--layer", "L1", "--until", "sparse"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  const fs::path out = root / ("cameras" + t + ".csv");
  ok(run_strata({"-q", "export", "cameras", site, "--layer", "L1", "--format", "csv-lens", "--out", out.string()}));
  return test::read_text(out);
}

// Centres (metres, UTM: absolute), every other number (pixels, unitless: relative).
constexpr double kCentreTolM = 1e-6;
constexpr double kRelativeTol = 1e-9;

std::vector<std::vector<std::string>> rows_of(const std::string& csv) {
  std::vector<std::vector<std::string>> rows;
  std::stringstream in(csv);
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::stringstream ls(line);
    std::string cell;
    while (std::getline(ls, cell, ',')) cells.push_back(cell);
    rows.push_back(cells);
  }
  return rows;
}

void expect_same_cameras(const std::string& a, const std::string& b) {
  const auto ra = rows_of(a), rb = rows_of(b);
  ASSERT_EQ(ra.size(), rb.size()) << "the same photos are registered";
  ASSERT_FALSE(ra.empty());
  const auto& header = ra[0];
  double worst_centre = 0, worst_relative = 0;
  for (std::size_t r = 0; r < ra.size(); ++r) {
    ASSERT_EQ(ra[r].size(), rb[r].size());
    for (std::size_t c = 0; c < ra[r].size(); ++c) {
      if (r == 0 || c < 2) {  // header, image name, lens model
        EXPECT_EQ(ra[r][c], rb[r][c]);
        continue;
      }
      const double x = std::stod(ra[r][c]), y = std::stod(rb[r][c]);
      const std::string& col = header[c];
      if (col == "X" || col == "Y" || col == "Z") {
        worst_centre = std::max(worst_centre, std::abs(x - y));
        EXPECT_LE(std::abs(x - y), kCentreTolM) << ra[r][0] << " " << col;
      } else {
        const double rel = std::abs(x - y) / std::max(1.0, std::abs(x));
        worst_relative = std::max(worst_relative, rel);
        EXPECT_LE(rel, kRelativeTol) << ra[r][0] << " " << col << ": " << ra[r][c] << " vs " << rb[r][c];
      }
    }
  }
  std::printf("[ figures  ] 1 vs 2 threads: centres differ by at most %.3g m, other terms by %.3g relative\n",
              worst_centre, worst_relative);
}

TEST(Threads, SparseResultIsTheSameWithOneAndTwoThreads) {
  test::ScratchDir dir("threads");
  const fs::path data = dir / "data";
  ok(run_strata({"-q", "synth", data.string(), "--size", "small", "--stages", "1", "--photos", "12",
                 "--width", "800", "--seed", "5"}));
  const std::string one = sparse_cameras(dir.path(), data, 1);
  const std::string two = sparse_cameras(dir.path(), data, 2);
  ASSERT_FALSE(one.empty());
  EXPECT_GT(std::count(one.begin(), one.end(), '\n'), 10) << "a camera row per registered photo";
  expect_same_cameras(one, two);
}

TEST(Threads, BadThreadCountsAreRefused) {
  const auto r = run_strata({"--threads", "-1", "info", "."});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("--threads"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace strata
