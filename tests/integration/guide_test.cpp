// 'strata markers guide' end to end with the real executable (docs/markers.md):
// a synthetic layer whose markers are non-coded chequered quadrant targets (coded-target
// detection finds nothing), clicked in 2 photos each with 2 px of Gaussian noise.
// Truth: the generator's gcp_list.txt, the true pixel of every marker in every photo
// that sees it.
#include "support/test_support.hpp"

#include <Eigen/Core>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iostream>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace strata {
namespace {

namespace fs = std::filesystem;
using test::run_strata;

// The scene of align_test: one stage, 20 photos per layer at 1000 px (the smallest
// set that aligns every photo, see docs/sfm.md).
constexpr int kPhotos = 20;
constexpr int kWidth = 1000;
constexpr double kClickNoisePx = 2.0;        // pixels, 1 sigma per axis (a careful click)
constexpr std::uint32_t kClickSeed = 15;
// Acceptance: found in >= 90 % of the photos that truly see the marker
// (photos without a click), the 90th percentile of the distance to the true pixel
// within 0.5 px, and no guided observation in a photo that does not see the marker.
constexpr double kMinFoundFraction = 0.9;
constexpr double kMaxP90ErrorPx = 0.5;
// The refined clicks are centred by the same symmetry step: their 90th percentile too.
constexpr double kMaxP90RefinedClickPx = 0.5;

void ok(const test::CommandResult& r) { ASSERT_EQ(r.exit_code, 0) << r.err; }
int lines(const std::string& s) { return int(std::count(s.begin(), s.end(), '\n')); }

struct TruthObservation {
  std::string fields;  // geo_x geo_y geo_z (tab separated)
  std::string image;
  std::string marker;
  double x = 0, y = 0;
};

std::vector<TruthObservation> read_gcp_list(const fs::path& path, const std::string& layer_prefix, std::string* crs) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  *crs = line;
  std::vector<TruthObservation> out;
  while (std::getline(in, line)) {
    std::stringstream ss(line);
    std::string e, n, z, x, y, image, marker;
    std::getline(ss, e, '\t');
    std::getline(ss, n, '\t');
    std::getline(ss, z, '\t');
    std::getline(ss, x, '\t');
    std::getline(ss, y, '\t');
    std::getline(ss, image, '\t');
    std::getline(ss, marker, '\t');
    if (image.rfind(layer_prefix, 0) != 0) continue;
    out.push_back({e + "\t" + n + "\t" + z, image, marker, std::stod(x), std::stod(y)});
  }
  return out;
}

std::string gcp_line(const TruthObservation& t, double x, double y) {
  return t.fields + "\t" + std::to_string(x) + "\t" + std::to_string(y) + "\t" + t.image + "\t" + t.marker + "\n";
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, std::size_t(std::ceil(q * double(v.size()))) - 1)];
}

