// Interrupting `strata process` (SIGKILL, as a crash or a pulled plug would) must
// lose nothing: the database passes integrity_check, the photos are untouched,
// and the next run resumes from the cached stages and completes.
#include "support/test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <sqlite3.h>

#include <csignal>
#include <sys/wait.h>
#include <unistd.h>

namespace strata {
namespace {

namespace fs = std::filesystem;
using test::run_strata;

// Runs strata with STRATA_CRASH_AT set: the process kills itself with SIGKILL at
// that point (src/core/fault.hpp), deterministically, mid-stage.
int run_until_fault(const std::string& fault, const std::vector<std::string>& args) {
  const pid_t pid = fork();
  if (pid == 0) {
    setenv("STRATA_CRASH_AT", fault.c_str(), 1);
    const std::string exe = test::strata_exe().string();
    std::vector<char*> argv{const_cast<char*>(exe.c_str())};
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    if (!freopen("/dev/null", "w", stdout) || !freopen("/dev/null", "w", stderr)) _exit(126);
    execv(exe.c_str(), argv.data());
    _exit(127);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  return WIFSIGNALED(status) ? WTERMSIG(status) : -WEXITSTATUS(status);
}

std::string integrity(const fs::path& db_path) {
  sqlite3* db = nullptr;
  sqlite3_open_v2(db_path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr);
  sqlite3_stmt* st = nullptr;
  sqlite3_prepare_v2(db, "PRAGMA integrity_check", -1, &st, nullptr);
  std::string out;
  while (sqlite3_step(st) == SQLITE_ROW) out += reinterpret_cast<const char*>(sqlite3_column_text(st, 0));
  sqlite3_finalize(st);
  sqlite3_close(db);
  return out;
}

TEST(Resume, KilledProcessingLosesNothingAndResumes) {
  test::ScratchDir dir("resume");
  const fs::path data = dir / "data";
  const fs::path site = dir / "site";
  // 12 photos at 800 px: the layer must align whatever the matcher's draw (8 at 640 px
  // registered 2 or 3 photos and sometimes found no initial pair at all, so the run
  // stopped before the commit it is killed at).
  auto r = run_strata({"synth", data.string(), "--size", "small", "--stages", "1", "--photos", "12",
                       "--width", "800", "--seed", "5"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  ASSERT_EQ(run_strata({"init", site.string(), "--crs", "EPSG:32636"}).exit_code, 0);
  ASSERT_EQ(run_strata({"unit", "add", site.string(), "101"}).exit_code, 0);
  ASSERT_EQ(run_strata({"layer", "add", site.string(), "L1", "--unit", "101"}).exit_code, 0);
  std::vector<std::string> import = {"import", "photos", site.string(), "--layer", "L1"};
  for (const auto& e : fs::directory_iterator(data / "photos" / "L1")) import.push_back(e.path().string());
  ASSERT_EQ(run_strata(import).exit_code, 0);
  // No markers: the layer is aligned in a local frame, which is all this test needs.
  const std::string media_before = test::tree_fingerprint(site / "media");
  const std::string info_before = run_strata({"info", site.string(), "--json"}).out;
  const std::vector<std::string> process = {"process", site.string(), "--layer", "L1", "--until", "sparse"};

  // Killed after the features were cached, and again with all results written but
  // not committed: the transaction must vanish as if never begun.
  for (const char* fault : {"process.features.done", "process.align.before_commit"}) {
    ASSERT_EQ(run_until_fault(fault, process), SIGKILL) << fault << ": the run was not interrupted";
    EXPECT_EQ(integrity(site / "project.gpkg"), "ok") << fault;
    EXPECT_EQ(test::tree_fingerprint(site / "media"), media_before) << fault;
    EXPECT_EQ(run_strata({"info", site.string(), "--json"}).out, info_before) << fault;
    const auto x = run_strata({"export", "cameras", site.string(), "--layer", "L1", "--out", (dir / "c.csv").string()});
    EXPECT_NE(x.exit_code, 0) << fault << ": a reconstruction was recorded by a killed run";
  }

  // The next run completes the stage; what the killed run cached is reused.
  r = run_strata({"process", site.string(), "--layer", "L1", "--until", "sparse", "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("from cache"), std::string::npos) << r.err;
  const auto q = nlohmann::json::parse(r.out);
  EXPECT_GT(q["images_registered"].get<int>(), 0);
  EXPECT_EQ(integrity(site / "project.gpkg"), "ok");
  EXPECT_EQ(test::tree_fingerprint(site / "media"), media_before);
  // A third run finds everything up to date and recomputes nothing.
  r = run_strata({"process", site.string(), "--layer", "L1", "--until", "sparse"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("up to date"), std::string::npos) << r.out;
}

}  // namespace
}  // namespace strata
