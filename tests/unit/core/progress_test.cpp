// Progress output without a terminal (plain lines, paced, with the time left) and
// the terminal bar's layout, on a fake clock: nothing here waits for real time.
#include "core/log.hpp"
#include "core/progress.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace strata {
namespace {

constexpr double kEstimateTolerance_s = 1e-9;  // the estimate is plain arithmetic

struct FakeOutput {
  double now = 100.0;  // seconds, arbitrary start
  std::vector<std::string> writes;
  ProgressOutput make(bool terminal, int width = 80) {
    ProgressOutput o;
    o.terminal = terminal;
    o.width = width;
    o.write = [this](std::string_view t) { writes.emplace_back(t); };
    o.seconds = [this] { return now; };
    return o;
  }
};

TEST(Progress, EstimateIsTheMeanRateSoFar) {
  // 5 of 20 items in 10 s: 2 s per item, 15 left.
  EXPECT_NEAR(*estimate_remaining_s(5, 20, 10.0), 30.0, kEstimateTolerance_s);
  EXPECT_NEAR(*estimate_remaining_s(20, 20, 10.0), 0.0, kEstimateTolerance_s);
  EXPECT_FALSE(estimate_remaining_s(0, 20, 10.0));  // nothing done: no rate
  EXPECT_FALSE(estimate_remaining_s(1, 20, 0.1));   // too early: noise
}

TEST(Progress, DurationsInWords) {
  EXPECT_EQ(format_duration(7.2), "7 s");
  EXPECT_EQ(format_duration(59.6), "1 min 00 s");  // rounded before splitting: never "60 s"
  EXPECT_EQ(format_duration(185), "3 min 05 s");
  EXPECT_EQ(format_duration(3720), "1 h 02 min");
  EXPECT_EQ(format_duration(-1), "0 s");
}

TEST(Progress, PlainLineCarriesCountPercentAndTimeLeft) {
  EXPECT_EQ(format_progress_line("matching", 7, 14, 3.0), "matching: 7/14 (50 %), 3 s so far, about 3 s left");
  EXPECT_EQ(format_progress_line("matching", 0, 14, 3.0), "matching: 0/14 (0 %), 3 s so far");
  EXPECT_EQ(format_progress_done("matching", 14, 14, 65), "matching: 14/14 done in 1 min 05 s");
}

TEST(Progress, QuickStageWithoutTerminalPrintsOnlyItsFinalLine) {
  FakeOutput fake;
  Progress p("features", 20, fake.make(false));
  for (int i = 0; i < 20; ++i) {
    fake.now += 0.05;
    p.step();
  }
  p.finish();
  ASSERT_EQ(fake.writes.size(), 1u);
  EXPECT_EQ(fake.writes[0], "features: 20/20 done in 1 s\n");
}

TEST(Progress, SlowStageWithoutTerminalPrintsOneLinePerTenthWithTimeLeft) {
  FakeOutput fake;
  {
    Progress p("dense: depth maps", 100, fake.make(false));
    for (int i = 0; i < 100; ++i) {
      fake.now += 1.0;  // one item a second
      p.step();
    }
    // No finish(): the destructor reports a completed stage itself.
  }
  ASSERT_EQ(fake.writes.size(), 10u);  // 10 %, 20 %, ... 90 %, then done
  EXPECT_EQ(fake.writes[0], "dense: depth maps: 10/100 (10 %), 10 s so far, about 1 min 30 s left\n");
  EXPECT_EQ(fake.writes[4], "dense: depth maps: 50/100 (50 %), 50 s so far, about 50 s left\n");
  EXPECT_EQ(fake.writes.back(), "dense: depth maps: 100/100 done in 1 min 40 s\n");
  for (const auto& w : fake.writes) {
    EXPECT_EQ(w.find('\r'), std::string::npos) << "no terminal control characters in plain lines";
    EXPECT_EQ(w.find('\x1b'), std::string::npos);
  }
}

TEST(Progress, VerySlowStageWithoutTerminalStillReportsEveryMinute) {
  FakeOutput fake;
  Progress p("fusion", 1000, fake.make(false));
  for (int i = 0; i < 13; ++i) {  // one item every 10 s: the first 10 % would take 1000 s
    fake.now += 10.0;
    p.step();
  }
  ASSERT_EQ(fake.writes.size(), 2u);  // at 60 s and at 120 s
  EXPECT_EQ(fake.writes[0], "fusion: 6/1000 (0 %), 1 min 00 s so far, about 2 h 45 min left\n");
  EXPECT_EQ(fake.writes[1].rfind("fusion: 12/1000 (1 %), 2 min 00 s so far", 0), 0u) << fake.writes[1];
}

TEST(Progress, QuietPrintsNothing) {
  FakeOutput fake;
  log::set_level(log::Level::warning);  // -q
  {
    Progress p("matching", 10, fake.make(false));
    for (int i = 0; i < 10; ++i) {
      fake.now += 10;
      p.step();
    }
    p.finish();
  }
  log::set_level(log::Level::info);
  EXPECT_TRUE(fake.writes.empty());
}

TEST(Progress, TerminalBarRedrawsInPlaceAtMostTenTimesASecond) {
  FakeOutput fake;
  constexpr int kWidth = 100;
  Progress p("aligning photos", 200, fake.make(true, kWidth));
  for (int i = 0; i < 200; ++i) {
    fake.now += 0.01;  // 2 s in all
    p.step();
  }
  p.finish();
  ASSERT_GE(fake.writes.size(), 15u);
  ASSERT_LE(fake.writes.size(), 22u);  // 20 redraws in 2 s, plus the final one
  std::size_t length = 0;
  for (std::size_t i = 0; i < fake.writes.size(); ++i) {
    const std::string& w = fake.writes[i];
    ASSERT_EQ(w.front(), '\r') << "redrawn over itself";
    const std::size_t end = w.find("\x1b[K");
    ASSERT_NE(end, std::string::npos) << "clears what a longer line left";
    EXPECT_LT(end - 1, std::size_t(kWidth)) << "never wraps: " << w;
    if (i > 0 && i + 1 < fake.writes.size()) {
      EXPECT_EQ(end - 1, length) << "same length: no jitter";
    }
    length = end - 1;
    EXPECT_EQ(w.back() == '\n', i + 1 == fake.writes.size());
  }
  EXPECT_NE(fake.writes[fake.writes.size() / 2].find("left"), std::string::npos) << "an estimate of the time left";
  EXPECT_NE(fake.writes.back().find("200/200"), std::string::npos);
  EXPECT_NE(fake.writes.back().find("done"), std::string::npos);
}

TEST(Progress, NarrowTerminalDropsTheBarNotTheFigures) {
  const std::string bar = format_progress_bar("dense: depth maps", 7, 20, 30, 50);
  EXPECT_LT(bar.size(), 50u);
  EXPECT_NE(bar.find("7/20"), std::string::npos);
  EXPECT_EQ(bar.find('['), std::string::npos);
  const std::string wide = format_progress_bar("dense: depth maps", 7, 20, 30, 120);
  EXPECT_NE(wide.find("[##########...................."), std::string::npos) << wide;  // 7/20 of 30 cells
  EXPECT_NE(wide.find("~ 0:56 left"), std::string::npos) << wide;  // 13 items at 30/7 s each
}

}  // namespace
}  // namespace strata
