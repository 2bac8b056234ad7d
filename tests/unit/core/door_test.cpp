// The checks at the door on their own (the command-line behaviour is in
// tests/integration/door_test.cpp).
#include "core/door.hpp"
#include "core/error.hpp"
#include "core/field_error.hpp"

#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <fstream>
#include <functional>

namespace strata {
namespace {

namespace fs = std::filesystem;

std::string refusal(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(DoorChecks, NamesAreTrimmedNormalisedAndPrintable) {
  EXPECT_EQ(door::name("code", " \t101\u00a0 "), "101");  // no-break space is white space too
  EXPECT_EQ(door::name("code", "e\xcc\x81"), "\xc3\xa9");  // NFC: one code point
  EXPECT_EQ(door::name("code", "Trench \xce\x91 / 3"), "Trench \xce\x91 / 3");  // inner spaces and Greek kept
  EXPECT_NE(refusal([] { door::name("code", ""); }).find("code is empty"), std::string::npos);
  EXPECT_NE(refusal([] { door::name("code", "a\tb"); }).find("U+0009"), std::string::npos);
  EXPECT_NE(refusal([] { door::name("code", "a\xe2\x80\xae" "b"); }).find("U+202E"), std::string::npos);
  EXPECT_NE(refusal([] { door::name("code", "a\xe2\x80\xa8" "b"); }).find("line break"), std::string::npos);
  EXPECT_NE(refusal([] { door::name("code", "\xc3"); }).find("not UTF-8"), std::string::npos);
  EXPECT_NE(refusal([] { door::name("code", "\xed\xa0\x80"); }).find("not UTF-8"), std::string::npos);  // a surrogate
  // Too long is said as too long, not as "not UTF-8".
  EXPECT_NE(refusal([] { door::text("description", std::string((1u << 20) + 1, 'a')); }).find("bytes long"),
            std::string::npos);
  EXPECT_EQ(door::name("code", std::string(64, 'x')).size(), 64u);
  EXPECT_NE(refusal([] { door::name("code", std::string(65, 'x')); }).find("more than 64"), std::string::npos);
  // 64 characters, not bytes: Greek letters take two bytes each.
  std::string greek;
  for (int i = 0; i < 64; ++i) greek += "\xce\xb1";
  EXPECT_EQ(door::name("code", greek), greek);
  try {
    door::name("unit", "");
    ADD_FAILURE();
  } catch (const FieldError& e) {
    EXPECT_EQ(e.field(), "unit");
  }
  EXPECT_EQ(door::text("description", "two\nlines\tand tabs"), "two\nlines\tand tabs");
  EXPECT_NE(refusal([] { door::text("description", "bell\a"); }).find("U+0007"), std::string::npos);
  EXPECT_NE(refusal([] { door::name_at("importer.finds.csv: f.csv:3", "find id", " "); }).find("f.csv:3: find id is empty"),
            std::string::npos);
}

TEST(DoorChecks, DatesMustExist) {
  EXPECT_EQ(door::date_time("d", " 2024-02-29 "), "2024-02-29");
  EXPECT_EQ(door::date_time("d", "2026-05-14T09:31:02.5+03:00"), "2026-05-14T09:31:02.5+03:00");
  EXPECT_EQ(door::date_time("d", "2026-05-14 09:31Z"), "2026-05-14 09:31Z");
  EXPECT_EQ(door::date_time("d", "2016-12-31T23:59:60Z"), "2016-12-31T23:59:60Z");  // a leap second
  for (const char* bad : {"2023-02-29", "2026-04-31", "2026-00-10", "2026-13-45", "2026-05-14T24:00", "2026-05-14T09:60",
                          "2026-05-14T09:31:61", "2026-05-14T09:31+15:00", "1838-12-31", "3026-01-01", "14.05.2026",
                          "2026-5-14", ""})
    EXPECT_FALSE(refusal([&] { door::date_time("d", bad); }).empty()) << bad;
}

TEST(DoorChecks, NumbersAndMemory) {
  EXPECT_EQ(door::number_in(0.5, 0, 1, "x", "m"), 0.5);
  EXPECT_NE(refusal([] { door::number_in(std::nan(""), 0, 1, "x", "m"); }).find("x = nan is not within 0..1 m"),
            std::string::npos);
  EXPECT_FALSE(refusal([] { door::number_in(1e308, 0, 1, "x", ""); }).empty());
  EXPECT_GT(door::memory_budget_bytes(), 1u << 20);
  EXPECT_TRUE(refusal([] { door::fits_in_memory(1e6, "small", ""); }).empty());
  EXPECT_NE(refusal([] { door::fits_in_memory(1e30, "huge", "smaller"); }).find("huge would need"), std::string::npos);
  EXPECT_FALSE(refusal([] { door::fits_in_memory(std::nan(""), "nan", ""); }).empty());
  EXPECT_FALSE(refusal([] { door::fits_in_memory(-1, "negative", ""); }).empty());
}

TEST(DoorChecks, PathsAreRegularFilesOrFolders) {
  const fs::path dir = fs::temp_directory_path() / ("door_unit_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::ofstream(dir / "ok.csv") << "1,2,3\n";
  ASSERT_EQ(mkfifo((dir / "fifo").c_str(), 0600), 0);
  fs::create_symlink("b", dir / "a");
  fs::create_symlink("a", dir / "b");
  fs::create_symlink("ok.csv", dir / "link.csv");
  fs::create_symlink("gone", dir / "dangling");
  EXPECT_EQ(door::input_file(dir / "link.csv", "survey"), dir / "link.csv");
  EXPECT_NE(refusal([&] { door::input_file(dir / "fifo", "survey"); }).find("named pipe"), std::string::npos);
  EXPECT_NE(refusal([&] { door::input_file(dir / "a", "survey"); }).find("loop of symbolic links"), std::string::npos);
  EXPECT_NE(refusal([&] { door::input_file(dir / "a" / "x.csv", "survey"); }).find("loop"), std::string::npos);
  EXPECT_NE(refusal([&] { door::input_file(dir / "dangling", "survey"); }).find("symbolic link to 'gone'"),
            std::string::npos);
  EXPECT_NE(refusal([&] { door::input_file(dir, "survey"); }).find("is a folder"), std::string::npos);
  EXPECT_NE(refusal([&] { door::input_file("/dev/null", "survey"); }).find("device"), std::string::npos);
  EXPECT_NE(refusal([&] { door::input_file(dir / "ok.csv", "survey", 3); }).find("more than"), std::string::npos);
  EXPECT_EQ(door::input_folder(dir, "project"), dir);
  EXPECT_NE(refusal([&] { door::input_folder(dir / "ok.csv", "project"); }).find("not a folder"), std::string::npos);
  EXPECT_TRUE(refusal([&] { door::output_file(dir / "new" / "deeper" / "out.svg", "--out"); }).empty());
  EXPECT_TRUE(refusal([&] { door::output_file(dir / "ok.csv", "--out"); }).empty());  // replaced
  EXPECT_NE(refusal([&] { door::output_file(dir / "fifo", "--out"); }).find("named pipe"), std::string::npos);
  EXPECT_NE(refusal([&] { door::output_file(dir / "ok.csv" / "x.svg", "--out"); }).find("not a folder"), std::string::npos);
  EXPECT_NE(refusal([&] { door::output_file(dir / "x" / "y.svg", "--out", false); }).find("does not exist"),
            std::string::npos);
  EXPECT_NE(refusal([&] { door::output_folder(dir / "ok.csv", "--out"); }).find("not a folder"), std::string::npos);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace strata
