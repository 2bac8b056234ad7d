#include "core/statistics.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace strata {
namespace {

TEST(Statistics, PercentileIsAnObservedSampleOfRoundedRank) {
  const std::vector<double> v = {5, 1, 4, 2, 3};
  EXPECT_EQ(percentile(v, 0.0), 1);
  EXPECT_EQ(percentile(v, 1.0), 5);
  EXPECT_EQ(percentile(v, 0.5), 3);
  EXPECT_EQ(percentile(v, 0.6), 3);   // rank round(2.4) = 2
  EXPECT_EQ(percentile(v, 0.65), 4);  // rank round(2.6) = 3
  EXPECT_EQ(percentile(v, 7.0), 5);   // clamped
  EXPECT_TRUE(std::isnan(percentile({}, 0.5)));
}

TEST(Statistics, MedianOfAnEvenCountIsTheUpperMiddleValue) {
  EXPECT_EQ(median({4, 1, 3, 2}), 3);
  EXPECT_EQ(median({2, 1}), 2);
  EXPECT_EQ(median({7}), 7);
}

TEST(Statistics, MedianInPlaceAgreesWithMedianForEveryCount) {
  for (int n = 1; n <= 9; ++n) {
    std::vector<double> v;
    for (int i = 0; i < n; ++i) v.push_back(double((i * 11 + 3) % n));  // a permutation of 0..n-1 (11 is prime to n)
    std::vector<double> w = v;
    EXPECT_EQ(median_in_place(w), median(v)) << n << " samples";
    EXPECT_EQ(median_in_place(w), double(n / 2)) << n << " samples";
  }
}

TEST(Statistics, KthSmallestTakesAnyValueTypeAndRank) {
  std::vector<float> v = {0.5f, -2.0f, 9.0f, 3.0f};
  EXPECT_EQ(kth_smallest(v, 0), -2.0f);
  EXPECT_EQ(kth_smallest(v, 1), 0.5f);
  EXPECT_EQ(kth_smallest(v, 3), 9.0f);
  EXPECT_EQ(v.size(), 4u);  // reordered, nothing lost
}

TEST(Statistics, NearestRankQuantileIsTheSmallestSampleCoveringTheFraction) {
  std::vector<double> v = {40, 10, 30, 20};
  EXPECT_EQ(nearest_rank_quantile(v, 0.5), 20);   // 2 of 4 at or below: the lower middle
  EXPECT_EQ(nearest_rank_quantile(v, 0.51), 30);
  EXPECT_EQ(nearest_rank_quantile(v, 0.25), 10);
  EXPECT_EQ(nearest_rank_quantile(v, 0.0), 10);   // rank at least 1
  EXPECT_EQ(nearest_rank_quantile(v, 1.0), 40);
  std::vector<double> none;
  EXPECT_TRUE(std::isnan(nearest_rank_quantile(none, 0.5)));
}

}  // namespace
}  // namespace strata
