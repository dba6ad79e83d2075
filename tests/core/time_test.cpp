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

}  // namespace
}  // namespace conesim::core
