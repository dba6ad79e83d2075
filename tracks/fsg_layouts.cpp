#include "tracks/fsg_layouts.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace conesim::tracks {

namespace {

constexpr double kPi = std::numbers::pi;

// appends a cone with the next id and returns that id
int add_cone(Track& track, ConeClass cls, const Vec2& position) {
  const int id = static_cast<int>(track.cones.size());
  track.cones.push_back({id, cls, position, std::nullopt});
  return id;
}

// appends points of the straight from a to b every step_m, without a itself (a and b are
// copies: a is often path.back())
void append_straight(std::vector<Vec2>& path, const Vec2 a, const Vec2 b, double step_m) {
  const double length = (b - a).norm();
  const int n = std::max(1, static_cast<int>(std::ceil(length / step_m)));
  for (int i = 1; i <= n; ++i) path.push_back(a + (b - a) * (static_cast<double>(i) / n));
}

// appends points of an arc around centre from angle phi0 through sweep (negative: clockwise),
// without the first point
void append_arc(std::vector<Vec2>& path, const Vec2& centre, double radius, double phi0,
                double sweep, double step_m) {
  const int n = std::max(1, static_cast<int>(std::ceil(std::abs(sweep) * radius / step_m)));
  for (int i = 1; i <= n; ++i) {
    const double phi = phi0 + sweep * static_cast<double>(i) / n;
    path.push_back(centre + radius * Vec2(std::cos(phi), std::sin(phi)));
  }
}

}  // namespace

Track make_skidpad() {
  Track track;
  track.name = "skidpad";
  track.event = EventType::kSkidpad;
  track.closed = false;
  track.start = {0.0, 0.0, 0.0};

  // geometry: the timing line is x = d, the right circle (driven first) lies at y < 0
  const double d = kSkidpadStartToTimingLineM;
  const double half_gap = kSkidpadCentreDistanceM / 2.0;  // 9.125 m
  const Vec2 right_centre(d, -half_gap);
  const Vec2 left_centre(d, half_gap);
  const double lane_half_width = half_gap - kSkidpadInnerConeRadiusM;  // 1.65 m, as fssim
  constexpr int kConesPerRing = 16;                                    // 22.5 degrees apart
  const double step = 2.0 * kPi / kConesPerRing;

  // inner rings: 16 cones each, one of them on the timing line; yellow inside the right circle
  // (on the car's right while it turns clockwise), blue inside the left circle
  for (int k = 0; k < kConesPerRing; ++k) {
    const Vec2 u(std::cos(k * step), std::sin(k * step));
    add_cone(track, ConeClass::kYellow, right_centre + kSkidpadInnerConeRadiusM * u);
  }
  for (int k = 0; k < kConesPerRing; ++k) {
    const Vec2 u(std::cos(k * step), std::sin(k * step));
    add_cone(track, ConeClass::kBlue, left_centre + kSkidpadInnerConeRadiusM * u);
  }

  // entry lane: small orange cones at 15 and 11.25 m before the timing line (fssim, PacSim)
  std::vector<int> left_lane, right_lane;
  for (double x : {d - 15.0, d - 11.25}) {
    left_lane.push_back(add_cone(track, ConeClass::kOrangeSmall, {x, lane_half_width}));
    right_lane.push_back(add_cone(track, ConeClass::kOrangeSmall, {x, -lane_half_width}));
  }

  // outer rings: the 16 positions less the three facing the other circle, where the car
  // crosses over; walked from the entry side over the far side to the exit side, so each
  // ring continues its lane. Blue outside the right circle, yellow outside the left.
  for (int k = 0; k <= 12; ++k) {
    const double phi_left = 1.25 * kPi - k * step;   // 225 deg down to -45 deg
    const double phi_right = 0.75 * kPi + k * step;  // 135 deg up to 405 deg
    left_lane.push_back(add_cone(
        track, ConeClass::kYellow,
        left_centre + kSkidpadOuterConeRadiusM * Vec2(std::cos(phi_left), std::sin(phi_left))));
    right_lane.push_back(add_cone(
        track, ConeClass::kBlue,
        right_centre + kSkidpadOuterConeRadiusM * Vec2(std::cos(phi_right), std::sin(phi_right))));
  }

  // exit lane to the stop area: small orange cones at 11, 16 and 21 m past the timing line,
  // and one across the lane at 21 m marking the stop line (fssim, PacSim)
  for (double x : {d + 11.0, d + 16.0, d + 21.0}) {
    left_lane.push_back(add_cone(track, ConeClass::kOrangeSmall, {x, lane_half_width}));
    right_lane.push_back(add_cone(track, ConeClass::kOrangeSmall, {x, -lane_half_width}));
  }
  add_cone(track, ConeClass::kOrangeSmall, {d + 21.0, 0.0});

  // timing line: big orange cones 1.3 m either side of it, 2 m out (fssim, PacSim), and the gate
  for (double dx : {-1.3, 1.3})
    for (double y : {2.0, -2.0}) add_cone(track, ConeClass::kOrangeBig, {d + dx, y});
  track.timing_gates.push_back({{d, 2.5}, {d, -2.5}});

  // lanes: the outer envelope of the figure eight (entry lane, outer rings, exit lane), as
  // PacSim's skidpad lists them; the inner rings belong to no lane
  track.left_lane = std::move(left_lane);
  track.right_lane = std::move(right_lane);

  track.centre_line = skidpad_driving_path({d, 0.0}, Vec2::UnitX(), Vec2::Zero());
  return track;
}

