#include "mvtwin/forward/step_size_control.h"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

namespace mvtwin::forward {
namespace {

TEST(StepSizeControl, FixedStepsWithoutATolerance) {
  const StepSizeControl c(0.01, 0.08, 0.0);
  EXPECT_FALSE(c.adaptive());
  EXPECT_TRUE(c.accept(0.01, 1e6));
  EXPECT_DOUBLE_EQ(c.next(0.01, 0.0), 0.01);
  EXPECT_DOUBLE_EQ(c.next(0.01, 1e6), 0.01);
}

TEST(StepSizeControl, AcceptsWithinTheToleranceOrAtTheSmallestStep) {
  const StepSizeControl c(0.01, 0.08, 0.1);
  EXPECT_TRUE(c.accept(0.04, 0.1));
  EXPECT_FALSE(c.accept(0.04, 0.11));
  EXPECT_TRUE(c.accept(0.01, 5.0));  // never below dt for error
  EXPECT_FALSE(c.accept(0.02, std::numeric_limits<double>::quiet_NaN()));
}

// The error grows as h^2, so the step scales by 0.9 sqrt(tol / error), at most doubled, at
// least quartered, rounded down to dt times a power of two within [dt, max].
TEST(StepSizeControl, NextStepFollowsTheErrorOnPowerOfTwoLevels) {
  const StepSizeControl c(0.01, 0.08, 0.1);
  EXPECT_DOUBLE_EQ(c.next(0.01, 0.0), 0.02);         // smooth: doubled
  EXPECT_DOUBLE_EQ(c.next(0.02, 0.001), 0.04);       // at most doubled
  EXPECT_DOUBLE_EQ(c.next(0.08, 0.0), 0.08);         // capped
  EXPECT_DOUBLE_EQ(c.next(0.04, 0.1), 0.02);         // 0.9 x 0.04 = 0.036: level 0.02
  EXPECT_DOUBLE_EQ(c.next(0.04, 0.1 / 0.81), 0.02);  // 0.8 x 0.04 = 0.032
  EXPECT_DOUBLE_EQ(c.next(0.08, 100.0), 0.02);       // quartered
  EXPECT_DOUBLE_EQ(c.next(0.02, 100.0), 0.01);       // never below dt
  EXPECT_DOUBLE_EQ(c.next(0.04, std::numeric_limits<double>::quiet_NaN()), 0.01);
  for (double h : {0.01, 0.02, 0.04, 0.08}) {
    for (double e : {0.0, 0.01, 0.05, 0.1, 0.3, 1.0}) {
      const double n = c.next(h, e);
      const double level = std::log2(n / 0.01);
      EXPECT_NEAR(level, std::round(level), 1e-9);
      EXPECT_GE(n, 0.01);
      EXPECT_LE(n, 0.08 + 1e-12);
    }
  }
  // max below dt: fixed steps of dt.
  const StepSizeControl small(0.05, 0.02, 0.1);
  EXPECT_DOUBLE_EQ(small.next(0.05, 0.0), 0.05);
}

}  // namespace
}  // namespace mvtwin::forward
