// GRASS reads the voxel export: the real CLI builds a project from a small
// synthetic excavation (truth rasters as layer surfaces), exports the voxel model
// as a GRASS 3D ASCII raster, and GRASS 8 imports it with r3.in.ascii; r3.info
// must report the exported size and the range of unit labels.
#include "support/test_support.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>

namespace strata::test {
namespace {
namespace fs = std::filesystem;

// r3.info -g prints bounds with 2-3 decimals (1449.675 -> 1449.67): half a centimetre.
constexpr double kGrassPrinted = 0.006;

bool on_path(const std::string& program) {
  return std::system(("command -v " + program + " > /dev/null 2>&1").c_str()) == 0;
}

std::string run_shell(const std::string& command, int* status) {
  std::string out;
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (!pipe) return out;
  char buffer[4096];
  while (std::size_t n = std::fread(buffer, 1, sizeof buffer, pipe)) out.append(buffer, n);
  *status = pclose(pipe);
  return out;
}

void strata_ok(const std::vector<std::string>& args) {
  const CommandResult r = run_strata(args);
  ASSERT_EQ(r.exit_code, 0) << args[0] << ": " << r.err;
}

// The header value `key: value` of a GRASS ASCII 3D raster.
std::string header_value(const std::string& text, const std::string& key) {
  std::smatch m;
  if (std::regex_search(text, m, std::regex(key + ":\\s*(\\S+)"))) return m[1];
  return "";
}

TEST(GrassR3, ImportsTheVoxelExport) {
  if (!on_path("grass")) GTEST_SKIP() << "grass is not on PATH: install grass-core (GRASS 8) to run this test";
  ScratchDir dir("grass_r3");
  const fs::path synth = dir / "synth", site = dir / "site";
  // Only the truth rasters are used: the fewest, smallest photos the generator allows.
  strata_ok({"-q", "synth", synth.string(), "--photos", "3", "--width", "96", "--height", "64"});
  strata_ok({"-q", "init", site.string(), "--crs", "EPSG:32636", "--origin", "734000,4174000,1450"});
  for (const char* u : {"101", "102", "103", "104"}) strata_ok({"-q", "unit", "add", site.string(), u});
  for (int k = 1; k <= 3; ++k)
    strata_ok({"-q", "relation", "add", site.string(), std::to_string(100 + k), "above", std::to_string(101 + k)});
  for (int k = 1; k <= 4; ++k)
    strata_ok({"-q", "layer", "add", site.string(), "L" + std::to_string(k), "--unit", std::to_string(100 + k),
               "--captured-at", "2024-06-1" + std::to_string(k) + "T09:00:00"});
  std::vector<std::string> args{"-q", "export", "voxels", site.string(), "--voxel-size", "0.05",
                                "--out", (dir / "units.asc").string()};
  for (int k = 1; k <= 4; ++k) {
    args.push_back("--surface");
    args.push_back("L" + std::to_string(k) + "=" + (synth / "truth" / ("L" + std::to_string(k)) / "surface.tif").string());
  }
  strata_ok(args);
  ASSERT_TRUE(fs::exists(dir / "units.sh"));
  const std::string text = read_text(dir / "units.asc");
  const std::string rows = header_value(text, "rows"), cols = header_value(text, "cols"),
                    levels = header_value(text, "levels");
  ASSERT_FALSE(rows.empty());

  // Unit ids are 1..4 in the order added; units 101..103 are excavated.
  int status = 0;
  const std::string out = run_shell(
      "cd " + dir.path().string() + " && grass --tmp-location EPSG:32636 --exec sh -c '" +
          "r3.in.ascii --quiet input=units.asc output=u null_value=\"*\" && g.region raster_3d=u && " +
          "r3.info -g map=u && r3.info -r map=u'",
      &status);
  ASSERT_EQ(status, 0) << out;
  std::map<std::string, std::string> info;
  std::istringstream lines(out);
  for (std::string line; std::getline(lines, line);) {
    const auto eq = line.find('=');
    if (eq != std::string::npos) info[line.substr(0, eq)] = line.substr(eq + 1);
  }
  EXPECT_EQ(info["rows"], rows) << out;
  EXPECT_EQ(info["cols"], cols) << out;
  EXPECT_EQ(info["depths"], levels) << out;
  EXPECT_NEAR(std::stod(info["tbres"]), 0.05, 1e-9) << out;
  EXPECT_NEAR(std::stod(info["ewres"]), 0.05, 1e-9) << out;
  EXPECT_DOUBLE_EQ(std::stod(info["min"]), 1.0) << out;
  EXPECT_DOUBLE_EQ(std::stod(info["max"]), 3.0) << out;
  for (const char* key : {"north", "south", "east", "west", "top", "bottom"})
    EXPECT_NEAR(std::stod(info[key]), std::stod(header_value(text, key)), kGrassPrinted) << key << "\n" << out;
}

}  // namespace
}  // namespace strata::test