std::vector<Vec2> skidpad_driving_path(const Vec2& timing_mid, const Vec2& forward,
                                       const Vec2& start) {
  // entry, two clockwise laps of the right circle, two counter-clockwise laps of the left
  // circle, exit to 1 m before the stop line; points every 0.5 m or a little less
  constexpr double kStepM = 0.5;
  const double r = 0.5 * kSkidpadCentreDistanceM;
  const Vec2 f = forward.normalized();
  const Vec2 left(-f.y(), f.x());
  const double heading = std::atan2(f.y(), f.x());
  const double along_start = std::min((start - timing_mid).dot(f), 0.0);
  std::vector<Vec2> path{timing_mid + along_start * f};
  append_straight(path, path.back(), timing_mid, kStepM);
  append_arc(path, timing_mid - r * left, r, heading + 0.5 * kPi, -4.0 * kPi, kStepM);
  append_arc(path, timing_mid + r * left, r, heading - 0.5 * kPi, 4.0 * kPi, kStepM);
  append_straight(path, path.back(), timing_mid + 20.0 * f, kStepM);
  return path;
}

Track make_acceleration() {
  Track track;
  track.name = "acceleration";
  track.event = EventType::kAcceleration;
  track.closed = false;
  track.start = {-kAccelerationStartSetbackM, 0.0, 0.0};
  const double w = kAccelerationHalfWidthM;
  const double finish = kAccelerationLengthM;

  // one cone pair at x: blue (or cls) on the left, yellow (or cls) on the right
  auto add_pair = [&track](double x, double half_width, ConeClass left, ConeClass right) {
    track.left_lane.push_back(add_cone(track, left, {x, half_width}));
    track.right_lane.push_back(add_cone(track, right, {x, -half_width}));
  };

  // start gate: big orange cones 0.3 m before and after the start line (fssim, PacSim)
  add_pair(-0.3, w, ConeClass::kOrangeBig, ConeClass::kOrangeBig);
  add_pair(0.3, w, ConeClass::kOrangeBig, ConeClass::kOrangeBig);

  // the straight: blue left, yellow right, every 5 m
  for (double x = 5.0; x < finish - 1.0; x += 5.0)
    add_pair(x, w, ConeClass::kBlue, ConeClass::kYellow);

  // finish gate: big orange cones 0.3 m either side of the finish line
  add_pair(finish - 0.3, w, ConeClass::kOrangeBig, ConeClass::kOrangeBig);
  add_pair(finish + 0.3, w, ConeClass::kOrangeBig, ConeClass::kOrangeBig);

  // braking zone: small orange cones every 5 m from 5 m past the finish to its end, and one
  // across the lane at the end
  for (double x = finish + 5.0; x <= finish + kAccelerationBrakingZoneM + 1e-9; x += 5.0)
    add_pair(x, w, ConeClass::kOrangeSmall, ConeClass::kOrangeSmall);
  add_cone(track, ConeClass::kOrangeSmall, {finish + kAccelerationBrakingZoneM, 0.0});

  // timing gates at the start and the finish line, posts 0.5 m outside the cones (fssim)
  track.timing_gates.push_back({{0.0, w + 0.5}, {0.0, -(w + 0.5)}});
  track.timing_gates.push_back({{finish, w + 0.5}, {finish, -(w + 0.5)}});

  track.centre_line = derive_centre_line(track);
  return track;
}

}  // namespace conesim::tracks
