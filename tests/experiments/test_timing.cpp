// experiments/timing: the distribution-free interval of the median.
#include <gtest/gtest.h>

#include <cmath>

#include "experiments/timing.hpp"

namespace pbdbench::experiments {
namespace {

TEST(Timing, MedianIntervalFromOrderStatistics) {
  // n = 9: [x_(2), x_(8)], coverage 1 - 2 (1 + 9) / 512.
  const MedianInterval nine = median_interval({9, 1, 8, 2, 7, 3, 6, 4, 5});
  EXPECT_EQ(nine.median, 5);
  EXPECT_EQ(nine.lo, 2);
  EXPECT_EQ(nine.hi, 8);
  EXPECT_NEAR(nine.coverage, 1.0 - 20.0 / 512.0, 1e-12);
  // n = 7: P(B = 0) = 1/128 <= 0.025 but P(B <= 1) = 8/128 is not: [x_(1), x_(7)].
  const MedianInterval seven = median_interval({3, 1, 2, 7, 5, 4, 6});
  EXPECT_EQ(seven.median, 4);
  EXPECT_EQ(seven.lo, 1);
  EXPECT_EQ(seven.hi, 7);
  EXPECT_NEAR(seven.coverage, 1.0 - 2.0 / 128.0, 1e-12);
  EXPECT_GE(seven.coverage, 0.95);
  // n = 20: k = 6 (P(B <= 5) = 0.0207), [x_(6), x_(15)].
  std::vector<double> twenty;
  for (int i = 20; i >= 1; --i) twenty.push_back(i);
  const MedianInterval t = median_interval(twenty);
  EXPECT_EQ(t.median, 10.5);
  EXPECT_EQ(t.lo, 6);
  EXPECT_EQ(t.hi, 15);
  EXPECT_GE(t.coverage, 0.95);
  EXPECT_LT(t.coverage, 0.97);
  // Too few samples for 95 %: the whole range, with its lower coverage said.
  const MedianInterval five = median_interval({1, 2, 3, 4, 5});
  EXPECT_EQ(five.lo, 1);
  EXPECT_EQ(five.hi, 5);
  EXPECT_NEAR(five.coverage, 1.0 - 2.0 / 32.0, 1e-12);
  EXPECT_TRUE(std::isnan(median_interval({}).median));
}

}  // namespace
}  // namespace pbdbench::experiments
