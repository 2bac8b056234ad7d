// Every fuzz target over every file of its corpus (tests/fuzz/corpus/<target>/): the
// seeds and each input that once crashed a parser or broke its promise. Part of the
// ordinary test suite, so a fixed bug stays fixed in builds without sanitizers too.
#include "fuzz/fuzz_support.hpp"
#include "fuzz/targets.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <iterator>
#include <vector>

namespace fs = std::filesystem;

namespace strata::fuzz {

// The target's name in test names and messages (found by argument-dependent lookup).
void PrintTo(const Target& target, std::ostream* os) { *os << target.name; }

namespace {

const fs::path kFuzzDir = STRATA_FUZZ_DIR;

std::vector<std::uint8_t> read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Runs the target on every file of the folder, in name order.
void replay(const fs::path& folder, TargetFunction run) {
  ASSERT_TRUE(fs::is_directory(folder)) << folder;
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(folder)) {
    if (entry.is_regular_file()) files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  ASSERT_FALSE(files.empty()) << "no inputs in " << folder;
  for (const auto& file : files) {
    SCOPED_TRACE(file.string());
    const std::vector<std::uint8_t> bytes = read_bytes(file);
    try {
      EXPECT_EQ(run(bytes.data(), bytes.size()), 0);
    } catch (const std::exception& e) {
      ADD_FAILURE() << e.what();  // FuzzFailure, or an exception the parser let escape
    }
  }
}

class CorpusReplay : public ::testing::TestWithParam<Target> {};

TEST_P(CorpusReplay, EveryInputIsAcceptedOrRefusedCleanly) {
  replay(kFuzzDir / "corpus" / GetParam().name, GetParam().run);
}

INSTANTIATE_TEST_SUITE_P(FuzzReplay, CorpusReplay, ::testing::ValuesIn(kTargets),
                         [](const ::testing::TestParamInfo<Target>& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace strata::fuzz
