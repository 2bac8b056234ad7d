// Two processes, one project (docs/reliability.md): while one command changes a
// project, a second writing command stops with one line naming the first (or waits
// for it with --wait), reading commands work, and nothing is corrupted or lost. A
// writer killed mid-run does not block the next one.
#include "integration/field_project.hpp"

#include <gtest/gtest.h>

#include <csignal>

namespace strata {
namespace {

namespace fs = std::filesystem;
using test::run_strata;

// Seconds a background `process` may take to start and take the lock, on a machine
// that builds beside the tests.
constexpr double kLockTimeoutS = 120;

class Concurrency : public ::testing::Test {
 protected:
  // Two synthetic layers; L1 aligned (sparse), L2 only imported.
  // Made once for every process of the suite (ctest runs each test in its own process;
  // support/shared_scene.hpp); each test works on its own copy of the project.
  static void SetUpTestSuite() {
    scratch_ = new test::ScratchDir("concurrency");
    try {
      // 14 photos a layer: with 12, L2 of this seed registers too few photos to see three markers.
      shared_ = test::shared_project("concurrency", 2, 14, 5, std::vector<std::string>{"--until", "sparse"});
    } catch (const std::exception& e) {
      setup_error_ = e.what();
    }
  }
  // A failure while the shared project is made fails every test (gtest would report
  // them as skipped, and ctest count a skip as no failure).
  void SetUp() override {
    if (!setup_error_.empty()) FAIL() << "the shared project could not be made: " << setup_error_;
  }
  static void TearDownTestSuite() {
    delete scratch_;
    scratch_ = nullptr;
  }
  fs::path copy_template(const std::string& name) const {
    const fs::path site = *scratch_ / name;
    fs::remove_all(site);
    test::copy_scene(shared_ / "template", site);
    return site;
  }
  static fs::path data() { return shared_ / "data"; }
  static fs::path scratch() { return scratch_->path(); }