nlohmann::json process_json(const std::string& site) {
  const auto r = run_strata({"-q", "process", site, "--layer", "L1", "--until", "sparse", "--json"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return nlohmann::json::parse(r.out.substr(r.out.find('{')));
}

TEST(Guide, FindsClickedQuadrantMarkersInThePhotosThatSeeThem) {
  test::ScratchDir dir("guide");
  const fs::path data = dir / "data";
  const std::string site = (dir / "site").string();
  ok(run_strata({"-q", "synth", data.string(), "--size", "small", "--stages", "1", "--photos",
                 std::to_string(kPhotos), "--width", std::to_string(kWidth), "--marker-pattern", "quadrant"}));
  ok(run_strata({"-q", "init", site, "--crs", "EPSG:32636"}));
  ok(run_strata({"-q", "unit", "add", site, "101"}));
  ok(run_strata({"-q", "layer", "add", site, "L1", "--unit", "101"}));
  std::vector<std::string> import{"-q", "import", "photos", site, "--layer", "L1"};
  for (const auto& e : fs::directory_iterator(data / "photos" / "L1")) import.push_back(e.path().string());
  ok(run_strata(import));

  // Clicks: per marker, the first and the last photo of the capture that see it (the
  // widest baseline a person would pick), each with Gaussian noise. A marker seen in
  // two photos only is clicked in both (nothing left to guide, but it still counts in
  // the check RMSE of both runs).
  std::string crs;
  const auto truth = read_gcp_list(data / "gcp_list.txt", "L1_", &crs);
  std::map<std::string, std::vector<const TruthObservation*>> by_marker;
  for (const auto& t : truth) by_marker[t.marker].push_back(&t);
  std::mt19937 rng(kClickSeed);
  std::normal_distribution<double> noise(0.0, kClickNoisePx);
  std::map<std::pair<std::string, std::string>, Eigen::Vector2d> clicks;  // (marker, image) -> click
  std::string first_clicks = crs + "\n", second_clicks = crs + "\n";
  std::string held_back;  // the marker whose second click comes late (refusal step)
  for (const auto& [marker, seen] : by_marker) {
    if (seen.size() < 2) continue;  // a person cannot click it twice
    for (const TruthObservation* t : {seen.front(), seen.back()}) {
      const Eigen::Vector2d c(t->x + noise(rng), t->y + noise(rng));
      clicks[{marker, t->image}] = c;
      const bool late = held_back.empty() && seen.size() >= 3 && t == seen.back();
      (late ? second_clicks : first_clicks) += gcp_line(*t, c.x(), c.y());
    }
    if (held_back.empty() && seen.size() >= 3) held_back = marker;
  }
  ASSERT_GE(clicks.size(), 2u * 4u) << "the scene should show at least 4 markers in 2+ photos";
  test::write_text(dir / "clicks1.txt", first_clicks);
  test::write_text(dir / "clicks2.txt", second_clicks);
  ok(run_strata({"-q", "import", "markers", site, (dir / "clicks1.txt").string(), "--format", "odm"}));
  ok(run_strata({"-q", "import", "markers", site, (data / "markers.csv").string()}));

  // Refusal 1: the layer is not aligned. One line, the project unchanged.
  std::string listing = run_strata({"markers", site, "--json"}).out;
  auto r = run_strata({"markers", "guide", site, "--layer", "L1"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("not aligned"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--until sparse"), std::string::npos) << r.err;
  EXPECT_EQ(run_strata({"markers", site, "--json"}).out, listing);

  // Refusal 2: a marker clicked in one photo only.
  const auto q_partial = process_json(site);
  ASSERT_TRUE(q_partial["georeferenced"].get<bool>()) << q_partial["markers"];
  listing = run_strata({"markers", site, "--json"}).out;  // now with the layer's residuals
  r = run_strata({"markers", "guide", site, "--layer", "L1"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("marker " + held_back + " is clicked in only 1"), std::string::npos) << r.err;
  EXPECT_EQ(run_strata({"markers", site, "--json"}).out, listing);

  // Clicks alone: the baseline.
  ok(run_strata({"-q", "import", "markers", site, (dir / "clicks2.txt").string(), "--format", "odm"}));
  const auto q_clicks = process_json(site);
  ASSERT_TRUE(q_clicks["georeferenced"].get<bool>());
  ASSERT_GE(q_clicks["check_rmse"]["markers"].get<int>(), 1) << q_clicks["markers"];
  // Non-coded targets: coded-target detection finds none of them.
  EXPECT_EQ(q_clicks["detected_observations"].get<int>(), 0);

  // Guide.
  r = run_strata({"-q", "markers", "guide", site, "--layer", "L1", "--json"});
  ok(r);
  const auto g = nlohmann::json::parse(r.out);
  std::map<std::pair<std::string, std::string>, Eigen::Vector2d> guided;
  std::vector<double> click_errors, refined_errors;
  std::map<std::pair<std::string, std::string>, const TruthObservation*> truth_at;
  for (const auto& t : truth) truth_at[{t.marker, t.image}] = &t;
  for (const auto& m : g["markers"]) {
    const std::string name = m["marker"];
    for (const auto& a : m["added"]) guided[{name, a["image"]}] = {a["x"].get<double>(), a["y"].get<double>()};
    for (const auto& c : m["clicks"]) {
      const auto* t = truth_at.at({name, c["image"].get<std::string>()});
      const Eigen::Vector2d tp(t->x, t->y);
      click_errors.push_back((Eigen::Vector2d(c["clicked"][0], c["clicked"][1]) - tp).norm());
      if (!c["refined"].is_null()) refined_errors.push_back((Eigen::Vector2d(c["refined"][0], c["refined"][1]) - tp).norm());
    }
  }
  int should = 0, found = 0, wrong = 0;
  std::vector<double> errors;
  for (const auto& t : truth) {
    if (!clicks.count({t.marker, t.image})) {
      ++should;
      const auto it = guided.find({t.marker, t.image});
      if (it != guided.end()) {
        ++found;
        errors.push_back((it->second - Eigen::Vector2d(t.x, t.y)).norm());
      }
    }
  }
  for (const auto& [key, px] : guided) wrong += truth_at.count(key) ? 0 : 1;
  const double fraction = should > 0 ? double(found) / should : 0;
  std::cout << "guide: found " << found << " of " << should << " (" << 100 * fraction << " %), " << wrong
            << " in photos that do not see the marker; error to truth: median " << percentile(errors, 0.5)
            << " px, p90 " << percentile(errors, 0.9) << " px, max " << percentile(errors, 1.0) << " px; clicks "
            << percentile(click_errors, 0.5) << " px median -> refined " << percentile(refined_errors, 0.5)
            << " px median, p90 " << percentile(refined_errors, 0.9) << " px (" << refined_errors.size() << " of "
            << click_errors.size() << " refined)\n";
  EXPECT_GE(fraction, kMinFoundFraction);
  EXPECT_EQ(wrong, 0);
  EXPECT_LE(percentile(errors, 0.9), kMaxP90ErrorPx);
  EXPECT_LE(percentile(refined_errors, 0.9), kMaxP90RefinedClickPx);
  EXPECT_GE(refined_errors.size(), click_errors.size() * 3 / 4);

  // The listing counts the sources.
  const auto listed = nlohmann::json::parse(run_strata({"markers", site, "--json"}).out);
  int guided_listed = 0, clicked_listed = 0;
  for (const auto& m : listed) {
    guided_listed += m["sources"]["guided"].get<int>();
    clicked_listed += m["sources"]["clicked"].get<int>();
  }
  EXPECT_EQ(guided_listed, int(guided.size()));
  EXPECT_EQ(clicked_listed, int(clicks.size()));

  // With the guided observations the check markers agree better with the survey.
  const auto q_guided = process_json(site);
  ASSERT_TRUE(q_guided["georeferenced"].get<bool>());
  const double rmse_clicks = q_clicks["check_rmse"]["xyz_m"].get<double>();
  const double rmse_guided = q_guided["check_rmse"]["xyz_m"].get<double>();
  std::cout << "check RMSE (3D): clicks alone " << 1000 * rmse_clicks << " mm, with guided " << 1000 * rmse_guided
            << " mm (" << q_guided["check_rmse"]["markers"] << " check markers)\n";
  EXPECT_EQ(q_guided["check_rmse"]["markers"], q_clicks["check_rmse"]["markers"]);
  EXPECT_LT(rmse_guided, rmse_clicks);

  // A second run replaces the guided rows instead of adding to them.
  r = run_strata({"-q", "markers", "guide", site, "--layer", "L1", "--json"});
  ok(r);
  const auto g2 = nlohmann::json::parse(r.out);
  EXPECT_EQ(g2["replaced"].get<int>(), int(guided.size()));
}

}  // namespace
}  // namespace strata
