// The field station's marker workspace through its API, as a person uses it: a synthetic
// layer whose markers are non-coded chequered quadrant targets (coded-target detection
// finds none), aligned without georeference; a scripted user clicks each marker in two
// photos with 2 px of noise, georeferences, asks for the predicted positions, confirms
// them and georeferences again. Truth: the generator's gcp_list.txt (the true pixel of
// every marker in every photo that sees it). Measured against the same layer with coded
// targets (ArUco), detected by strata.
// Eigen before cpp-httplib (served.hpp): <resolv.h>, which httplib includes, defines a
// macro `_res` that Eigen uses as a parameter name.
#include <Eigen/Core>

#include "integration/served.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <csignal>
#include <fstream>
#include <iostream>
#include <map>
#include <random>
#include <sstream>

namespace strata {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test::run_strata;
using test::Served;

// One stage, 20 photos at 2000 px: the coded targets of the comparison are found
// from this width on (at 1000 px two of the four control markers are detected in one
// photo only, and the layer cannot be georeferenced on them).
constexpr int kPhotos = 20;
constexpr int kWidth = 2000;
constexpr double kClickNoisePx = 2.0;  // pixels, 1 sigma per axis: a careful click
constexpr std::uint32_t kClickSeed = 15;
// Acceptance (issue 43): predictions in at least 90 % of the photos that truly see the
// marker, each within 1 px of the truth after refinement; the check-marker RMSE after
// confirmation within 1.2 x that of coded targets on the same layer.
constexpr double kMinPredictedFraction = 0.9;
constexpr double kMaxPredictionErrorPx = 1.0;
constexpr double kMaxCheckRmseRatio = 1.2;

struct Truth {
  std::string image, marker;
  Eigen::Vector2d pixel;
};

std::vector<Truth> read_truth(const fs::path& gcp_list, const std::string& prefix) {
  std::ifstream in(gcp_list);
  std::string line;
  std::getline(in, line);  // the CRS
  std::vector<Truth> out;
  while (std::getline(in, line)) {
    std::stringstream ss(line);
    std::string e, n, z, x, y, image, marker;
    for (auto* f : {&e, &n, &z, &x, &y, &image, &marker}) std::getline(ss, *f, '\t');
    if (image.rfind(prefix, 0) == 0) out.push_back({image, marker, {std::stod(x), std::stod(y)}});
  }
  return out;
}

void ok(const test::CommandResult& r) { ASSERT_EQ(r.exit_code, 0) << r.err; }

// A synthetic layer imported into a new project (photos and the survey; no clicks).
void make_layer(const fs::path& data, const fs::path& site, const std::string& pattern) {
  ok(run_strata({"-q", "synth", data.string(), "--size", "small", "--stages", "1", "--photos", std::to_string(kPhotos),
                 "--width", std::to_string(kWidth), "--marker-pattern", pattern}));
  ok(run_strata({"-q", "init", site.string(), "--crs", "EPSG:32636"}));
  ok(run_strata({"-q", "unit", "add", site.string(), "101"}));
  ok(run_strata({"-q", "layer", "add", site.string(), "L1", "--unit", "101"}));
  std::vector<std::string> import{"-q", "import", "photos", site.string(), "--layer", "L1"};
  for (const auto& e : fs::directory_iterator(data / "photos" / "L1")) import.push_back(e.path().string());
  ok(run_strata(import));
  ok(run_strata({"-q", "import", "markers", site.string(), (data / "markers.csv").string()}));
}

// Georeferences (processes to sparse) through the API and waits for the job.
void align(Served& s) {
  const auto r = s.post("/api/layers/L1/process", json{{"until", "sparse"}});
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string stream = s.follow(json::parse(r->body).at("id"));
  ASSERT_NE(stream.find("\"state\":\"done\""), std::string::npos) << stream.substr(stream.size() > 2000 ? stream.size() - 2000 : 0);
}

TEST(MarkerWorkspace, AScriptedUserPlacesNonCodedMarkersAsWellAsCodedTargetsAreDetected) {
  std::signal(SIGPIPE, SIG_IGN);
  test::ScratchDir dir("workspace");
  const fs::path site = dir / "site";
  make_layer(dir / "data", site, "quadrant");
  const auto truth = read_truth(dir / "data" / "gcp_list.txt", "L1_");
  std::map<std::string, std::vector<const Truth*>> by_marker;
  for (const auto& t : truth) by_marker[t.marker].push_back(&t);

  Served s(dir.path(), site);
  align(s);
  json overview = s.get("/api/layers/L1/markers");
  ASSERT_TRUE(overview.at("aligned").get<bool>());
  ASSERT_FALSE(overview.at("georeferenced").get<bool>()) << "non-coded markers, no clicks: nothing to georeference on";

  // Clicks: per marker seen in two photos or more, the first and the last that see it
  // (the widest baseline a person would pick), each off by Gaussian noise.
  std::mt19937 rng(kClickSeed);
  std::normal_distribution<double> noise(0.0, kClickNoisePx);
  std::map<std::pair<std::string, std::string>, bool> clicked;
  for (const auto& [marker, seen] : by_marker) {
    if (seen.size() < 2) continue;
    for (const Truth* t : {seen.front(), seen.back()}) {
      const Eigen::Vector2d c = t->pixel + Eigen::Vector2d(noise(rng), noise(rng));
      const auto r = s.post("/api/layers/L1/markers/" + marker + "/clicks", json{{"photo", t->image}, {"x", c.x()}, {"y", c.y()}});
      ASSERT_EQ(r->status, 201) << r->body;
      const json e = json::parse(r->body);
      EXPECT_EQ(e.at("status"), "clicked");
      EXPECT_DOUBLE_EQ(e.at("observation").at("x").get<double>(), c.x());  // stored as sent: full-image pixels
      EXPECT_DOUBLE_EQ(e.at("observation").at("y").get<double>(), c.y());
      clicked[{marker, t->image}] = true;
    }
  }
  ASSERT_GE(clicked.size(), 8u) << "the scene should show at least 4 markers in 2 photos or more";
  align(s);
  overview = s.get("/api/layers/L1/markers");
  ASSERT_TRUE(overview.at("georeferenced").get<bool>()) << overview.dump();

  // The strip: the photos predicted to see each marker are those that truly do.
  int truly = 0, listed = 0;
  for (const auto& [marker, seen] : by_marker) {
    const json photos = s.get("/api/layers/L1/markers/" + marker).at("photos");
    std::map<std::string, bool> sees;
    for (const auto& p : photos) sees[p.at("name")] = p.at("sees").get<bool>();
    for (const Truth* t : seen) {
      ++truly;
      listed += sees[t->image] ? 1 : 0;
    }
  }
  std::cout << "workspace: " << listed << " of " << truly << " photos that see a marker are listed as seeing it\n";
  EXPECT_GE(listed, truly * 9 / 10);

  // Predictions (the guide), against the truth.
  const auto g = s.post("/api/layers/L1/guide", json::object());
  ASSERT_EQ(g->status, 200) << g->body;
  int should = 0, predicted = 0;
  double worst = 0;
  std::vector<std::pair<std::string, std::string>> to_confirm;
  for (const auto& [marker, seen] : by_marker) {
    if (seen.size() < 2) continue;
    std::map<std::string, json> entry;
    const json photos = s.get("/api/layers/L1/markers/" + marker).at("photos");
    for (const auto& p : photos) entry[p.at("name")] = p;
    for (const Truth* t : seen) {
      if (clicked.count({marker, t->image})) continue;
      ++should;
      const json& e = entry.at(t->image);
      if (e.at("status") != "predicted") continue;
      ++predicted;
      const Eigen::Vector2d at(e.at("observation").at("x").get<double>(), e.at("observation").at("y").get<double>());
      worst = std::max(worst, (at - t->pixel).norm());
      to_confirm.emplace_back(marker, t->image);
    }
  }
  const double fraction = should ? double(predicted) / should : 0;
  std::cout << "workspace: predicted in " << predicted << " of " << should << " photos (" << 100 * fraction
            << " %), farthest from the truth " << worst << " px\n";
  EXPECT_GE(fraction, kMinPredictedFraction);
  EXPECT_LE(worst, kMaxPredictionErrorPx);

  // Review: confirm each prediction; one rejected instead, which the guide does not make again.
  ASSERT_FALSE(to_confirm.empty());
  const auto [rejected_marker, rejected_photo] = to_confirm.back();
  to_confirm.pop_back();
  for (const auto& [marker, photo] : to_confirm) {
    const auto r = s.post("/api/layers/L1/markers/" + marker + "/review", json{{"photo", photo}, {"verdict", "confirmed"}});
    ASSERT_EQ(r->status, 200) << r->body;
    EXPECT_EQ(json::parse(r->body).at("status"), "confirmed");
  }
  auto r = s.post("/api/layers/L1/markers/" + rejected_marker + "/review",
                  json{{"photo", rejected_photo}, {"verdict", "rejected"}});
  ASSERT_EQ(r->status, 200) << r->body;
  EXPECT_EQ(json::parse(r->body).at("status"), "rejected");
  ASSERT_EQ(s.post("/api/layers/L1/guide", json::object())->status, 200);
  const json after_guide = s.get("/api/layers/L1/markers/" + rejected_marker).at("photos");
  for (const auto& p : after_guide) {
    if (p.at("name") == rejected_photo) {
      EXPECT_EQ(p.at("status"), "rejected") << "the guide placed a rejected position again";
    }
  }
  // A review of what is not there is refused naming the field.
  r = s.post("/api/layers/L1/markers/" + rejected_marker + "/review", json{{"photo", "nothing.jpg"}, {"verdict", "confirmed"}});
  EXPECT_EQ(r->status, 400);
  EXPECT_EQ(json::parse(r->body).at("error").at("field"), "photo");
  r = s.post("/api/layers/L1/markers/" + rejected_marker + "/clicks", json{{"photo", rejected_photo}, {"x", -3.0}, {"y", 10.0}});
  EXPECT_EQ(r->status, 400);
  EXPECT_EQ(json::parse(r->body).at("error").at("field"), "x");

  align(s);
  overview = s.get("/api/layers/L1/markers");
  const json check = overview.at("check_rmse");
  ASSERT_TRUE(check.is_object()) << overview.dump();
  const double workspace_rmse = check.at("xyz_m").get<double>();
  s.process().kill_now();

  // The same layer with coded targets, detected by strata.
  const fs::path coded = dir / "coded";
  make_layer(dir / "coded_data", coded, "aruco");
  const auto p = run_strata({"process", coded.string(), "--layer", "L1", "--until", "sparse", "--json"});
  ok(p);
  const json q = json::parse(p.out.substr(p.out.find('{')));
  ASSERT_GT(q.at("detected_observations").get<int>(), 0) << "no coded target detected: the comparison means nothing";
  ASSERT_TRUE(q.at("georeferenced").get<bool>());
  const double coded_rmse = q.at("check_rmse").at("xyz_m").get<double>();
  std::cout << "workspace: check RMSE " << 1000 * workspace_rmse << " mm (" << check.at("markers")
            << " markers) against " << 1000 * coded_rmse << " mm with coded targets (" << q.at("detected_observations")
            << " detections)\n";
  EXPECT_LE(workspace_rmse, kMaxCheckRmseRatio * coded_rmse);
}

}  // namespace
}  // namespace strata
