#pragma once
// A fresh project in a scratch folder, photos made on the fly, and a dump of the
// whole database for before/after comparisons.
#include "core/error.hpp"
#include "project/project.hpp"
#include "project/records.hpp"
#include "support/test_support.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <gtest/gtest.h>

#include <filesystem>
#include <memory>
#include <string>

namespace strata::test {

class ImporterTest : public ::testing::Test {
 protected:
  void SetUp() override {
    scratch_ = std::make_unique<ScratchDir>("imp");
    project_ = std::make_unique<Project>(
        Project::create(scratch_->path() / "site", {"EPSG:32636", "", std::nullopt}));
    Transaction tx(db());
    insert_unit(db(), {0, "101", "deposit", ""});
    insert_layer(db(), {0, "L1", "101", std::nullopt});
    insert_layer(db(), {0, "L2", "101", std::nullopt});
    tx.commit();
  }

  Database& db() { return project_->db(); }
  Project& project() { return *project_; }
  std::filesystem::path scratch() const { return scratch_->path(); }

  // A small random-texture JPEG, different for each seed.
  std::filesystem::path make_photo(const std::string& name, int seed) {
    cv::Mat img(120, 160, CV_8UC3);
    cv::RNG rng(seed);
    rng.fill(img, cv::RNG::UNIFORM, 0, 255);
    const auto path = scratch() / "in" / name;
    std::filesystem::create_directories(path.parent_path());
    cv::imwrite(path.string(), img);
    return path;
  }

  // A text input file under scratch()/in.
  std::filesystem::path write(const std::string& name, const std::string& text) {
    const auto p = scratch() / "in" / name;
    write_text(p, text);
    return p;
  }

  // Writes `text` as bad.csv, runs `import(path)` and expects an Error whose message
  // contains `expected`; the database must be unchanged.
  template <typename Import>
  void expect_import_refused(const std::string& text, const std::string& expected, Import import) {
    const std::string before = dump();
    try {
      import(write("bad.csv", text));
      ADD_FAILURE() << "accepted:\n" << text;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos)
          << "message: " << e.what() << "\nexpected to contain: " << expected;
    }
    EXPECT_EQ(dump(), before);
  }

  // Every row of every table, as text: equal dumps mean an unchanged database.
  std::string dump() {
    std::string out;
    auto tables = db().prepare("SELECT name FROM sqlite_master WHERE type='table' ORDER BY name");
    std::vector<std::string> names;
    while (tables.step()) names.push_back(tables.get_text(0));
    for (const auto& t : names) {
      auto st = db().prepare("SELECT * FROM \"" + t + "\"");
      out += "# " + t + "\n";
      while (st.step()) {
        for (int c = 0; c < 16; ++c) out += st.get_text(c) + "|";
        out += "\n";
      }
    }
    return out;
  }

  std::unique_ptr<ScratchDir> scratch_;
  std::unique_ptr<Project> project_;
};

}  // namespace strata::test
