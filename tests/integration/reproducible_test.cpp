// The same photos, markers and options give the same products, bit for bit, whatever
// the thread count and whether or not the run was killed and resumed
// (docs/reliability.md, "Reproducible results"). Compared: the SHA-256 the
// products table records for every product file. The layer report is left out: it
// states when it was generated and how long the alignment took, facts of the run and
// not of the data.
#include "integration/field_project.hpp"

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <csignal>
#include <cstdlib>

namespace strata {
namespace {

namespace fs = std::filesystem;
using test::run_strata;

// "kind path sha256" of every product but the report, in path order.
std::string product_checksums(const fs::path& site) {
  sqlite3* db = nullptr;
  std::string out;
  if (sqlite3_open_v2((site / "project.gpkg").c_str(), &db, SQLITE_OPEN_READONLY, nullptr) == SQLITE_OK) {
    sqlite3_stmt* st = nullptr;
    sqlite3_prepare_v2(db, "SELECT kind, path, sha256 FROM products WHERE kind <> 'report' ORDER BY path", -1, &st,
                       nullptr);
    while (st && sqlite3_step(st) == SQLITE_ROW) {
      for (int c = 0; c < 3; ++c) {
        out += reinterpret_cast<const char*>(sqlite3_column_text(st, c));
        out += c < 2 ? ' ' : '\n';
      }
    }
    sqlite3_finalize(st);
  }
  sqlite3_close(db);
  return out;
}

// `strata process SITE --layer L1` killed (SIGKILL) at `point`; true when it was.
bool killed_at(const fs::path& site, const std::string& point, const std::string& threads) {
  setenv("STRATA_CRASH_AT", point.c_str(), 1);
  const auto r = run_strata({"-q", "--threads", threads, "process", site.string(), "--layer", "L1"});
  unsetenv("STRATA_CRASH_AT");
  return r.exit_code == 128 + SIGKILL;
}

class Reproducible : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    scratch_ = new test::ScratchDir("reproducible");
    try {
      // Made once (support/shared_scene.hpp); each run works on a copy.
      shared_ = test::shared_project("reproducible", 1, 12, 5, std::nullopt);
    } catch (const std::exception& e) {
      setup_error_ = e.what();
    }
  }
  static void TearDownTestSuite() {
    delete scratch_;
    scratch_ = nullptr;
  }
  void SetUp() override {
    if (!setup_error_.empty()) FAIL() << "the shared project could not be made: " << setup_error_;
  }
  // A copy of the imported project (no caches: every stage runs).
  static fs::path fresh(const std::string& name) {
    const fs::path site = *scratch_ / name;
    fs::remove_all(site);
    test::copy_scene(shared_ / "template", site);
    return site;
  }
  static test::ScratchDir* scratch_;
  static fs::path shared_;
  static std::string setup_error_;
};
test::ScratchDir* Reproducible::scratch_ = nullptr;
fs::path Reproducible::shared_;
std::string Reproducible::setup_error_;

TEST_F(Reproducible, ProductsAreTheSameWithOneOrTwoThreadsAndAfterKills) {
  const fs::path two = fresh("two"), one = fresh("one"), resumed = fresh("resumed");
  auto r = run_strata({"-q", "--threads", "2", "process", two.string(), "--layer", "L1"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string reference = product_checksums(two);
  // DTM, its sigma, orthophoto, surface volume, mesh, points, GeoPackage rasters...
  ASSERT_GE(test::line_count(reference), 5) << reference;

  r = run_strata({"-q", "--threads", "1", "process", one.string(), "--layer", "L1"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(product_checksums(one), reference) << "one thread against two";

  // Killed in every stage, part-way through the per-photo and per-pair work and
  // between writing and committing; each kill resumes from what the last one cached.
  for (const char* point : {"process.features.image_done:4", "process.matching.pair_done:9",
                            "process.align.before_commit", "process.dense.depth_map_written:5",
                            "process.dense.swapped", "process.products.ortho_written"}) {
    EXPECT_TRUE(killed_at(resumed, point, "2")) << point << ": the run was not killed there";
    EXPECT_EQ(test::integrity(resumed / "project.gpkg"), "ok") << point;
  }
  r = run_strata({"-q", "--threads", "2", "process", resumed.string(), "--layer", "L1"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(product_checksums(resumed), reference) << "killed six times and resumed, against undisturbed";
}

}  // namespace
}  // namespace strata
