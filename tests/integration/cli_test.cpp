// Runs the real `strata` executable on small projects: the command-line contract.
#include "support/test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>

namespace strata {
namespace {

namespace fs = std::filesystem;
using test::run_strata;

int lines(const std::string& s) { return int(std::count(s.begin(), s.end(), '\n')); }

void ok(const test::CommandResult& r) { ASSERT_EQ(r.exit_code, 0) << r.err; }

TEST(Cli, HelpTeaches) {
  const auto r = run_strata({"--help"});
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.out.find("strata init"), std::string::npos);
  const auto rel = run_strata({"relation", "add", "--help"});
  EXPECT_NE(rel.out.find("filled_by"), std::string::npos) << rel.out;
}

TEST(Cli, ProjectLifecycleAndInfoJson) {
  test::ScratchDir dir("cli");
  const std::string site = (dir / "site").string();
  ok(run_strata({"init", site, "--crs", "EPSG:32636", "--name", "Test trench"}));
  ok(run_strata({"unit", "add", site, "101", "--description", "topsoil"}));
  ok(run_strata({"unit", "add", site, "102"}));
  ok(run_strata({"unit", "add", site, "103", "--type", "cut"}));
  ok(run_strata({"relation", "add", site, "102", "below", "101"}));
  ok(run_strata({"relation", "add", site, "103", "cuts", "102"}));
  ok(run_strata({"layer", "add", site, "L101", "--unit", "101"}));
  test::write_text(dir / "m.csv", "GCP1,734001,4174002,1450\nGCP2,734004,4174002,1450\nGCP3,734002,4174005,1450.2,0.005,check\n");
  ok(run_strata({"import", "markers", site, (dir / "m.csv").string()}));
  const auto r = run_strata({"info", site, "--json"});
  ok(r);
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["site"]["crs"], "EPSG:32636");
  EXPECT_EQ(j["units"].size(), 3u);
  EXPECT_EQ(j["relations"], 2);
  EXPECT_EQ(j["markers"]["check"], 1);
  EXPECT_EQ(j["layers"][0]["name"], "L101");
  const auto m = run_strata({"matrix", site, "--format", "json"});
  ok(m);
  const auto mj = nlohmann::json::parse(m.out);
  EXPECT_EQ(mj["order"].front(), "101");
}

TEST(Cli, ErrorsAreOneLineAndLeaveNothingBehind) {
  test::ScratchDir dir("err");
  const std::string site = (dir / "site").string();
  auto r = run_strata({"init", (dir / "geo").string(), "--crs", "EPSG:4326"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("geographic"), std::string::npos);
  EXPECT_FALSE(fs::exists(dir / "geo"));

  ok(run_strata({"init", site, "--crs", "EPSG:32636"}));
  ok(run_strata({"unit", "add", site, "1"}));
  ok(run_strata({"unit", "add", site, "2"}));
  ok(run_strata({"relation", "add", site, "1", "above", "2"}));
  r = run_strata({"relation", "add", site, "2", "above", "1"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("cycle 2 -> 1 -> 2"), std::string::npos) << r.err;

  test::write_text(dir / "bad.csv", "GCP1,734001,4174002,1450\nGCP2,x,4174002,1450\n");
  r = run_strata({"import", "markers", site, (dir / "bad.csv").string()});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("bad.csv:2: E 'x' is not a number"), std::string::npos) << r.err;
  const auto info = nlohmann::json::parse(run_strata({"info", site, "--json"}).out);
  EXPECT_EQ(info["markers"]["total"], 0);

  // A bad photo batch: non-zero exit, nothing in the database or media/.
  ok(run_strata({"layer", "add", site, "L1", "--unit", "1"}));
  cv::Mat img(64, 64, CV_8UC3, cv::Scalar(10, 200, 30));
  cv::imwrite((dir / "good.jpg").string(), img);
  test::write_text(dir / "bad.jpg", "not a photo");
  const std::string media_before = test::tree_fingerprint(dir / "site" / "media");
  r = run_strata({"import", "photos", site, "--layer", "L1", (dir / "good.jpg").string(),
                  (dir / "bad.jpg").string()});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("bad.jpg: not a JPEG"), std::string::npos) << r.err;
  EXPECT_EQ(test::tree_fingerprint(dir / "site" / "media"), media_before);
  EXPECT_EQ(nlohmann::json::parse(run_strata({"info", site, "--json"}).out)["photos"], 0);

  r = run_strata({"info", (dir / "nowhere").string()});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("project folder '" + (dir / "nowhere").string() + "' does not exist"), std::string::npos) << r.err;
  fs::create_directories(dir / "empty");
  r = run_strata({"info", (dir / "empty").string()});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("not a strata project"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace strata
