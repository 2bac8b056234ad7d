// What a new user trips over (issue 50), through the real CLI on one small synthetic
// layer (20 photos at 1000 px, 8 surveyed markers):
// - the verdict on a survey rounded to 0.1 m judges against that survey, and still
//   fails markers that really disagree;
// - `strata markers` shows each marker's residuals per processed layer;
// - `strata info` keeps its columns apart when a description is long;
// - a layer without markers comes out with its cameras above the surface, looking
//   down, and its report says that the scale is arbitrary.
#include "geometry/similarity.hpp"
#include "support/test_support.hpp"

#include <gtest/gtest.h>
#include <sqlite3.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <numbers>
#include <sstream>

namespace strata {
namespace {

namespace fs = std::filesystem;
using test::run_strata;

// The truth's up carried into a layer aligned without markers: the synthetic photos
// are tilted up to 14 degrees from looking at the trench, so their mean viewing
// direction is within that of the vertical (radians, about 15 degrees).
constexpr double kUpTolRad = 0.26;

void ok(const test::CommandResult& r) { ASSERT_EQ(r.exit_code, 0) << r.out << r.err; }

std::vector<std::string> lines_of(const std::string& s) {
  std::vector<std::string> out;
  std::istringstream in(s);
  for (std::string line; std::getline(in, line);) out.push_back(line);
  return out;
}

// The generated excavation, made once for every test of this file.
struct Data {
  test::ScratchDir dir{"first_use"};
  fs::path data = dir / "data";
  Data() {
    const auto r = run_strata({"-q", "synth", data.string(), "--size", "small", "--stages", "1", "--photos", "20",
                               "--width", "1000"});
    if (r.exit_code != 0) throw std::runtime_error("synth failed: " + r.err);
  }
};
const Data& data() {
  static const Data d;
  return d;
}

struct SurveyedMarker {
  std::string name, kind;
  double e = 0, n = 0, z = 0;
};

std::vector<SurveyedMarker> truth_markers() {
  std::ifstream in(data().data / "markers.csv");
  std::string line;
  std::getline(in, line);  // name,E,N,Z,sigma,kind
  std::vector<SurveyedMarker> out;
  while (std::getline(in, line)) {
    std::istringstream f(line);
    SurveyedMarker m;
    std::string e, n, z, sigma;
    std::getline(f, m.name, ',');
    std::getline(f, e, ',');
    std::getline(f, n, ',');
    std::getline(f, z, ',');
    std::getline(f, sigma, ',');
    std::getline(f, m.kind, ',');
    m.e = std::stod(e);
    m.n = std::stod(n);
    m.z = std::stod(z);
    out.push_back(m);
  }
  return out;
}

// A survey typed from a sketch: every coordinate rounded to 0.1 m, no sigma column;
// `shifts` moves named markers (metres, E and N) before the rounding.
void write_rounded_survey(const fs::path& out, const std::map<std::string, std::pair<double, double>>& shifts = {}) {
  std::ofstream f(out);
  f << "name,E,N,Z,kind\n";
  for (auto m : truth_markers()) {
    if (auto it = shifts.find(m.name); it != shifts.end()) {
      m.e += it->second.first;
      m.n += it->second.second;
    }
    auto r = [](double v) { return std::round(v * 10) / 10; };
    f << m.name << ',' << std::fixed << r(m.e) << ',' << r(m.n) << ',' << r(m.z) << ',' << m.kind << '\n';
  }
}

// init -> unit 101 -> layer L1 with its photos -> the clicks of L1 (gcp_list) and the
// survey `survey_csv` (none: a layer without markers) -> process L1 to the sparse stage.
struct Site {
  test::ScratchDir dir;
  std::string site;
  explicit Site(const std::string& name, const fs::path& survey_csv = {}) : dir(name), site((dir / "site").string()) {
    ok(run_strata({"-q", "init", site, "--crs", "EPSG:32636"}));
    ok(run_strata({"-q", "unit", "add", site, "101"}));
    ok(run_strata({"-q", "layer", "add", site, "L1", "--unit", "101"}));
    std::vector<std::string> photos;
    for (const auto& e : fs::directory_iterator(data().data / "photos" / "L1")) photos.push_back(e.path().string());
    std::sort(photos.begin(), photos.end());
    std::vector<std::string> import{"-q", "import", "photos", site, "--layer", "L1"};
    import.insert(import.end(), photos.begin(), photos.end());
    ok(run_strata(import));
    if (!survey_csv.empty()) {
      test::write_gcp_lines_of(data().data / "gcp_list.txt", "L1_", dir / "gcp_l1.txt");
      ok(run_strata({"-q", "import", "markers", site, (dir / "gcp_l1.txt").string(), "--format", "odm"}));
      ok(run_strata({"-q", "import", "markers", site, survey_csv.string(), "--update"}));
    }
    ok(run_strata({"-q", "process", site, "--layer", "L1", "--until", "sparse"}));
  }
  nlohmann::json findings() const {
    const auto r = run_strata({"report", site, "--layer", "L1", "--json", "--out", (dir / "report.html").string()});
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return nlohmann::json::parse(r.out.substr(0, r.out.rfind(']') + 1))[0]["findings"];
  }
};

const nlohmann::json* rule(const nlohmann::json& findings, const std::string& name) {
  for (const auto& f : findings) {
    if (f["rule"] == name) return &f;
  }
  return nullptr;
}

// One layer on the rounded survey, aligned once for the verdict and the markers table.
const Site& rounded_site() {
  static const Site s = [] {
    const fs::path survey = data().dir / "rounded.csv";
    write_rounded_survey(survey);
    return Site("first_use_rounded", survey);
  }();
  return s;
}

TEST(Verdict, RoundedSurveyIsJudgedAgainstWhatItCanDeliver) {
  const Site& s = rounded_site();
  const auto markers = nlohmann::json::parse(run_strata({"markers", s.site, "--json"}).out);
  double worst = 0;
  for (const auto& m : markers) {
    EXPECT_FALSE(m["sigma_stated"].get<bool>()) << "the file has no sigma column";
    for (const auto& r : m["residuals"]) {
      if (r.contains("xyz_m")) worst = std::max(worst, r["xyz_m"].get<double>());
    }
  }
  ASSERT_GT(worst, 0.02) << "the rounding must be visible in the residuals for this test to mean anything";
  const auto findings = s.findings();
  for (const auto& f : findings) EXPECT_NE(f["severity"], "problem") << f.dump();
  const auto* c = rule(findings, "control_rmse_survey");
  ASSERT_NE(c, nullptr) << findings.dump(1);
  EXPECT_EQ(c->at("severity"), "warning");
  const std::string message = c->at("message");
  EXPECT_NE(message.find("on a survey rounded to 0.1 m (about"), std::string::npos) << message;
  std::printf("[ figures  ] rounded survey: %s\n", message.c_str());
  EXPECT_EQ(rule(findings, "control_rmse"), nullptr);
  EXPECT_EQ(rule(findings, "marker_residual"), nullptr) << "residuals within what the rounding explains";
}

// Whether the survey stated its sigma moves the verdict, not the alignment: a project
// upgraded to schema 15 (every marker unstated) keeps its layers up to date.
// Runs `sql` on the site's project database, as another program would.
void edit_project(const std::string& site, const char* sql) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open((fs::path(site) / "project.gpkg").c_str(), &db), SQLITE_OK);
  EXPECT_EQ(sqlite3_exec(db, sql, nullptr, nullptr, nullptr), SQLITE_OK) << sql;
  sqlite3_close(db);
}

