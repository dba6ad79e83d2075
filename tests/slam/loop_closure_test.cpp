// The loop closure state machine and its decision, including the guards against false triggers.

#include "slam/loop_closure.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace conesim::slam {
namespace {

TEST(LoopState, InViewLeftViewReturned) {
  const LoopClosureConfig c;
  // stays in view while predicted in view or seen, then leaves
  EXPECT_EQ(next_loop_state(c, LoopState::kInView, true, false, 5.0, 0.0), LoopState::kInView);
  EXPECT_EQ(next_loop_state(c, LoopState::kInView, false, true, 5.0, 0.0), LoopState::kInView);
  EXPECT_EQ(next_loop_state(c, LoopState::kInView, false, false, 5.0, 0.0), LoopState::kLeftView);
  // returns when seen again long after its first sighting, from the same direction
  EXPECT_EQ(next_loop_state(c, LoopState::kLeftView, true, true, 300.0, 0.1), LoopState::kReturned);
  EXPECT_EQ(next_loop_state(c, LoopState::kReturned, false, false, 400.0, 0.0),
            LoopState::kReturned);
}

TEST(LoopState, NoReturnTooSoonOrFromTheOtherSide) {
  const LoopClosureConfig c;
  // a hairpin brings cones seen 20 m ago back into view: not a return
  EXPECT_EQ(next_loop_state(c, LoopState::kLeftView, true, true, 20.0, 0.0), LoopState::kLeftView);
  // a parallel section seen from the opposite direction: not a return
  EXPECT_EQ(next_loop_state(c, LoopState::kLeftView, true, true, 200.0, 3.0), LoopState::kLeftView);
  // predicted in view but not seen: not a return
  EXPECT_EQ(next_loop_state(c, LoopState::kLeftView, true, false, 300.0, 0.0),
            LoopState::kLeftView);
}

// the lap guard passed: near the start pose, with the start's landmarks returned
LoopClosureStats guard_passed() {
  LoopClosureStats s;
  s.near_start = true;
  s.start_returned = LoopClosureConfig{}.start_min_returned;
  return s;
}

TEST(LoopClosure, ClosesOnEnoughConsistentReturnedLandmarks) {
  const LoopClosureConfig c;
  LoopClosureStats s = guard_passed();
  s.travel_m = 300.0;
  s.returned = 8;
  s.old_matched = 6;
  s.old_matched_returned = 6;
  EXPECT_TRUE(loop_closed(c, s));
  // too few returned
  s.returned = 5;
  EXPECT_FALSE(loop_closed(c, s));
}

TEST(LoopClosure, GuardsAgainstFalseTriggers) {
  const LoopClosureConfig c;
  LoopClosureStats s = guard_passed();
  s.returned = 20;
  s.old_matched = 6;
  s.old_matched_returned = 6;
  s.big_orange_returned = true;
  // not before a lap can have been driven, even with big orange cones in view
  s.travel_m = 60.0;
  EXPECT_FALSE(loop_closed(c, s));
  // old landmarks matched now but mostly not returned (seen from elsewhere): no closure
  s.travel_m = 300.0;
  s.old_matched_returned = 2;
  EXPECT_FALSE(loop_closed(c, s));
}

TEST(LoopClosure, HairpinReturnsAreNotALap) {
  // after a hairpin the landmarks of its first leg come back into view from the same side,
  // long after their first sighting: every statistic says "returned", but the car is not at
  // the start (generated seed 8 closed its loop there before this guard)
  const LoopClosureConfig c;
  LoopClosureStats s;
  s.travel_m = 270.0;
  s.returned = 12;
  s.old_matched = 8;
  s.old_matched_returned = 8;
  s.near_start = false;
  s.start_returned = 0;
  EXPECT_FALSE(loop_closed(c, s));
  // near the start but none of the start's own landmarks back: still not a lap
  s.near_start = true;
  EXPECT_FALSE(loop_closed(c, s));
  s.start_returned = c.start_min_returned - 1;
  EXPECT_FALSE(loop_closed(c, s));
  s.start_returned = c.start_min_returned;
  EXPECT_TRUE(loop_closed(c, s));
  // the start's landmarks seen again from elsewhere: not near the start, no closure
  s.near_start = false;
  EXPECT_FALSE(loop_closed(c, s));
}

TEST(LoopClosure, BigOrangeCueNeedsOnlyAFewReturnedLandmarks) {
  const LoopClosureConfig c;
  LoopClosureStats s = guard_passed();
  s.travel_m = 300.0;
  s.returned = 3;
  s.old_matched = 3;
  s.old_matched_returned = 3;
  EXPECT_FALSE(loop_closed(c, s));
  s.big_orange_returned = true;
  EXPECT_TRUE(loop_closed(c, s));
  // big orange cones alone (no returned landmark) do not close the loop
  s.returned = 0;
  s.old_matched_returned = 0;
  EXPECT_FALSE(loop_closed(c, s));
}

TEST(LoopClosure, BackAtStartAfterOneTurnEitherWay) {
  const LoopClosureConfig c;
  const core::Pose2 start{-2.0, 1.0, 0.3};
  // a lap ending a few metres behind the start in its lane, having turned once around, either way
  const core::Pose2 behind = start.compose({-12.0, 1.5, 0.2});
  EXPECT_TRUE(back_at_start(c, start, behind, 2.0 * M_PI + 0.2));
  EXPECT_TRUE(back_at_start(c, start, behind, -2.0 * M_PI + 0.2));
  // the heading summed since the start may be off by the odometry's drift, up to the tolerance
  EXPECT_TRUE(back_at_start(c, start, behind, 2.0 * M_PI + c.heading_tolerance_rad - 0.01));
  EXPECT_FALSE(back_at_start(c, start, behind, 2.0 * M_PI + c.heading_tolerance_rad + 0.01));
  // no turn, or two turns (a spiral), is no lap of a circuit without crossings
  EXPECT_FALSE(back_at_start(c, start, behind, 0.2));
  EXPECT_FALSE(back_at_start(c, start, behind, 4.0 * M_PI + 0.2));
  // facing the other way, or beyond start_radius_m: not back
  EXPECT_FALSE(back_at_start(c, start, start.compose({-12.0, 1.5, M_PI}), 3.0 * M_PI));
  EXPECT_FALSE(
      back_at_start(c, start, start.compose({-c.start_radius_m - 0.1, 0.0, 0.0}), 2.0 * M_PI));
}

TEST(LoopClosure, OneFullTurnEitherWay) {
  EXPECT_TRUE(turned_once_around(2.0 * M_PI, 0.1));
  EXPECT_TRUE(turned_once_around(-2.0 * M_PI + 0.09, 0.1));
  EXPECT_FALSE(turned_once_around(2.0 * M_PI + 0.11, 0.1));
  EXPECT_FALSE(turned_once_around(0.05, 0.1));
  EXPECT_FALSE(turned_once_around(4.0 * M_PI, 0.1));
}

TEST(LoopClosure, ALegAlongsideTheStartIsNoLap) {
  // hard trackdrives 7041 and 7077 start on a straight into a hairpin, then a second hairpin the
  // other way leads onto a leg beside the start straight, 16-18 m over and the same way: the
  // start's cones come back into view from their first heading, 160 m into a 460 m lap. The car
  // has turned by about zero there, not by a full turn
  const LoopClosureConfig c;
  const core::Pose2 start{0.0, 0.0, 0.0};
  const core::Pose2 beside{-2.85, 15.7, 0.61};
  EXPECT_FALSE(back_at_start(c, start, beside, 0.61));
  // a full turn would not make it a lap either: it is 15.7 m off the start's line
  EXPECT_FALSE(back_at_start(c, start, beside, 2.0 * M_PI + 0.61));
  // nor does a lane 8 m over (beyond start_lateral_m), while one in the start's lane is
  EXPECT_FALSE(back_at_start(c, start, {-5.0, c.start_lateral_m + 0.1, 0.0}, 2.0 * M_PI));
  EXPECT_TRUE(back_at_start(c, start, {-5.0, c.start_lateral_m - 0.1, 0.0}, 2.0 * M_PI));
}

TEST(LoopClosureConfig, ValidateNamesTheBadKey) {
  LoopClosureConfig c;
  EXPECT_EQ(c.validate(), "");
  c.returned_fraction = 2.0;
  EXPECT_NE(c.validate().find("loop_closure.returned_fraction"), std::string::npos);
  c = LoopClosureConfig{};
  c.start_radius_m = 0.0;
  EXPECT_NE(c.validate().find("loop_closure.start_radius_m"), std::string::npos);
  c = LoopClosureConfig{};
  c.start_lateral_m = -1.0;
  EXPECT_NE(c.validate().find("loop_closure.start_lateral_m"), std::string::npos);
}

}  // namespace
}  // namespace conesim::slam
