// Finds in place, end to end through the real CLI: a small synthetic excavation
// (its truth rasters as the layer surfaces, no photogrammetry), its voxel model
// from `strata volume`, the planted finds imported from the generator's finds.csv;
// `strata finds --json` must put every find in its true unit and flag exactly the
// planted contradictions, with exit status 1; the site model, the QGIS project, the
// site report and sections carry the same finds and verdicts.
#include "support/recorded_mesh.hpp"
#include "support/shared_scene.hpp"
#include "support/test_support.hpp"

#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <ogrsf_frmts.h>

#include <cmath>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>

namespace strata::test {
namespace {
namespace fs = std::filesystem;

void strata_ok(const std::vector<std::string>& args) {
  const CommandResult r = run_strata(args);
  ASSERT_EQ(r.exit_code, 0) << args[1] << ": " << r.err;
}

// A step of the shared scene's build: a failure throws, so that the scene is not kept.
void build_step(const std::vector<std::string>& args) {
  const CommandResult r = run_strata(args);
  if (r.exit_code != 0) throw std::runtime_error(args[1] + ": " + r.err);
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

// `--surface LAYER=FILE` for every layer of the generator's site: its truth raster.
std::vector<std::string> truth_surfaces(const fs::path& synth) {
  std::vector<std::string> args;
  for (const auto& l : read_rows(synth / "layers.csv")) {
    args.push_back("--surface");
    args.push_back(l.at("layer") + "=" + (synth / "truth" / l.at("layer") / "surface.tif").string());
  }
  return args;
}

// The synthetic site, built once for every process of the suite
// (support/shared_scene.hpp): synth/ (the generator's output), record/ (units,
// layers and the planted finds imported, no voxel model) and site/ (record/ after
// `strata volume` on the truth surfaces). Tests copy what they change.
class Finds : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    shared_ = shared_scene("finds_site", "synth --photos 3 --width 96 --height 64; finds; volume on truth",
                           [](const fs::path& d) {
      const fs::path synth = d / "synth", record = d / "record", site = d / "site";
      // Only the truth rasters and finds are used: the fewest, smallest photos allowed.
      build_step({"-q", "synth", synth.string(), "--photos", "3", "--width", "96", "--height", "64"});
      const std::string r = record.string();
      build_step({"-q", "init", r, "--crs", "EPSG:32636", "--origin", "734000,4174000,1450"});
      for (const auto& u : read_rows(synth / "units.csv")) build_step({"-q", "unit", "add", r, u.at("code")});
      for (const auto& l : read_rows(synth / "layers.csv"))
        build_step({"-q", "layer", "add", r, l.at("layer"), "--unit", l.at("unit")});
      build_step({"-q", "import", "finds", r, (synth / "finds.csv").string()});
      copy_scene(record, site);
      std::vector<std::string> volume{"-q", "volume", site.string()};
      for (const auto& a : truth_surfaces(synth)) volume.push_back(a);
      build_step(volume);
    });
  }
  static fs::path synth() { return shared_ / "synth"; }
  // A copy of the shared record/ or site/ under this test's scratch folder.
  fs::path copy_of(const std::string& which) {
    const fs::path to = scratch_ / which;
    copy_scene(shared_ / which, to);
    return to;
  }
  static fs::path shared_;
  ScratchDir scratch_{"finds"};
};
fs::path Finds::shared_;

TEST_F(Finds, SyntheticFindsLandInTheirTrueUnitAndPlantedContradictionsConflict) {
  const ScratchDir& dir = scratch_;
  // Before the voxel model exists: one clear line telling what to run.
  const std::string record = copy_of("record").string();
  const CommandResult early = run_strata({"finds", record});
  EXPECT_EQ(early.exit_code, 1);
  EXPECT_NE(early.err.find("run 'strata volume " + record + "' first"), std::string::npos) << early.err;

  const fs::path site = copy_of("site"), synth = this->synth();
  const std::string s = site.string();
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

// The <maplayer> element of the layer with this id in a .qgs.
std::string maplayer_xml(const std::string& qgs, const std::string& id) {
  const auto at = qgs.find("<id>" + id + "</id>");
  if (at == std::string::npos) return "";
  const auto begin = qgs.rfind("<maplayer", at), end = qgs.find("</maplayer>", at);
  return qgs.substr(begin, end - begin);
}

TEST_F(Finds, QgisProjectLabelsTheFindsAndSetsTheConflictsApart) {
  // Without the voxel model: the finds layer, one symbol, labelled by number.
  const fs::path record = copy_of("record");
  const CommandResult plain = run_strata({"export", "qgis", record.string(), "--out", (record / "record.qgs").string()});
  ASSERT_EQ(plain.exit_code, 0) << plain.err;
  EXPECT_NE(plain.err.find("no voxel model yet"), std::string::npos) << plain.err;
  const std::string before = maplayer_xml(read_text(record / "record.qgs"), "strata_finds");
  ASSERT_FALSE(before.empty());
  EXPECT_NE(before.find("<datasource>./project.gpkg|layername=finds</datasource>"), std::string::npos) << before;
  EXPECT_NE(before.find("renderer-v2 type=\"singleSymbol\""), std::string::npos) << before;
  EXPECT_NE(before.find("fieldName=\"find_id\" isExpression=\"0\""), std::string::npos) << before;

  // With it: the planted contradictions, and only they, in the conflict rule, each
  // labelled with the unit that holds it.
  const fs::path site = copy_of("site");
  const CommandResult r = run_strata({"export", "qgis", site.string(), "--out", (site / "site.qgz").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("14 finds of which 2 in conflict with the unit solids"), std::string::npos) << r.err;
  const CommandResult qgs = run_strata({"export", "qgis", site.string(), "--out", (site / "site.qgs").string()});
  ASSERT_EQ(qgs.exit_code, 0) << qgs.err;
  const std::string layer = maplayer_xml(read_text(site / "site.qgs"), "strata_finds");
  EXPECT_NE(layer.find("renderer-v2 type=\"RuleRenderer\""), std::string::npos) << layer;
  std::string ids;
  for (const auto& t : read_rows(synth() / "truth" / "finds.csv")) {
    if (t.at("planted_contradiction") != "1") continue;
    ids += (ids.empty() ? "" : ", ") + ("&#39;" + t.at("id") + "&#39;");
    const std::string label = "&quot;find_id&quot; = &#39;" + t.at("id") + "&#39; THEN &quot;find_id&quot; || "
                              "&#39;: recorded &#39; || &quot;unit&quot; || &#39;, lies in " + t.at("true_unit") + "&#39;";
    EXPECT_NE(layer.find(label), std::string::npos) << label << "\n" << layer;
  }
  EXPECT_NE(layer.find("filter=\"&quot;find_id&quot; IN (" + ids + ")\" label=\"conflict with the unit solids (2)\""),
            std::string::npos)
      << ids << "\n" << layer;
  EXPECT_NE(layer.find("filter=\"ELSE\" label=\"agree with the unit solids\""), std::string::npos) << layer;
}

// The site report's section "Finds", up to the next section.
std::string finds_section(const std::string& html) {
  const auto begin = html.find("<h2>Finds</h2>");
  if (begin == std::string::npos) return "";
  return html.substr(begin, html.find("<h2>", begin + 1) - begin);
}

TEST_F(Finds, SiteReportListsTheFindsWithTheConflictsFirst) {
  const auto recorded = read_rows(synth() / "finds.csv");
  std::map<std::string, int> per_unit;
  for (const auto& f : recorded) ++per_unit[f.at("unit")];

  // Without the voxel model: the record, counted per unit, and what to run.
  const fs::path record = copy_of("record");
  const CommandResult plain =
      run_strata({"report", record.string(), "--no-section", "--out", (record / "report.html").string()});
  ASSERT_EQ(plain.exit_code, 0) << plain.err;
  const std::string before = finds_section(read_text(record / "report.html"));
  ASSERT_FALSE(before.empty());
  EXPECT_NE(before.find("14 finds as recorded; not yet checked against the unit solids: run strata volume DIR, "
                        "then this report again."),
            std::string::npos);
  for (const auto& [unit, n] : per_unit) {
    const std::string row = "<tr><td>" + unit + "</td><td>" + std::to_string(n) + "</td></tr>";
    EXPECT_NE(before.find(row), std::string::npos) << row;
  }
  for (const auto& f : recorded) EXPECT_NE(before.find("<tr><td>" + f.at("id") + "</td>"), std::string::npos) << f.at("id");
  EXPECT_EQ(before.find("class=\"warning\""), std::string::npos);

  // With it: a warning per planted contradiction, in the field's words, before the
  // tables; the conflicting finds head the list of finds; counts per recorded unit.
  const fs::path site = copy_of("site");
  const CommandResult r = run_strata({"report", site.string(), "--no-section", "--out", (site / "report.html").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("finds: 2 in conflict with the unit solids"), std::string::npos) << r.out;
  const std::string html = read_text(site / "report.html");
  const auto section = html.find("<h2>Finds</h2>");
  ASSERT_NE(section, std::string::npos);
  EXPECT_NE(html.find("2 of 14 finds conflict with the unit solids: re-check their record or their survey", section),
            std::string::npos);
  const auto list = html.find("<tr><th>find</th>", section);
  ASSERT_NE(list, std::string::npos);
  std::map<std::string, int> conflicts_per_unit;
  std::size_t last_conflict_row = 0, first_other_row = std::string::npos;
  for (const auto& t : read_rows(synth() / "truth" / "finds.csv")) {
    const auto row = html.find("<tr><td>" + t.at("id") + "</td>", list);
    ASSERT_NE(row, std::string::npos) << t.at("id");
    if (t.at("planted_contradiction") != "1") {
      first_other_row = std::min(first_other_row, row);
      continue;
    }
    ++conflicts_per_unit[t.at("recorded_unit")];
    last_conflict_row = std::max(last_conflict_row, row);
    const std::string said = "find " + t.at("id") + " was recorded in unit " + t.at("recorded_unit") + ", but its point (";
    const auto warning = html.find(said, section);
    ASSERT_NE(warning, std::string::npos) << said;
    EXPECT_LT(warning, list);
    const std::string item = html.substr(warning, html.find("</li>", warning) - warning);
    EXPECT_NE(item.find(") lies in unit " + t.at("true_unit") + ", "), std::string::npos) << item;
    EXPECT_NE(item.find("What to do: re-check the find&#39;s record"), std::string::npos) << item;
    EXPECT_NE(item.find("and its survey (the total-station point"), std::string::npos) << item;
    EXPECT_NE(item.find("the boundary between units " + t.at("recorded_unit") + " and " + t.at("true_unit")),
              std::string::npos)
        << item;
  }
  EXPECT_LT(last_conflict_row, first_other_row);
  // Every other planted find lies in its recorded unit (the CLI test above).
  for (const auto& [unit, n] : per_unit) {
    const int c = conflicts_per_unit[unit];
    const std::string row = "<tr><td>" + unit + "</td><td>" + std::to_string(n) + "</td><td>" + std::to_string(n - c) +
                            "</td><td>0</td><td>0</td><td class=\"" + (c ? "bad" : "") + "\">" + std::to_string(c) +
                            "</td></tr>";
    EXPECT_NE(html.find(row, section), std::string::npos) << row;
  }
}

// The projected finds of a section written as a GeoPackage, by find number:
// chainage, height, offset, recorded unit.
struct SectionFind {
  double chainage_m = 0, height_m = 0, offset_m = 0;
  std::string unit;
};
std::map<std::string, SectionFind> section_finds(const fs::path& gpkg, bool* table) {
  std::map<std::string, SectionFind> out;
  GDALAllRegister();
  GDALDataset* ds = GDALDataset::Open(gpkg.c_str(), GDAL_OF_VECTOR);
  if (!ds) return out;
  OGRLayer* l = ds->GetLayerByName("section_finds");
  *table = l != nullptr;
  if (l) {
    while (OGRFeature* f = l->GetNextFeature()) {
      out[f->GetFieldAsString("find_id")] = {f->GetFieldAsDouble("chainage_m"), f->GetFieldAsDouble("height_m"),
                                             f->GetFieldAsDouble("offset_m"), f->GetFieldAsString("unit")};
      OGRFeature::DestroyFeature(f);
    }
  }
  GDALClose(ds);
  return out;
}

TEST_F(Finds, SectionsShowTheFindsNearThePlane) {
  // The brief's precision for a drawn section; the CSV's coordinates and GDAL's
  // doubles carry far more.
  constexpr double kSectionTol = 0.001;  // metres
  const fs::path site = copy_of("site");
  // The finds as recorded (the register's surveyed points, with the generator's
  // survey noise), which is what the section projects.
  const auto recorded = read_rows(synth() / "finds.csv");
  // West to east, 2 m long, 0.1 m south of the first find: it lies 1.0 m along the
  // line, 0.1 m behind the plane (north, left of the line).
  const double e0 = std::stod(recorded.at(0).at("E")) - 1.0, n0 = std::stod(recorded.at(0).at("N")) - 0.1;
  const std::string line = std::to_string(e0) + "," + std::to_string(n0) + "," + std::to_string(e0 + 2.0) + "," +
                           std::to_string(n0);
  auto section = [&](const fs::path& out, const std::vector<std::string>& extra) {
    std::vector<std::string> args{"export", "section", site.string(), "--line", line, "--out", out.string()};
    for (const auto& a : truth_surfaces(synth())) args.push_back(a);
    for (const auto& a : extra) args.push_back(a);
    return run_strata(args);
  };
  std::map<std::string, SectionFind> want;
  int left_out = 0;  // beside the line but farther than 0.25 m from the plane
  for (const auto& t : recorded) {
    const double s = std::stod(t.at("E")) - e0, offset = n0 - std::stod(t.at("N"));
    if (s < 0 || s > 2.0) continue;
    if (std::abs(offset) > 0.25) {
      ++left_out;
      continue;
    }
    want[t.at("id")] = {s, std::stod(t.at("Z")), offset, t.at("unit")};
  }
  ASSERT_GE(want.size(), 1u);
  EXPECT_GE(left_out, 1) << "the line should pass finds farther than 0.25 m too";
  EXPECT_NEAR(want.at(recorded.at(0).at("id")).chainage_m, 1.0, 1e-6);

  const CommandResult r = section(scratch_ / "s.gpkg", {});  // the default 0.25 m
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find(std::to_string(want.size()) + " of 14 finds within 0.25 m of the plane"), std::string::npos)
      << r.err;
  bool table = false;
  const auto got = section_finds(scratch_ / "s.gpkg", &table);
  EXPECT_TRUE(table);
  ASSERT_EQ(got.size(), want.size());
  for (const auto& [id, w] : want) {
    ASSERT_TRUE(got.count(id)) << id;
    const SectionFind& g = got.at(id);
    EXPECT_NEAR(g.chainage_m, w.chainage_m, kSectionTol) << id;
    EXPECT_NEAR(g.height_m, w.height_m, kSectionTol) << id;
    EXPECT_NEAR(g.offset_m, w.offset_m, kSectionTol) << id;
    EXPECT_EQ(g.unit, w.unit) << id;
  }
  EXPECT_NEAR(got.at(recorded.at(0).at("id")).offset_m, -0.1, kSectionTol);

  // The drawing: a labelled marker for each of them and for no other find.
  ASSERT_EQ(section(scratch_ / "s.svg", {}).exit_code, 0);
  const std::string svg = read_text(scratch_ / "s.svg");
  for (const auto& t : recorded) {
    const bool drawn = svg.find("data-find=\"" + t.at("id") + "\"") != std::string::npos;
    EXPECT_EQ(drawn, want.count(t.at("id")) == 1) << t.at("id");
    if (drawn) {
      EXPECT_NE(svg.find(">" + t.at("id") + "</text>"), std::string::npos) << t.at("id");
    }
  }

  // 0 switches the finds off; a negative distance is refused by value, nothing written.
  ASSERT_EQ(section(scratch_ / "off.gpkg", {"--finds-within", "0"}).exit_code, 0);
  section_finds(scratch_ / "off.gpkg", &table);
  EXPECT_FALSE(table);
  const CommandResult bad = section(scratch_ / "bad.svg", {"--finds-within=-0.5"});
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find("--finds-within -0.5 must be 0 (no finds) or a distance of at most 100 m"), std::string::npos)
      << bad.err;
  EXPECT_FALSE(fs::exists(scratch_ / "bad.svg"));
}

}  // namespace
}  // namespace strata::test
