// Finds in place, end to end through the real CLI: a small synthetic excavation
// (its truth rasters as the layer surfaces, no photogrammetry), its voxel model
// from `strata volume`, the planted finds imported from the generator's finds.csv;
// `strata finds --json` must put every find in its true unit and flag exactly the
// planted contradictions, with exit status 1; the site model carries the same verdicts.
#include "support/recorded_mesh.hpp"
#include "support/test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fstream>
#include <map>
#include <sstream>

namespace strata::test {
namespace {
namespace fs = std::filesystem;

void strata_ok(const std::vector<std::string>& args) {
  const CommandResult r = run_strata(args);
  ASSERT_EQ(r.exit_code, 0) << args[1] << ": " << r.err;
}

// Rows of a plain comma-separated file with a header (no quoted commas).
std::vector<std::map<std::string, std::string>> read_rows(const fs::path& path) {
  std::istringstream in(read_text(path));
  std::string line;
  std::getline(in, line);
  std::vector<std::string> names;
  std::stringstream hs(line);
  for (std::string f; std::getline(hs, f, ',');) names.push_back(f);
  std::vector<std::map<std::string, std::string>> rows;
  while (std::getline(in, line)) {
    std::stringstream ls(line);
    std::map<std::string, std::string> row;
    std::size_t i = 0;
    for (std::string f; std::getline(ls, f, ',') && i < names.size(); ++i) row[names[i]] = f;
    rows.push_back(row);
  }
  return rows;
}

TEST(Finds, SyntheticFindsLandInTheirTrueUnitAndPlantedContradictionsConflict) {
  ScratchDir dir("finds");
  const fs::path synth = dir / "synth", site = dir / "site";
  const std::string s = site.string();
  // Only the truth rasters and finds are used: the fewest, smallest photos allowed.
  strata_ok({"-q", "synth", synth.string(), "--photos", "3", "--width", "96", "--height", "64"});
  strata_ok({"-q", "init", s, "--crs", "EPSG:32636", "--origin", "734000,4174000,1450"});
  for (const auto& u : read_rows(synth / "units.csv")) strata_ok({"-q", "unit", "add", s, u.at("code")});
  std::vector<std::string> volume{"-q", "volume", s};
  for (const auto& l : read_rows(synth / "layers.csv")) {
    strata_ok({"-q", "layer", "add", s, l.at("layer"), "--unit", l.at("unit")});
    volume.push_back("--surface");
    volume.push_back(l.at("layer") + "=" + (synth / "truth" / l.at("layer") / "surface.tif").string());
  }

  // Before the voxel model exists: one clear line telling what to run.
  strata_ok({"-q", "import", "finds", s, (synth / "finds.csv").string()});
  const CommandResult early = run_strata({"finds", s});
  EXPECT_EQ(early.exit_code, 1);
  EXPECT_NE(early.err.find("run 'strata volume " + s + "' first"), std::string::npos) << early.err;

  strata_ok(volume);
  const CommandResult r = run_strata({"finds", s, "--json"});
  EXPECT_EQ(r.exit_code, 1) << "planted contradictions must fail the command\n" << r.err;
  EXPECT_NE(r.err.find("finds: 2 of 14 finds conflict"), std::string::npos) << r.err;
  const auto list = nlohmann::json::parse(r.out);
  const auto truth = read_rows(synth / "truth" / "finds.csv");
  ASSERT_EQ(list.size(), truth.size());
  std::map<std::string, nlohmann::json> by_id;
  for (const auto& f : list) by_id[f.at("id")] = f;
  int right = 0, flagged = 0, planted = 0;
  for (const auto& t : truth) {
    const auto& f = by_id.at(t.at("id"));
    for (const char* key : {"id", "recorded_unit", "geometric_unit", "distance_m", "conflict"})
      EXPECT_TRUE(f.contains(key)) << key;
    EXPECT_EQ(f.at("recorded_unit"), t.at("recorded_unit"));
    ASSERT_FALSE(f.at("geometric_unit").is_null()) << t.at("id");
    EXPECT_EQ(f.at("geometric_unit"), t.at("true_unit")) << t.at("id");
    right += f.at("geometric_unit") == t.at("true_unit");
    const bool wrong = t.at("planted_contradiction") == "1";
    planted += wrong;
    EXPECT_EQ(f.at("conflict").get<bool>(), wrong) << t.at("id");
    flagged += f.at("conflict").get<bool>() && wrong;
    if (wrong) {
      // At least the planted clearance from the recorded (adjacent) unit's solid,
      // less a voxel for the model's staircase and a few mm of survey noise.
      EXPECT_GT(f.at("distance_m").get<double>(), std::stod(t.at("clearance_m")) - 0.02) << t.at("id");
    } else {
      EXPECT_EQ(f.at("distance_m").get<double>(), 0.0) << t.at("id");
    }
  }
  EXPECT_EQ(right, int(truth.size()));
  EXPECT_EQ(flagged, planted);
  EXPECT_EQ(planted, 2);

  // The site model (a recorded dense mesh stands in for the processed layer it needs)
  // holds every find as node 'find ID' at its surveyed point, with the verdict above.
  DenseMesh ground;
  ground.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  ground.faces = {{0, 1, 2}};
  record_dense_mesh(site, read_rows(synth / "layers.csv").at(0).at("layer"), ground);
  const CommandResult model = run_strata({"export", "model", s, "--out", (dir / "site.glb").string()});
  ASSERT_EQ(model.exit_code, 0) << model.err;
  EXPECT_NE(model.err.find("14 finds"), std::string::npos) << model.err;
  const nlohmann::json glb = glb_json(dir / "site.glb");
  ASSERT_TRUE(glb.is_object());
  std::map<std::string, nlohmann::json> nodes;
  for (const auto& n : glb.at("nodes")) {
    const std::string name = n.value("name", "");
    if (name.rfind("find ", 0) == 0) nodes[name.substr(5)] = n;
  }
  ASSERT_EQ(nodes.size(), list.size());
  for (const auto& f : list) {
    const nlohmann::json& n = nodes.at(f.at("id").get<std::string>());
    const nlohmann::json& x = n.at("extras");
    EXPECT_EQ(x.at("find"), f.at("id"));
    EXPECT_EQ(x.at("recorded_unit"), f.at("recorded_unit"));
    EXPECT_EQ(x.at("geometric_unit"), f.at("geometric_unit"));
    EXPECT_EQ(x.at("conflict"), f.at("conflict"));
    EXPECT_NEAR(x.at("distance_m").get<double>(), f.at("distance_m").get<double>(), 1e-9);
    // Marker-like nodes sit at their absolute site position in glTF axes (x = E, y = Z, z = -N).
    const auto& t = n.at("translation");
    EXPECT_NEAR(t.at(0).get<double>(), f.at("E").get<double>(), 1e-4);
    EXPECT_NEAR(-t.at(2).get<double>(), f.at("N").get<double>(), 1e-4);
    EXPECT_NEAR(t.at(1).get<double>(), f.at("Z").get<double>(), 1e-4);
    EXPECT_NEAR(x.at("site_crs").at(0).get<double>(), f.at("E").get<double>(), 1e-6);
  }

  // A wide tolerance accepts the contradictions (exit 0); the text table lists all.
  const CommandResult wide = run_strata({"finds", s, "--tolerance", "1"});
  EXPECT_EQ(wide.exit_code, 0) << wide.err;
  EXPECT_NE(wide.out.find("14 finds: 12 inside their recorded unit's solid"), std::string::npos) << wide.out;

  // find add: same validation, and the project lock like other writers.
  const CommandResult bad = run_strata({"find", "add", s, "--id", "X1", "--at", "734013,4174019,1450", "--unit", "999"});
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find("find add: find 'X1': unit '999' is not in the project"), std::string::npos) << bad.err;
  strata_ok({"-q", "find", "add", s, "--id", "X1", "--at", "734013,4174019,1452", "--unit", "101"});
  const CommandResult above = run_strata({"finds", s, "--json", "--tolerance", "1"});
  EXPECT_EQ(above.exit_code, 1) << "a find far above the ground conflicts";
}

}  // namespace
}  // namespace strata::test