  static test::ScratchDir* scratch_;
  static fs::path shared_;
  static std::string setup_error_;
};
test::ScratchDir* Concurrency::scratch_ = nullptr;
fs::path Concurrency::shared_;
std::string Concurrency::setup_error_;

// `strata ARGS...` refused because `holder` has the project: exit 1, one line that
// names the holder's command and pid.
void expect_busy(const test::CommandResult& r, const std::string& holder_command, pid_t holder) {
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_EQ(test::line_count(r.err), 1) << r.err;
  const std::string expected =
      "strata: error: project is busy: `" + holder_command + "` (pid " + std::to_string(holder) + ", since ";
  EXPECT_EQ(r.err.rfind(expected, 0), 0u) << r.err;
}

TEST_F(Concurrency, SecondWriterStopsNamingTheFirstReadersWork) {
  const fs::path site = copy_template("busy");
  const std::string s = site.string();
  test::Background process(scratch(), {"process", s, "--layer", "L2", "--until", "dense"});
  ASSERT_TRUE(test::wait_for_lock(site, process, kLockTimeoutS)) << process.wait().err;
  const std::string holder = "strata process --layer L2 --until dense";

  // Writers, each refused before it reads or writes anything.
  const std::vector<std::string> refused_tables = {"units", "layers", "images", "markers", "unit_volumes"};
  const std::string rows_before = test::database_rows(site / "project.gpkg", refused_tables);
  const std::string media_before = test::tree_fingerprint(site / "media");
  const std::string extra_photo = test::layer_photos(data(), "L1").front();
  expect_busy(run_strata({"process", s, "--layer", "L1", "--until", "sparse", "--force"}), holder, process.pid());
  expect_busy(run_strata({"import", "photos", s, "--layer", "L2", extra_photo}), holder, process.pid());
  expect_busy(run_strata({"import", "markers", s, (data() / "markers.csv").string(), "--update"}), holder,
              process.pid());
  expect_busy(run_strata({"volume", s}), holder, process.pid());
  expect_busy(run_strata({"unit", "add", s, "999"}), holder, process.pid());
  // The running process commits its own stages meanwhile; the refused commands'
  // tables and the photos are as they were.
  EXPECT_EQ(test::database_rows(site / "project.gpkg", refused_tables), rows_before);
  EXPECT_EQ(test::tree_fingerprint(site / "media"), media_before);

  // Readers: the last committed state, while the writer works.
  auto r = run_strata({"info", s, "--json"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("\"L2\""), std::string::npos);
  r = run_strata({"markers", s});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  r = run_strata({"export", "cameras", s, "--layer", "L1", "--out", (site / "cameras_L1.csv").string()});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  r = run_strata({"report", s, "--layer", "L1", "--out", (site / "report_L1.html").string()});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(process.running()) << "the background process ended before the readers did: the test proved nothing";

  const auto done = process.wait();
  ASSERT_EQ(done.exit_code, 0) << done.err;
  EXPECT_EQ(test::integrity(site / "project.gpkg"), "ok");
  // Free again: the refused writer runs, and the project has both layers' results.
  r = run_strata({"unit", "add", s, "999"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  for (const char* layer : {"L1", "L2"}) {
    r = run_strata({"export", "cameras", s, "--layer", layer, "--out", (site / "c.csv").string()});
    EXPECT_EQ(r.exit_code, 0) << layer << ": " << r.err;
  }
}

TEST_F(Concurrency, WaitingWritersRunOneAfterTheOther) {
  const fs::path site = copy_template("wait");
  const std::string s = site.string();
  test::Background first(scratch(), {"process", s, "--layer", "L2", "--until", "sparse"});
  ASSERT_TRUE(test::wait_for_lock(site, first, kLockTimeoutS)) << first.wait().err;
  // A second process of the other layer and an import, both told to wait.
  test::Background second(scratch(), {"--wait", "600", "process", s, "--layer", "L1", "--until", "sparse", "--force"});
  const auto unit = run_strata({"--wait", "600", "unit", "add", s, "999"});
  EXPECT_EQ(unit.exit_code, 0) << unit.err;
  EXPECT_NE(unit.err.find("project is busy: `strata"), std::string::npos) << unit.err;
  const auto a = first.wait();
  const auto b = second.wait();
  ASSERT_EQ(a.exit_code, 0) << a.err;
  ASSERT_EQ(b.exit_code, 0) << b.err;
  EXPECT_NE(b.err.find("project is busy: `strata process --layer L2 --until sparse`"), std::string::npos) << b.err;
  EXPECT_NE(b.err.find("waiting"), std::string::npos) << b.err;
  EXPECT_EQ(test::integrity(site / "project.gpkg"), "ok");
  // No lost rows: both reconstructions and the unit are there.
  for (const char* layer : {"L1", "L2"}) {
    const auto r = run_strata({"export", "cameras", s, "--layer", layer, "--out", (site / "c.csv").string()});
    EXPECT_EQ(r.exit_code, 0) << layer << ": " << r.err;
  }
  EXPECT_NE(run_strata({"info", s}).out.find("999"), std::string::npos);
}

TEST_F(Concurrency, KilledWriterDoesNotBlockTheNext) {
  const fs::path site = copy_template("stale");
  const std::string s = site.string();
  test::Background process(scratch(), {"process", s, "--layer", "L2", "--until", "sparse"});
  ASSERT_TRUE(test::wait_for_lock(site, process, kLockTimeoutS)) << process.wait().err;
  const pid_t dead = process.pid();
  process.kill_now();
  // The lock file still names the killed command; the lock itself went with it.
  EXPECT_NE(test::read_text(site / "project.lock").find("pid=" + std::to_string(dead)), std::string::npos);
  const auto before = test::project_state(site);
  const auto r = run_strata({"unit", "add", s, "999"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("`strata process --layer L2 --until sparse` (pid " + std::to_string(dead)), std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("did not finish"), std::string::npos) << r.err;
  EXPECT_EQ(test::integrity(site / "project.gpkg"), "ok");
  EXPECT_EQ(test::project_state(site).media, before.media);
  EXPECT_EQ(test::read_text(site / "project.lock"), "") << "released at the end of the command";
}

}  // namespace
}  // namespace strata
