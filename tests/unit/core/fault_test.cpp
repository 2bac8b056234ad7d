// The crash-injection facility (core/fault.hpp): a point fires only when armed, at
// the armed hit, and the registry the bench script reads is sound. Each case arms
// STRATA_CRASH_AT in a forked child (gtest's death tests), since the variable is
// read once per process.
#include "core/error.hpp"
#include "core/fault.hpp"

#include <gtest/gtest.h>

#include <csignal>
#include <cstdlib>
#include <set>
#include <string>
#include <unistd.h>

namespace strata {
namespace {

constexpr int kSurvived = 3;   // exit status of a child that passed its points alive
constexpr int kRefused = 4;    // exit status of a child whose point threw InternalError
constexpr std::size_t kMatrixMinimum = 50;  // the crash matrix covers at least 50 kill points

// Death tests re-run this binary for the child ("threadsafe"), so that each child
// reads STRATA_CRASH_AT afresh rather than inheriting the parent's reading.
void fresh_children() { GTEST_FLAG_SET(death_test_style, "threadsafe"); }

// Arms `spec`, passes `name` `hits` times, exits kSurvived if still alive.
void pass_point(const char* spec, const char* name, int hits) {
  setenv("STRATA_CRASH_AT", spec, 1);
  for (int i = 0; i < hits; ++i) fault::point(name);
  _exit(kSurvived);
}

TEST(FaultDeathTest, ArmedPointKillsWithSigkill) {
  fresh_children();
  EXPECT_EXIT(pass_point("process.dense.depth_map_written", "process.dense.depth_map_written", 1),
              testing::KilledBySignal(SIGKILL), "");
}

TEST(FaultDeathTest, NthHitIsTheOneThatKills) {
  fresh_children();
  EXPECT_EXIT(pass_point("process.dense.depth_map_written:3", "process.dense.depth_map_written", 2),
              testing::ExitedWithCode(kSurvived), "");
  EXPECT_EXIT(pass_point("process.dense.depth_map_written:3", "process.dense.depth_map_written", 3),
              testing::KilledBySignal(SIGKILL), "");
}

TEST(FaultDeathTest, OtherPointsAndMalformedCountsDoNotFire) {
  fresh_children();
  EXPECT_EXIT(pass_point("process.dense.depth_map_written", "process.dense.fusion_done", 5),
              testing::ExitedWithCode(kSurvived), "");
  EXPECT_EXIT(pass_point("process.dense.depth_map_written:0", "process.dense.depth_map_written", 5),
              testing::ExitedWithCode(kSurvived), "");
  EXPECT_EXIT(pass_point("process.dense.depth_map_written:x", "process.dense.depth_map_written", 5),
              testing::ExitedWithCode(kSurvived), "");
}

TEST(FaultDeathTest, UnlistedPointIsRefusedWhileArmed) {
  fresh_children();
  auto child = [] {
    setenv("STRATA_CRASH_AT", "process.dense.fusion_done", 1);
    try {
      fault::point("process.dense.no_such_point");
    } catch (const InternalError&) {
      _exit(kRefused);
    }
    _exit(kSurvived);
  };
  EXPECT_EXIT(child(), testing::ExitedWithCode(kRefused), "");
}

TEST(Fault, RegistryNamesAreUniqueAndDescribed) {
  std::set<std::string> names;
  for (const auto& p : fault::kCrashPoints) {
    EXPECT_TRUE(names.insert(std::string(p.name)).second) << "listed twice: " << p.name;
    EXPECT_FALSE(p.where.empty()) << p.name;
    EXPECT_NE(p.name.find('.'), std::string_view::npos) << p.name << ": <family>.<stage>.<event>";
  }
  EXPECT_GE(names.size(), kMatrixMinimum);
}

TEST(Fault, UnarmedPointIsANoOp) {
  unsetenv("STRATA_CRASH_AT");
  EXPECT_TRUE(fault::armed().empty());
  EXPECT_NO_THROW(fault::point("process.dense.no_such_point"));  // not checked while unarmed
}

}  // namespace
}  // namespace strata
