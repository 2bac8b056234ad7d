// What a survey's coordinates alone say: rounding steps and unknown heights.
#include "georef/survey.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace strata {
namespace {

TEST(Survey, CoordinatesRoundedToADecimetreAreFound) {
  const auto a = assess_survey({{734012.3, 4174005.1, 1450.2}, {734015.0, 4174007.7, 1450.9},
                                {734011.8, 4174009.4, 1451.3}, {734014.6, 4174003.2, 1450.5}});
  EXPECT_DOUBLE_EQ(a.plan_step_m, 0.1);
  EXPECT_DOUBLE_EQ(a.height_step_m, 0.1);
  EXPECT_FALSE(a.heights_equal);
  EXPECT_NEAR(a.plan_rounding_sigma_m(), 0.1 / std::sqrt(12.0), 1e-12);
}

TEST(Survey, MillimetreCoordinatesAreNotRounded) {
  const auto a = assess_survey({{734012.312, 4174005.127, 1450.203}, {734015.041, 4174007.716, 1450.911},
                                {734011.806, 4174009.433, 1451.372}});
  EXPECT_EQ(a.plan_step_m, 0.0);
  EXPECT_EQ(a.height_step_m, 0.0);
}

TEST(Survey, EqualHeightsAreUnknownHeights) {
  const auto a = assess_survey({{235269.88, 3811198.11, 0.0}, {235262.54, 3811203.5, 0.0},
                                {235248.03, 3811227.25, 0.0}});
  EXPECT_TRUE(a.heights_equal);
  EXPECT_DOUBLE_EQ(a.plan_step_m, 0.01);
  const auto b = assess_survey({{1, 2, 101.5}, {3, 4, 101.5}, {5, 7, 101.5}});
  EXPECT_TRUE(b.heights_equal) << "one nominal level, not only 0.0";
  EXPECT_FALSE(assess_survey({{1, 2, 0}, {3, 4, 0}}).heights_equal) << "two markers say nothing";
}

}  // namespace
}  // namespace strata
