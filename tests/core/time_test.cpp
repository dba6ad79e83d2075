#include "core/time.hpp"

#include <gtest/gtest.h>

namespace conesim::core {
namespace {

TEST(PhysicsSteps, RatesMustFireOnEveryPeriod) {
  // periods of whole 2 ms steps: 100, 50, 40, 20, 10, 8, 4, 2 ms
  for (double hz : {10.0, 20.0, 25.0, 50.0, 100.0, 125.0, 250.0, 500.0})
    EXPECT_TRUE(whole_physics_steps(hz)) << hz;
  // 25 ms, 1 ms, 33.3 ms, 3 ms: "t % period == 0" would skip samples or never fire
  for (double hz : {40.0, 1000.0, 30.0, 1000.0 / 3.0, 0.0, -10.0})
    EXPECT_FALSE(whole_physics_steps(hz)) << hz;
}

TEST(FromSeconds, RoundsAndSaturatesInsteadOfOverflowing) {
  EXPECT_EQ(from_seconds(1.5), 1'500'000);
  EXPECT_EQ(from_seconds(-0.0000014), -1);
  // a referee timeout of 1e13 s is 1e19 us, past the 64-bit clock: the largest time, not
  // undefined behaviour (issue 20 item 2)
  EXPECT_EQ(from_seconds(1e13), std::numeric_limits<TimeUs>::max());
  EXPECT_EQ(from_seconds(-1e13), std::numeric_limits<TimeUs>::min());
  EXPECT_EQ(from_seconds(1e300), std::numeric_limits<TimeUs>::max());
  EXPECT_EQ(from_seconds(std::numeric_limits<double>::infinity()),
            std::numeric_limits<TimeUs>::max());
  EXPECT_EQ(from_seconds(std::numeric_limits<double>::quiet_NaN()), 0);
  // the largest time that fits still converts exactly enough
  EXPECT_GT(from_seconds(9.2e12), 9'199'999'999'999'999'000);
}

}  // namespace
}  // namespace conesim::core
