// strata import units|relations through the real executable: a spreadsheet register
// with quoted values comes in whole; a bad line or a cycle leaves the project as it was.
#include "support/test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>

namespace strata {
namespace {

namespace fs = std::filesystem;
using test::run_strata;

class RegisterImport : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_EQ(run_strata({"init", site_, "--crs", "EPSG:32636"}).exit_code, 0);
    test::write_text(dir_ / "units.csv",
                     "Code;Type;Description;Excavator\n"
                     "101;deposit;topsoil;AB\n"
                     "104;deposit;\"pale yellowish sandy gravel (sand, gravel); \"\"clean\"\"\";CD\n"
                     "105;cut;pit;CD\n");
    const auto r = run_strata({"import", "units", site_, (dir_ / "units.csv").string()});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find("3 new, 0 updated, 0 unchanged units"), std::string::npos) << r.out;
    EXPECT_NE(r.err.find("ignored: Excavator"), std::string::npos) << r.err;
  }

  nlohmann::json info() { return nlohmann::json::parse(run_strata({"info", site_, "--json"}).out); }

  // Runs an import that must fail on `expected`, with one line on stderr, exit 1,
  // and the project folder byte for byte as before.
  void expect_refused(const std::vector<std::string>& args, const std::string& expected) {
    const std::string before = test::tree_fingerprint(site_);
    const auto r = run_strata(args);
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find(expected), std::string::npos) << r.err;
    EXPECT_EQ(test::tree_fingerprint(site_), before);
  }

  test::ScratchDir dir_{"register"};
  std::string site_ = (dir_ / "site").string();
};

TEST_F(RegisterImport, QuotedDescriptionComesInWhole) {
  const auto j = info();
  ASSERT_EQ(j["units"].size(), 3u);
  EXPECT_EQ(j["units"][1]["code"], "104");
  EXPECT_EQ(j["units"][1]["description"], "pale yellowish sandy gravel (sand, gravel); \"clean\"");
  EXPECT_EQ(j["units"][2]["type"], "cut");
  const auto text = run_strata({"info", site_});
  EXPECT_NE(text.out.find("pale yellowish sandy gravel (s"), std::string::npos) << text.out;
  EXPECT_EQ(text.out.find("\"pale"), std::string::npos) << text.out;
}

TEST_F(RegisterImport, RelationsThenACycleOrBadLineChangesNothing) {
  test::write_text(dir_ / "relations.csv", "a,relation,b\n104,below,101\n105,cuts,104\n");
  const auto r = run_strata({"import", "relations", site_, (dir_ / "relations.csv").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(info()["relations"], 2);

  test::write_text(dir_ / "cycle.csv", "a,relation,b\n101,above,105\n105,above,101\n");
  expect_refused({"import", "relations", site_, (dir_ / "cycle.csv").string()},
                 "cycle.csv:3: relation '105 above 101' refused: it would make the Harris matrix contradictory: "
                 "cycle 105 -> 101 -> ");
  test::write_text(dir_ / "unknown.csv", "a,relation,b\n101,above,105\n105,above,999\n");
  expect_refused({"import", "relations", site_, (dir_ / "unknown.csv").string()},
                 "unknown.csv:3: unit '999' is not in the project");
  test::write_text(dir_ / "bad_units.csv", "code,type\n106,deposit\n107,layer\n");
  expect_refused({"import", "units", site_, (dir_ / "bad_units.csv").string()},
                 "bad_units.csv:3: unit '107': type 'layer' is not one of deposit, cut, structure, interface");
  test::write_text(dir_ / "changed.csv", "code,type\n106,deposit\n105,deposit\n");
  expect_refused({"import", "units", site_, (dir_ / "changed.csv").string()},
                 "changed.csv:3: unit '105' is already in the project");
  EXPECT_EQ(info()["units"].size(), 3u);
  EXPECT_EQ(info()["relations"], 2);

  const auto updated = run_strata({"import", "units", site_, (dir_ / "changed.csv").string(), "--update"});
  ASSERT_EQ(updated.exit_code, 0) << updated.err;
  EXPECT_EQ(info()["units"][2]["type"], "deposit");
}

TEST_F(RegisterImport, HelpTeachesColumnsAndAnExample) {
  const auto u = run_strata({"import", "units", "--help"});
  EXPECT_NE(u.out.find("code,type,description"), std::string::npos) << u.out;
  const auto r = run_strata({"import", "relations", "--help"});
  EXPECT_NE(r.out.find("a,relation,b"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("filled_by"), std::string::npos) << r.out;
}

}  // namespace
}  // namespace strata