TEST(Verdict, StatingTheSigmaDoesNotRealignTheLayer) {
  const Site& s = rounded_site();
  edit_project(s.site, "UPDATE markers SET sigma_stated = 1 - sigma_stated");
  const auto r = run_strata({"process", s.site, "--layer", "L1", "--until", "sparse"});
  ok(r);
  EXPECT_NE(r.out.find("up to date"), std::string::npos) << r.out << r.err;
  const auto markers = nlohmann::json::parse(run_strata({"markers", s.site, "--json"}).out);
  ASSERT_FALSE(markers.empty());
  EXPECT_TRUE(markers[0]["sigma_stated"].get<bool>());
  edit_project(s.site, "UPDATE markers SET sigma_stated = 0");  // back as it was, for the other tests of this site
}

TEST(Verdict, RoundedSurveyStillFailsMarkersThatDisagree) {
  const fs::path survey = data().dir / "disagree.csv";
  // Four control markers moved 12-15 cm, each its own way: more than any 0.1 m
  // rounding explains, and too many to reject as one outlier.
  write_rounded_survey(survey, {{"GCP1", {0.15, 0}}, {"GCP4", {0, -0.15}}, {"GCP7", {0, 0.15}}, {"GCP5", {-0.12, 0}}});
  const Site s("first_use_disagree", survey);
  const auto findings = s.findings();
  const auto* c = rule(findings, "control_rmse");
  ASSERT_NE(c, nullptr) << findings.dump(1);
  EXPECT_EQ(c->at("severity"), "problem");
  const std::string message = c->at("message");
  EXPECT_NE(message.find("more than a survey rounded to 0.1 m explains"), std::string::npos) << message;
  std::printf("[ figures  ] markers that disagree: %s\n", message.c_str());
  EXPECT_NE(rule(findings, "marker_residual"), nullptr) << findings.dump(1);
}

