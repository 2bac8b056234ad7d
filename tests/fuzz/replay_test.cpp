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
namespace {

std::vector<std::uint8_t> read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

class CorpusReplay : public ::testing::TestWithParam<Target> {};

TEST_P(CorpusReplay, EveryInputIsAcceptedOrRefusedCleanly) {
  const Target& target = GetParam();
  const fs::path corpus = fs::path(STRATA_FUZZ_CORPUS_DIR) / target.name;
  ASSERT_TRUE(fs::is_directory(corpus)) << corpus;
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(corpus)) {
    if (entry.is_regular_file()) files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  ASSERT_FALSE(files.empty()) << "no seeds in " << corpus;
  for (const auto& file : files) {
    SCOPED_TRACE(file.string());
    const std::vector<std::uint8_t> bytes = read_bytes(file);
    EXPECT_NO_THROW(EXPECT_EQ(target.run(bytes.data(), bytes.size()), 0));
  }
}

INSTANTIATE_TEST_SUITE_P(Fuzz, CorpusReplay, ::testing::ValuesIn(kTargets),
                         [](const ::testing::TestParamInfo<Target>& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace strata::fuzz
