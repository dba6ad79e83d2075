#include "tracks/lanes.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <string>

#include "tracks/io.hpp"

namespace conesim::tracks {
namespace {

using ::testing::HasSubstr;

std::string data(const std::string& path) {
  return std::string(CONESIM_TEST_DATA) + "/tracks/" + path;
}

// adds a cone with the next id and returns the id
int add(Track& track, ConeClass cls, double x, double y) {
  const int id = track.next_id();
  track.cones.push_back({id, cls, {x, y}, std::nullopt});
  return id;
}

// an oval circuit run counter-clockwise: 60 m straights, 15 m turn radius, 4 m wide, cones about
// every 3-4 m; the start is on the bottom straight facing +x
Track oval() {
  Track track;
  track.name = "oval";
  const double half_width = 2.0;
  for (int side = 0; side < 2; ++side) {
    const double r = 15.0 + (side == 0 ? -half_width : half_width);  // blue inside (left)
    const ConeClass cls = side == 0 ? ConeClass::kBlue : ConeClass::kYellow;
    // bottom straight from x=0 to 60 (y = -r), turn around (60, 0), top straight, turn around (0,
    // 0)
    for (double x = 0.0; x < 60.0; x += 4.0) add(track, cls, x, -r);
    const int n_turn = static_cast<int>(std::ceil(std::numbers::pi * r / 3.5));
    for (int k = 0; k < n_turn; ++k) {
      const double a = -std::numbers::pi / 2 + std::numbers::pi * k / n_turn;
      add(track, cls, 60.0 + r * std::cos(a), r * std::sin(a));
    }
    for (double x = 60.0; x > 0.0; x -= 4.0) add(track, cls, x, r);
    for (int k = 0; k < n_turn; ++k) {
      const double a = std::numbers::pi / 2 + std::numbers::pi * k / n_turn;
      add(track, cls, r * std::cos(a), r * std::sin(a));
    }
  }
  track.start = {10.0, -15.0, 0.0};
  return track;
}

std::vector<int> ids_of(const Track& track, ConeClass cls) {
  std::vector<int> ids;
  for (const Cone& c : track.cones)
    if (c.cls == cls) ids.push_back(c.id);
  return ids;
}

// fraction of left-lane cones that lie on the left of the direction of travel
double fraction_left_on_left(const Track& track) {
  const std::vector<Vec2> left = track.lane_points(track.left_lane);
  const std::vector<Vec2> right = track.lane_points(track.right_lane);
  int on_left = 0;
  for (size_t i = 0; i + 1 < left.size(); ++i) {
    const Vec2 dir = left[i + 1] - left[i];
    Vec2 nearest_right = right.front();
    for (const Vec2& r : right)
      if ((r - left[i]).norm() < (nearest_right - left[i]).norm()) nearest_right = r;
    if (core::cross(dir, left[i] - nearest_right) > 0.0) ++on_left;
  }
  return static_cast<double>(on_left) / static_cast<double>(left.size() - 1);
}

TEST(OrderLane, RecoversAShuffledCircuitFromTheStartGoingForward) {
  Track track = oval();
  const std::vector<int> blue = ids_of(track, ConeClass::kBlue);
  std::vector<int> shuffled = blue;
  std::mt19937 rng(7);
  std::shuffle(shuffled.begin(), shuffled.end(), rng);

  std::vector<int> left_out;
  const std::vector<int> lane = order_lane(track, shuffled, &left_out);

  // every cone, in the generated (driving) order, beginning at the cone nearest the start
  EXPECT_TRUE(left_out.empty());
  ASSERT_EQ(lane.size(), blue.size());
  const auto first = std::find(blue.begin(), blue.end(), lane.front());
  std::vector<int> expected(first, blue.end());
  expected.insert(expected.end(), blue.begin(), first);
  EXPECT_EQ(lane, expected);
  EXPECT_NEAR((track.cone(lane.front()).position - track.start.position()).norm(), 2.0, 1.0);
  EXPECT_TRUE(lane_closes(track, lane));
}

TEST(OrderLane, PicksUpConesBehindTheStartOnAnOpenLane) {
  // a straight lane every 5 m from x = -20 to 60, the car starting at x = 10
  Track track;
  std::vector<int> ids;
  for (double x = -20.0; x <= 60.0; x += 5.0) ids.push_back(add(track, ConeClass::kBlue, x, 1.5));
  track.start = {10.0, 0.0, 0.0};
  std::vector<int> reversed(ids.rbegin(), ids.rend());

  const std::vector<int> lane = order_lane(track, reversed);

  EXPECT_EQ(lane, ids);
  EXPECT_FALSE(lane_closes(track, lane));
}

TEST(OrderLane, LeavesOutAnOutlier) {
  Track track = oval();
  std::vector<int> blue = ids_of(track, ConeClass::kBlue);
  const int outlier = add(track, ConeClass::kBlue, 30.0, 0.0);  // in the middle of the infield
  blue.push_back(outlier);

  std::vector<int> left_out;
  const std::vector<int> lane = order_lane(track, blue, &left_out);

  EXPECT_EQ(left_out, std::vector<int>{outlier});
  EXPECT_EQ(lane.size(), blue.size() - 1);
}

TEST(OrderLane, EmptyInputGivesAnEmptyLane) {
  Track track = oval();
  std::vector<int> left_out{42};
  EXPECT_TRUE(order_lane(track, {}, &left_out).empty());
  EXPECT_TRUE(left_out.empty());
}

TEST(RebuildLanes, OvalComesOutClosedWithBlueOnTheLeft) {
  Track track = oval();
  rebuild_lanes(track);
  EXPECT_TRUE(track.closed);
  EXPECT_EQ(track.left_lane.size(), ids_of(track, ConeClass::kBlue).size());
  EXPECT_EQ(track.right_lane.size(), ids_of(track, ConeClass::kYellow).size());
  EXPECT_GT(fraction_left_on_left(track), 0.95);
}

TEST(RebuildLanes, StartFacingBackwardsStillKeepsBlueOnTheLeft) {
  Track track = oval();
  track.start.yaw = std::numbers::pi;  // facing against the layout's direction
  rebuild_lanes(track);
  EXPECT_TRUE(track.closed);
  EXPECT_GT(fraction_left_on_left(track), 0.95);
  EXPECT_THAT(track.warnings, ::testing::Contains(HasSubstr("lanes reversed")));
}

// the real circuits give their lane order: rebuilding from the colours alone must find it
class RebuildMatchesFileOrder : public ::testing::TestWithParam<std::string> {};

TEST_P(RebuildMatchesFileOrder, SameLanesAsTheFile) {
  const Track given = read_track(data(GetParam()));
  Track rebuilt = given;
  rebuilt.left_lane.clear();
  rebuilt.right_lane.clear();
  rebuilt.closed = false;
  rebuild_lanes(rebuilt);
  EXPECT_TRUE(rebuilt.closed);
  EXPECT_EQ(rebuilt.left_lane, given.left_lane);
  EXPECT_EQ(rebuilt.right_lane, given.right_lane);
}

INSTANTIATE_TEST_SUITE_P(Circuits, RebuildMatchesFileOrder,
                         ::testing::Values("fssim/FSG.yaml", "fssim/FSI.yaml", "pacsim/FSG19.yaml",
                                           "pacsim/FSG21.yaml", "pacsim/FSE23.yaml"));

TEST(RebuildLanes, AccelerationLanesContinueThroughOrangeConesInLine) {
  // eufs acceleration: blue/yellow from -45 to 20, big orange gates at -50 and 25, orange
  // braking-zone cones from 30 to 50 on both sides and two across the end of the lane
  const Track track = read_track(data("eufs/acceleration.csv"));
  ASSERT_FALSE(track.closed);
  const std::vector<Vec2> left = track.lane_points(track.left_lane);
  const std::vector<Vec2> right = track.lane_points(track.right_lane);

  // 14 blue + 2 big orange at the start + 1 at the finish + 5 braking-zone cones per side
  EXPECT_EQ(left.size(), 22u);
  EXPECT_EQ(right.size(), 22u);
  for (const Vec2& p : left) EXPECT_DOUBLE_EQ(p.y(), 1.5);
  for (const Vec2& p : right) EXPECT_DOUBLE_EQ(p.y(), -1.5);
  for (size_t i = 0; i + 1 < left.size(); ++i) EXPECT_LT(left[i].x(), left[i + 1].x());
  EXPECT_DOUBLE_EQ(left.front().x(), -50.5);
  EXPECT_DOUBLE_EQ(left.back().x(), 50.0);
}

TEST(RebuildLanes, SkidpadFigureEightDoesNotBreak) {
  // no sensible lanes exist for a figure eight; the result only has to be usable
  for (const char* file : {"eufs/skidpad.csv", "fssim/skidpad.yaml", "pacsim/skidpad.yaml"}) {
    Track track = read_track(data(file));
    rebuild_lanes(track);
    EXPECT_FALSE(track.left_lane.empty()) << file;
    EXPECT_FALSE(track.right_lane.empty()) << file;
    EXPECT_FALSE(derive_centre_line(track).empty()) << file;
  }
}

TEST(RebuildLanes, ScatteredConesDoNotBreak) {
  // no layout at all: cones anywhere in a 200 m square
  Track track;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> coord(-100.0, 100.0);
  for (int i = 0; i < 1000; ++i)
    add(track,
        i % 3 == 0 ? ConeClass::kBlue : (i % 3 == 1 ? ConeClass::kYellow : ConeClass::kOrangeBig),
        coord(rng), coord(rng));
  rebuild_lanes(track);
  EXPECT_FALSE(track.left_lane.empty());
  track.centre_line = derive_centre_line(track);
  guess_start_pose(track);
  EXPECT_TRUE(std::isfinite(track.start.yaw));
}

TEST(DeriveCentreLine, NoneThroughMidpointsThatJumpBetweenFarAwayArms) {
  // a 20 m left lane zigzagging across the axis of a right lane shaped like a tall roof: its
  // nearest right point jumps between the two arms, 29 km apart, at every left sample, so the
  // midpoints' line would run for hundreds of kilometres (a malformed file once asked for a
  // point every metre of it)
  Track track;
  for (int k = 0; k <= 20; ++k)
    track.left_lane.push_back(add(track, ConeClass::kBlue, k % 2 == 0 ? -0.5 : 0.5, k));
  for (const Vec2& p : {Vec2(-15e3, 0.0), Vec2(0.0, 1e5), Vec2(15e3, 0.0)})
    track.right_lane.push_back(add(track, ConeClass::kYellow, p.x(), p.y()));
  EXPECT_TRUE(derive_centre_line(track).empty());

  // the same lanes a few metres apart give a line
  track.right_lane.clear();
  for (int k = 0; k <= 20; ++k) track.right_lane.push_back(add(track, ConeClass::kYellow, 3.0, k));
  EXPECT_FALSE(derive_centre_line(track).empty());
}

TEST(LaneCloses, NeedsEndsCloseTogetherAndALongLane) {
  Track track;
  std::vector<int> square, line;
  for (int k = 0; k < 40; ++k) {  // a 40 m square, a cone every 4 m
    const double s = 4.0 * (k % 10);
    const Vec2 p = k < 10   ? Vec2(s, 0)
                   : k < 20 ? Vec2(40, s)
                   : k < 30 ? Vec2(40 - s, 40)
                            : Vec2(0, 40 - s);
    square.push_back(add(track, ConeClass::kBlue, p.x(), p.y()));
  }
  for (int k = 0; k < 10; ++k) line.push_back(add(track, ConeClass::kYellow, 4.0 * k, -10.0));
  EXPECT_TRUE(lane_closes(track, square));
  EXPECT_FALSE(lane_closes(track, line));
  EXPECT_FALSE(lane_closes(track, {square[0], square[1], square[39]}));  // too short
}

TEST(OrientLanes, RotatesAClosedLaneToBeginAtTheStart) {
  Track track = oval();
  rebuild_lanes(track);
  std::rotate(track.left_lane.begin(), track.left_lane.begin() + 10, track.left_lane.end());
  const std::vector<int> rotated = track.left_lane;
  orient_lanes(track);
  EXPECT_NE(track.left_lane, rotated);
  EXPECT_LT((track.cone(track.left_lane.front()).position - track.start.position()).norm(), 3.0);
}

TEST(GatesFromBigOrange, OneGatePerGroupWithTheLeftPostOnTheBlueSide) {
  const Track track = read_track(data("eufs/acceleration.csv"));
  const std::vector<Gate> gates = gates_from_big_orange(track);
  // four cones at x = -50/-50.5 (start) and two at x = 25 (finish), y = +-1.5
  ASSERT_EQ(gates.size(), 2u);
  for (const Gate& g : gates) {
    EXPECT_DOUBLE_EQ(g.left.y(), 1.5);
    EXPECT_DOUBLE_EQ(g.right.y(), -1.5);
  }
  EXPECT_DOUBLE_EQ(gates[0].left.x(), -50.25);
  EXPECT_DOUBLE_EQ(gates[1].left.x(), 25.0);
}

TEST(GatesFromBigOrange, ConesOnOneSideOnlyGiveNoGate) {
  Track track = oval();
  add(track, ConeClass::kOrangeBig, 10.0, -17.0);  // both on the right boundary
  add(track, ConeClass::kOrangeBig, 11.0, -17.0);
  EXPECT_TRUE(gates_from_big_orange(track).empty());
}

TEST(LeftDirectionAt, PointsFromTheRightBoundaryToTheLeftOne) {
  const Track track = oval();  // bottom straight: blue at y = -13, yellow at y = -17
  const Vec2 left = left_direction_at(track, {20.0, -15.0});
  EXPECT_NEAR(left.x(), 0.0, 1e-9);
  EXPECT_NEAR(left.y(), 1.0, 1e-9);
}

TEST(GuessStartPose, MiddleOfTheBigOrangeGateFacingAlongTheLanes) {
  Track track = oval();
  track.start = {};  // unknown
  add(track, ConeClass::kOrangeBig, 20.0, -12.8);
  add(track, ConeClass::kOrangeBig, 20.0, -17.2);
  guess_start_pose(track);
  EXPECT_NEAR(track.start.x, 20.0, 1e-9);
  EXPECT_NEAR(track.start.y, -15.0, 1e-9);
  EXPECT_NEAR(track.start.yaw, 0.0, 1e-9);  // blue (inside) on the left: counter-clockwise
  EXPECT_THAT(track.warnings, ::testing::Contains(HasSubstr("no start pose given")));
}

TEST(GuessStartPose, WithoutGatesUsesTheCentreLine) {
  Track track = oval();
  rebuild_lanes(track);
  track.centre_line = derive_centre_line(track);
  track.start = {100.0, 100.0, 2.0};
  guess_start_pose(track);
  EXPECT_NEAR((track.start.position() - track.centre_line.front()).norm(), 0.0, 1e-9);
  EXPECT_EQ(track.warnings.size(), 1u);
}

TEST(GuessStartPose, EmptyTrackDoesNotBreak) {
  Track track;
  guess_start_pose(track);
  EXPECT_EQ(track.start.x, 0.0);
  EXPECT_EQ(track.warnings.size(), 1u);
}

}  // namespace
}  // namespace conesim::tracks