TEST(Tables, MarkersShowTheirResidualsInEachProcessedLayer) {
  const Site& s = rounded_site();
  const auto r = run_strata({"markers", s.site});
  ok(r);
  EXPECT_EQ(r.out.find("Residuals appear here once"), std::string::npos);
  const auto lines = lines_of(r.out);
  const auto header = std::find_if(lines.begin(), lines.end(), [](const std::string& l) {
    return l.rfind("marker", 0) == 0 && l.find("L1") != std::string::npos;
  });
  ASSERT_NE(header, lines.end()) << r.out;
  // Every surveyed marker has a row with a number (mm) or what happened to it, under L1.
  const auto column_end = header->find("L1") + 2;
  for (const auto& m : truth_markers()) {
    const auto row = std::find_if(header, lines.end(), [&](const std::string& l) { return l.rfind(m.name + " ", 0) == 0; });
    ASSERT_NE(row, lines.end()) << m.name << " has no residual row:\n" << r.out;
    ASSERT_EQ(row->size(), column_end) << "right-aligned under L1: '" << *row << "'";
    const std::string cell = row->substr(row->find_last_of(' ') + 1);
    EXPECT_TRUE(std::isdigit(static_cast<unsigned char>(cell.front())) || cell == "located" || cell == "rejected")
        << *row;
  }
  EXPECT_NE(r.out.find("control RMSE"), std::string::npos) << r.out;

  // One layer axis by axis, and the JSON agrees with the text.
  const auto one = run_strata({"markers", s.site, "--layer", "L1"});
  ok(one);
  EXPECT_NE(one.out.find("dE mm"), std::string::npos) << one.out;
  const auto json = nlohmann::json::parse(run_strata({"markers", s.site, "--json"}).out);
  const auto& gcp3 = *std::find_if(json.begin(), json.end(), [](const auto& m) { return m["name"] == "GCP3"; });
  ASSERT_EQ(gcp3["residuals"].size(), 1u);
  const double de_mm = 1000 * gcp3["residuals"][0]["de_m"].get<double>();
  char de[32];
  std::snprintf(de, sizeof de, "%.1f", std::abs(de_mm) < 0.05 ? 0.0 : de_mm);
  const auto one_lines = lines_of(one.out);
  const auto table = std::find_if(one_lines.begin(), one_lines.end(),
                                  [](const std::string& l) { return l.rfind("Residuals in layer L1", 0) == 0; });
  ASSERT_NE(table, one_lines.end()) << one.out;
  const auto gcp3_row =
      std::find_if(table, one_lines.end(), [](const std::string& l) { return l.rfind("GCP3 ", 0) == 0; });
  ASSERT_NE(gcp3_row, one_lines.end()) << one.out;
  EXPECT_NE(gcp3_row->find(std::string(" ") + de + " "), std::string::npos) << *gcp3_row << " vs dE " << de;

  const auto missing = run_strata({"markers", s.site, "--layer", "L9"});
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_NE(missing.err.find("no layer 'L9'"), std::string::npos) << missing.err;
}

TEST(Tables, InfoWrapsALongDescriptionAndKeepsTheColumnsApart) {
  test::ScratchDir dir("first_use_info");
  const std::string site = (dir / "site").string();
  ok(run_strata({"-q", "init", site, "--crs", "EPSG:32636"}));
  const std::string long_description =
      "topsoil: dark greyish-brown loose loam with modern debris, roots and a little charcoal";
  ok(run_strata({"-q", "unit", "add", site, "101", "--description", long_description}));
  ok(run_strata({"-q", "unit", "add", site, "1020", "--type", "cut", "--description", "pit cut"}));
  ok(run_strata({"-q", "layer", "add", site, "L1", "--unit", "101"}));
  constexpr int kWidth = 60;
  setenv("COLUMNS", std::to_string(kWidth).c_str(), 1);
  const auto r = run_strata({"info", site});
  unsetenv("COLUMNS");
  ok(r);
  const auto lines = lines_of(r.out);
  const auto header = std::find_if(lines.begin(), lines.end(), [](const std::string& l) {
    return l.find("description") != std::string::npos && l.find("layers") != std::string::npos;
  });
  ASSERT_NE(header, lines.end()) << r.out;
  const auto layers_at = header->find("layers");
  const auto description_at = header->find("description");
  std::string description;
  bool in_units = false;
  for (auto it = header + 1; it != lines.end() && it->rfind("layers", 0) != 0; ++it) {
    in_units = true;
    EXPECT_LE(it->size(), std::size_t(kWidth)) << "wider than the terminal: '" << *it << "'";
    // Nothing of the description reaches into the layers column: a gap precedes it.
    const std::string left = it->substr(0, std::min(it->size(), layers_at));
    if (it->size() > layers_at) EXPECT_EQ(left.substr(left.size() - 2), "  ") << *it;
    if (left.size() <= description_at) continue;
    std::string part = left.substr(description_at);
    part.erase(part.find_last_not_of(' ') + 1);
    description += (description.empty() ? "" : " ") + part;
  }
  ASSERT_TRUE(in_units) << r.out;
  EXPECT_NE(description.find(long_description), std::string::npos)
      << "the description, every word of it, in its column:\n" << r.out;
  const auto row101 = std::find_if(lines.begin(), lines.end(), [](const std::string& l) { return l.find("  101 ") == 0; });
  ASSERT_NE(row101, lines.end()) << r.out;
  EXPECT_EQ(row101->substr(layers_at), "L1") << *row101;
}

TEST(Unreferenced, CamerasAreAboveTheSurfaceLookingDownAndTheScaleIsSaidArbitrary) {
  const Site s("first_use_noref");
  const fs::path cameras = s.dir / "cameras.csv";
  ok(run_strata({"-q", "export", "cameras", s.site, "--layer", "L1", "--format", "csv", "--out", cameras.string()}));
  // image,fx,fy,ppx,ppy,k1,k2,r11..r33,X,Y,Z against the generator's truth.
  auto read = [](const fs::path& p) {
    std::map<std::string, std::vector<double>> rows;
    std::ifstream in(p);
    std::string line;
    std::getline(in, line);
    while (std::getline(in, line)) {
      std::istringstream f(line);
      std::string name, cell;
      std::getline(f, name, ',');
      std::vector<double> v;
      while (std::getline(f, cell, ',')) v.push_back(std::stod(cell));
      rows[name] = v;
    }
    return rows;
  };
  const auto got = read(cameras);
  const auto truth = read(data().data / "truth" / "L1" / "cameras.csv");
  std::vector<Eigen::Vector3d> truth_centres, got_centres;
  for (const auto& [name, g] : got) {
    ASSERT_EQ(g.size(), 18u) << name;
    EXPECT_LT(g[14], 0) << name << ": the camera looks up (r33 = " << g[14] << ")";
    const auto& t = truth.at(name);
    truth_centres.emplace_back(t[15] - truth.begin()->second[15], t[16] - truth.begin()->second[16],
                               t[17] - truth.begin()->second[17]);
    got_centres.emplace_back(g[15], g[16], g[17]);
  }
  ASSERT_GE(got.size(), 15u);
  const Similarity3 to_got = fit_similarity(truth_centres, got_centres);
  const Eigen::Vector3d up = to_got.R * Eigen::Vector3d::UnitZ();
  const double tilt = std::acos(std::clamp(up.z(), -1.0, 1.0));
  EXPECT_LT(tilt, kUpTolRad) << "the truth's up in the layer's frame: " << up.transpose();
  std::printf("[ figures  ] layer without markers: the truth's up is %.1f degrees from the frame's +Z\n",
              tilt * 180 / std::numbers::pi);

  const auto findings = s.findings();
  ASSERT_NE(rule(findings, "not_georeferenced"), nullptr) << findings.dump(1);
  EXPECT_EQ(rule(findings, "low_resolution"), nullptr) << "a ground resolution in arbitrary units judges nothing";
  const std::string html = test::read_text(s.dir / "report.html");
  EXPECT_NE(html.find("units, arbitrary scale"), std::string::npos) << "the plans' scale bars";
  EXPECT_NE(html.find("unknown: the layer has no scale"), std::string::npos) << "the ground resolution";
}

}  // namespace
}  // namespace strata
