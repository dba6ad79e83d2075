#include "sim/referee.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>
#include <stdexcept>
#include <string>

#include "tracks/fsg_layouts.hpp"
#include "tracks/generator.hpp"
#include "tracks/io.hpp"

namespace conesim::sim {
namespace {

using core::EventType;
using core::Pose2;
using core::TimeUs;
using core::Vec2;
using tracks::ConeClass;
using tracks::Track;
using vehicle_models::VehicleParams;

constexpr double kPi = std::numbers::pi;
constexpr TimeUs kStepUs = 1000;  // the 1 kHz physics step
constexpr double kStepS = 1e-3;

// where the car is and how fast it goes at a time of a scripted run
struct Motion {
  Pose2 pose;  // rear axle centre
  double speed_mps = 0.0;
};
using Script = std::function<Motion(double t_s)>;

// the true state of a car with its rear axle at pose: wheels from the wheelbase and track width
VehicleTruth truth_at(const Motion& m, const VehicleParams& car) {
  VehicleTruth t;
  t.pose = m.pose;
  t.vx_mps = m.speed_mps;
  const double h = 0.5 * car.track_m;
  t.wheel_positions = {m.pose.transform({car.wheelbase_m, h}),
                       m.pose.transform({car.wheelbase_m, -h}), m.pose.transform({0.0, h}),
                       m.pose.transform({0.0, -h})};
  return t;
}

// the rear axle pose that puts the front wing at (x, y) with heading yaw
Pose2 front_at(double x, double y, double yaw, const VehicleParams& car) {
  const double f = car.front_overhang_from_rear_axle_m;
  return {x - f * std::cos(yaw), y - f * std::sin(yaw), yaw};
}

// steps the referee through the script every millisecond from from_s until it finishes or until_s
// passes; returns the last time judged, seconds
double run(Referee& referee, const Script& script, double until_s, const VehicleParams& car,
           double from_s = 0.0) {
  double t_s = from_s;
  for (TimeUs t = core::from_seconds(from_s); t <= core::from_seconds(until_s); t += kStepUs) {
    t_s = core::to_seconds(t);
    referee.update(t, truth_at(script(t_s), car));
    if (referee.finished()) break;
  }
  return t_s;
}

// an acceleration straight by hand: cones 1.9 m either side every 5 m from -0.3 m to 150 m, one
// across the lane at 150 m, gates at 0 and 75 m; cone ids 10 apart to exercise the id index
Track straight_track() {
  Track track;
  track.name = "straight";
  track.event = EventType::kAcceleration;
  track.start = {-0.3, 0.0, 0.0};
  int id = 100;
  for (double x = -0.3; x <= 150.0 + 1e-9; x += 5.0) {
    track.cones.push_back({id, ConeClass::kBlue, {x, 1.9}, std::nullopt});
    track.left_lane.push_back(id);
    id += 10;
    track.cones.push_back({id, ConeClass::kYellow, {x, -1.9}, std::nullopt});
    track.right_lane.push_back(id);
    id += 10;
  }
  track.cones.push_back({id, ConeClass::kOrangeSmall, {150.0, 0.0}, std::nullopt});
  track.timing_gates = {{{0.0, 2.4}, {0.0, -2.4}}, {{75.0, 2.4}, {75.0, -2.4}}};
  for (double x = -0.3; x <= 150.0; x += 1.0) track.centre_line.push_back({x, 0.0});
  return track;
}

// an oval driven counter-clockwise: straights of 50 m along y = 0 and y = 30, semicircles of
// radius 15 m; arc length s = 0 at the origin
struct Oval {
  static constexpr double kStraightM = 50.0;
  static constexpr double kRadiusM = 15.0;
  static constexpr double kWidthM = 3.5;
  static constexpr double kGateS = 10.0;
  static constexpr double kStartS = 4.0;

  static double length() { return 2.0 * kStraightM + 2.0 * kPi * kRadiusM; }

  // the centre-line pose at arc length s
  static Pose2 at(double s) {
    const double l = kStraightM, r = kRadiusM;
    s = std::fmod(s, length());
    if (s < l) return {s, 0.0, 0.0};
    if (s < l + kPi * r) {
      const double phi = (s - l) / r;
      return {l + r * std::sin(phi), r - r * std::cos(phi), core::normalize_angle(phi)};
    }
    if (s < 2.0 * l + kPi * r) return {l - (s - l - kPi * r), 2.0 * r, kPi};
    const double phi = (s - 2.0 * l - kPi * r) / r;
    return {-r * std::sin(phi), r + r * std::cos(phi), core::normalize_angle(kPi + phi)};
  }

  // cones every 3 m of centre line on both sides, the gate at kGateS, the start at kStartS
  static Track track() {
    Track track;
    track.name = "oval";
    track.closed = true;
    track.start = at(kStartS);
    const int n = static_cast<int>(length() / 3.0);
    for (int i = 0; i < n; ++i) {
      const Pose2 p = at(length() * i / n);
      for (const double side : {1.0, -1.0}) {
        const int id = static_cast<int>(track.cones.size());
        const Vec2 pos = p.transform({0.0, side * 0.5 * kWidthM});
        track.cones.push_back(
            {id, side > 0 ? ConeClass::kBlue : ConeClass::kYellow, pos, std::nullopt});
        (side > 0 ? track.left_lane : track.right_lane).push_back(id);
      }
    }
    const Pose2 g = at(kGateS);
    track.timing_gates.push_back(
        {g.transform({0.0, 0.5 * kWidthM + 1.0}), g.transform({0.0, -0.5 * kWidthM - 1.0})});
    for (int i = 0; i < static_cast<int>(length()); ++i)
      track.centre_line.push_back(at(length() * i / static_cast<int>(length())).position());
    return track;
  }

  // the rear axle follows the centre line from the start at speed_mps for distance_m, then stops
  static Script drive(double speed_mps, double distance_m) {
    return [=](double t_s) {
      const double travelled = std::min(speed_mps * t_s, distance_m);
      return Motion{at(kStartS + travelled), travelled < distance_m ? speed_mps : 0.0};
    };
  }
};

// acceleration: the front wing starts 1 m before the start line at 20 m/s, brakes at 8 m/s^2
// from brake_at_m (front wing position) and stands still after that
Script acceleration_run(double brake_at_m, const VehicleParams& car) {
  return [=](double t_s) {
    constexpr double kSpeed = 20.0, kDecel = 8.0;
    const double t_brake = (brake_at_m + 1.0) / kSpeed;
    if (t_s <= t_brake) return Motion{front_at(-1.0 + kSpeed * t_s, 0.0, 0.0, car), kSpeed};
    const double tau = std::min(t_s - t_brake, kSpeed / kDecel);
    const double x = brake_at_m + kSpeed * tau - 0.5 * kDecel * tau * tau;
    return Motion{front_at(x, 0.0, 0.0, car), kSpeed - kDecel * tau};
  };
}

TEST(Referee, DrivingThroughTheStartGateStartsTheClock) {
  const VehicleParams car;
  Referee referee(straight_track(), EventType::kAcceleration, car);

  // 10 m/s from 2 m before the line: the front wing crosses it at 0.2 s
  const Script script = [&](double t) {
    return Motion{front_at(-2.0 + 10.0 * t, 0, 0, car), 10.0};
  };
  run(referee, script, 0.15, car);
  EXPECT_EQ(referee.result().raw_time_s, 0.0);
  run(referee, script, 1.2, car, 0.151);
  EXPECT_NEAR(referee.result().raw_time_s, 1.0, kStepS);
  EXPECT_FALSE(referee.finished());
}

TEST(Referee, AccelerationAt20MpsTakes3p75sAndCompletesWhenStoppedInTheBrakingZone) {
  const VehicleParams car;
  Referee referee(straight_track(), EventType::kAcceleration, car);
  run(referee, acceleration_run(100.0, car), 20.0, car);

  const RefereeResult& r = referee.result();
  ASSERT_TRUE(referee.finished());
  EXPECT_TRUE(r.completed) << r.dnf_reason;
  EXPECT_EQ(r.laps, 1);
  ASSERT_EQ(r.lap_times_s.size(), 1u);
  EXPECT_NEAR(r.lap_times_s[0], 3.75, kStepS);
  EXPECT_NEAR(r.raw_time_s, 3.75, kStepS);
  EXPECT_NEAR(r.final_time_s, 3.75, kStepS);
  EXPECT_TRUE(r.cones_hit.empty());
  EXPECT_EQ(r.off_course, 0);
}

TEST(Referee, AccelerationOnTheFsgLayoutCompletes) {
  const VehicleParams car;
  Referee referee(tracks::make_acceleration(), EventType::kAcceleration, car);
  run(referee, acceleration_run(100.0, car), 20.0, car);
  EXPECT_TRUE(referee.result().completed) << referee.result().dnf_reason;
  EXPECT_NEAR(referee.result().raw_time_s, 3.75, kStepS);
  EXPECT_TRUE(referee.result().cones_hit.empty());
}

TEST(Referee, StoppingBeyondTheBrakingZoneIsDnf) {
  const VehicleParams car;
  Referee referee(straight_track(), EventType::kAcceleration, car);
  // braking from 140 m stops at 165 m, past the end cone at 150 m
  run(referee, acceleration_run(140.0, car), 20.0, car);
  EXPECT_TRUE(referee.finished());
  EXPECT_FALSE(referee.result().completed);
  EXPECT_TRUE(referee.result().dnf_reason.starts_with("overran braking zone at ("))
      << referee.result().dnf_reason;
}

TEST(Referee, DrivingThroughAConeKnocksItOverOnceAndAdds2s) {
  const VehicleParams car;
  Track track = straight_track();
  const int id = track.next_id();
  track.cones.push_back({id, ConeClass::kOrangeSmall, {30.0, 0.5}, std::nullopt});
  Referee referee(track, EventType::kAcceleration, car);

  // the car drives over the cone for 145 steps and on to the finish
  EXPECT_FALSE(referee.is_knocked(id));
  run(referee, acceleration_run(100.0, car), 20.0, car);
  const RefereeResult& r = referee.result();
  EXPECT_TRUE(referee.is_knocked(id));
  ASSERT_EQ(r.cones_hit.size(), 1u);
  EXPECT_EQ(r.cones_hit[0], id);
  EXPECT_FALSE(referee.is_knocked(100));
  EXPECT_FALSE(referee.is_knocked(-7));

  // the 2 s land on the final time
  EXPECT_TRUE(r.completed) << r.dnf_reason;
  EXPECT_NEAR(r.penalty_s, 2.0, 1e-12);
  EXPECT_NEAR(r.final_time_s, 3.75 + 2.0, kStepS);
}

// the straight drive with a sideways excursion to lateral offset y_out between 20 and 35 m
Script swerve(double y_out, const VehicleParams& car) {
  return [=](double t) {
    const double x = -1.0 + 10.0 * t;
    const double y = x > 20.0 && x < 35.0 ? y_out * std::sin(kPi * (x - 20.0) / 15.0) : 0.0;
    return Motion{front_at(x, y, 0.0, car), 10.0};
  };
}

TEST(Referee, AllFourWheelsOutsideOnceIsExactlyOneOffCourse) {
  const VehicleParams car;
  Referee referee(straight_track(), EventType::kAcceleration, car);
  run(referee, swerve(3.5, car), 5.0, car);  // wheels 2.9-4.1 m out at the peak, cones at 1.9
  const RefereeResult& r = referee.result();
  EXPECT_FALSE(referee.finished());
  EXPECT_EQ(r.off_course, 1);
  EXPECT_NEAR(r.penalty_s, 10.0 + 2.0 * static_cast<double>(r.cones_hit.size()), 1e-12);
}

TEST(Referee, TwoWheelsOutsideIsNotOffCourse) {
  const VehicleParams car;
  Referee referee(straight_track(), EventType::kAcceleration, car);
  run(referee, swerve(1.8, car), 5.0, car);  // left wheels at 2.4 m, right wheels at 1.2 m
  EXPECT_EQ(referee.result().off_course, 0);
}

TEST(Referee, DrivingAwayFromTheTrackIsDnfLeftTheTrack) {
  const VehicleParams car;
  Referee referee(straight_track(), EventType::kAcceleration, car);
  // through the start line, then straight out to the left at 40 m
  const Script script = [&](double t) {
    const double x = -1.0 + 10.0 * t;
    if (x < 40.0) return Motion{front_at(x, 0.0, 0.0, car), 10.0};
    return Motion{front_at(40.0, x - 40.0, kPi / 2, car), 10.0};
  };
  const double t_end = run(referee, script, 20.0, car);
  EXPECT_TRUE(referee.result().dnf_reason.starts_with("left the track at ("))
      << referee.result().dnf_reason;
  EXPECT_EQ(referee.result().off_course, 1);
  // the footprint centre (1.45 m behind the front wing) is 10 m from the nearest cone, at
  // (40, 1.9), when the front wing is 13.35 m out
  EXPECT_NEAR(t_end, 4.1 + 1.335, 2 * kStepS);
}

TEST(Referee, CrawlingPastTheLimitIsDnfTimeout) {
  const VehicleParams car;
  Referee referee(straight_track(), EventType::kAcceleration, car);
  // 0.5 m/s: across the line at 1 s, 25 s allowed from there
  const Script script = [&](double t) { return Motion{front_at(-0.5 + 0.5 * t, 0, 0, car), 0.5}; };
  const double t_end = run(referee, script, 60.0, car);
  EXPECT_TRUE(referee.result().dnf_reason.starts_with("timeout at ("))
      << referee.result().dnf_reason;
  EXPECT_NEAR(t_end, 26.0, 2 * kStepS);
  EXPECT_NEAR(referee.result().raw_time_s, 25.0, 2 * kStepS);
}

TEST(Referee, TrackdriveFirstLapHasItsOwnTimeout) {
  const VehicleParams car;
  Referee referee(Oval::track(), EventType::kTrackdrive, car);
  const double t_end = run(referee, Oval::drive(0.5, 1e9), 400.0, car);
  EXPECT_TRUE(referee.result().dnf_reason.starts_with("timeout (first lap) at ("))
      << referee.result().dnf_reason;
  // across the line after 3.75 m at 0.5 m/s, then 300 s
  EXPECT_NEAR(t_end, 7.5 + 300.0, 2 * kStepS);
}

TEST(Referee, ACarThatNeverMovesIsDnfStuck) {
  const VehicleParams car;
  Referee referee(Oval::track(), EventType::kAutocross, car);
  const double t_end = run(referee, Oval::drive(0.0, 0.0), 400.0, car);
  EXPECT_TRUE(referee.result().dnf_reason.starts_with("stuck at (")) << referee.result().dnf_reason;
  EXPECT_NEAR(t_end, 15.0, 2 * kStepS);
}

TEST(Referee, ACarThatStopsOnTheTrackIsDnfStuck) {
  const VehicleParams car;
  Referee referee(Oval::track(), EventType::kAutocross, car);
  // 10 m/s for 30 m (2.9 s past the line), then standing
  const double t_end = run(referee, Oval::drive(10.0, 30.0), 400.0, car);
  EXPECT_TRUE(referee.result().dnf_reason.starts_with("stuck at (")) << referee.result().dnf_reason;
  EXPECT_NEAR(t_end, 3.0 + 15.0, 2 * kStepS);
  EXPECT_EQ(referee.result().laps, 0);
}

TEST(Referee, AutocrossCountsOneLapAndCompletesAfterTheStop) {
  const VehicleParams car;
  Referee referee(Oval::track(), EventType::kAutocross, car);
  const double lap_s = Oval::length() / 10.0;
  run(referee, Oval::drive(10.0, Oval::length() + 10.0), 100.0, car);

  const RefereeResult& r = referee.result();
  EXPECT_TRUE(r.completed) << r.dnf_reason;
  EXPECT_EQ(referee.laps(), 1);
  ASSERT_EQ(r.lap_times_s.size(), 1u);
  EXPECT_NEAR(r.lap_times_s[0], lap_s, kStepS);
  EXPECT_NEAR(r.final_time_s, lap_s, kStepS);
  EXPECT_TRUE(r.cones_hit.empty());
  EXPECT_EQ(r.off_course, 0);
}

TEST(Referee, ReversingBackOverTheLineDoesNotCountALap) {
  const VehicleParams car;
  Referee referee(Oval::track(), EventType::kAutocross, car);
  // 10 m forward (across the line), 10 m back (across it backwards), then a lap and 10 m
  const Script script = [](double t) {
    if (t < 1.0) return Motion{Oval::at(Oval::kStartS + 10.0 * t), 10.0};
    if (t < 2.0) return Motion{Oval::at(Oval::kStartS + 10.0 - 10.0 * (t - 1.0)), -10.0};
    const double d = std::min(10.0 * (t - 2.0), Oval::length() + 10.0);
    return Motion{Oval::at(Oval::kStartS + d), d < Oval::length() + 10.0 ? 10.0 : 0.0};
  };
  run(referee, script, 2.5, car);
  EXPECT_EQ(referee.laps(), 0);
  run(referee, script, 100.0, car, 2.501);
  EXPECT_TRUE(referee.result().completed) << referee.result().dnf_reason;
  EXPECT_EQ(referee.laps(), 1);
  EXPECT_NEAR(referee.result().raw_time_s, 2.0 + Oval::length() / 10.0, kStepS);
}

TEST(Referee, LeavingACircuitOnceIsOneOffCourseOnTopOfTheLapTime) {
  const VehicleParams car;
  Referee referee(Oval::track(), EventType::kAutocross, car);
  // on the first straight the car slides 3.5 m to the right (outside) and back
  const Script script = [](double t) {
    const double s = std::min(10.0 * t, Oval::length() + 10.0);
    const double y = s > 20.0 && s < 35.0 ? -3.5 * std::sin(kPi * (s - 20.0) / 15.0) : 0.0;
    return Motion{Oval::at(Oval::kStartS + s).compose({0.0, y, 0.0}),
                  s < Oval::length() + 10.0 ? 10.0 : 0.0};
  };
  run(referee, script, 100.0, car);
  const RefereeResult& r = referee.result();
  EXPECT_TRUE(r.completed) << r.dnf_reason;
  EXPECT_EQ(r.off_course, 1);
  EXPECT_NEAR(r.final_time_s - r.raw_time_s, 10.0 + 2.0 * static_cast<double>(r.cones_hit.size()),
              1e-9);
}

TEST(Referee, WithoutGatesTheLineIsAcrossTheTrackAheadOfTheStart) {
  const VehicleParams car;
  Track track = Oval::track();
  track.timing_gates.clear();
  Referee referee(track, EventType::kAutocross, car);
  run(referee, Oval::drive(10.0, Oval::length() + 10.0), 100.0, car);
  EXPECT_TRUE(referee.result().completed) << referee.result().dnf_reason;
  EXPECT_NEAR(referee.result().raw_time_s, Oval::length() / 10.0, kStepS);
}

TEST(Referee, TrackdriveCountsTenLapsWithTheirTimes) {
  const VehicleParams car;
  Referee referee(Oval::track(), EventType::kTrackdrive, car);
  const double lap_s = Oval::length() / 15.0;
  run(referee, Oval::drive(15.0, 10.0 * Oval::length() + 10.0), 200.0, car);

  const RefereeResult& r = referee.result();
  EXPECT_TRUE(r.completed) << r.dnf_reason;
  EXPECT_EQ(r.laps, 10);
  ASSERT_EQ(r.lap_times_s.size(), 10u);
  for (double t : r.lap_times_s) EXPECT_NEAR(t, lap_s, kStepS);
  EXPECT_NEAR(r.raw_time_s, 10.0 * lap_s, kStepS);
  EXPECT_TRUE(r.cones_hit.empty());
  EXPECT_EQ(r.off_course, 0);
}

TEST(Referee, TrackdriveStoppingBeforeTenLapsIsDnfStoppedEarly) {
  const VehicleParams car;
  Referee referee(Oval::track(), EventType::kTrackdrive, car);
  run(referee, Oval::drive(15.0, 7.0 * Oval::length() + 10.0), 200.0, car);
  EXPECT_TRUE(referee.result().dnf_reason.starts_with("stopped early at ("))
      << referee.result().dnf_reason;
  EXPECT_EQ(referee.result().laps, 7);
}

// the rear axle follows a closed line at speed_mps for distance_m from its point nearest `from`,
// then stands still
Script follow_closed_line(const std::vector<Vec2>& line, const Vec2& from, double speed_mps,
                          double distance_m) {
  std::vector<double> s{0.0};
  for (size_t i = 1; i <= line.size(); ++i)
    s.push_back(s.back() + (line[i % line.size()] - line[i - 1]).norm());
  size_t nearest = 0;
  for (size_t i = 1; i < line.size(); ++i)
    if ((line[i] - from).norm() < (line[nearest] - from).norm()) nearest = i;
  const double lap_m = s.back(), s0 = s[nearest];
  return [=](double t) {
    const double d = std::min(speed_mps * t, distance_m);
    const double m = std::fmod(s0 + d, lap_m);
    const size_t i = static_cast<size_t>(std::upper_bound(s.begin(), s.end(), m) - s.begin()) - 1;
    const Vec2 a = line[i % line.size()], b = line[(i + 1) % line.size()];
    const Vec2 p = a + (b - a) * ((m - s[i]) / (s[i + 1] - s[i]));
    return Motion{{p.x(), p.y(), std::atan2(b.y() - a.y(), b.x() - a.x())},
                  d < distance_m ? speed_mps : 0.0};
  };
}

// length of a closed line
double closed_length(const std::vector<Vec2>& line) {
  double length = 0.0;
  for (size_t i = 0; i < line.size(); ++i) length += (line[(i + 1) % line.size()] - line[i]).norm();
  return length;
}

TEST(Referee, AutocrossOnAGeneratedCircuitCompletesClean) {
  const VehicleParams car;
  const Track track = tracks::generate_circuit(7);
  Referee referee(track, EventType::kAutocross, car);

  // from the start pose, 6 m behind the line, for a lap and 5 m
  const double lap_m = closed_length(track.centre_line);
  run(referee, follow_closed_line(track.centre_line, track.start.position(), 8.0, lap_m + 11.0),
      200.0, car);
  const RefereeResult& r = referee.result();
  EXPECT_TRUE(r.completed) << r.dnf_reason;
  EXPECT_EQ(r.laps, 1);
  EXPECT_NEAR(r.raw_time_s, lap_m / 8.0, 2 * kStepS);
  EXPECT_EQ(r.off_course, 0);
}

TEST(Referee, AutocrossOnFssimAndPacsimCircuitFilesCountsTheLap) {
  const VehicleParams car;
  for (const char* file : {"fssim/FSG.yaml", "pacsim/FSG19.yaml"}) {
    SCOPED_TRACE(file);
    const Track track = tracks::read_track(std::string(CONESIM_TEST_DATA) + "/tracks/" + file);
    Referee referee(track, EventType::kAutocross, car);
    const double lap_m = closed_length(track.centre_line);
    run(referee, follow_closed_line(track.centre_line, track.start.position(), 8.0, lap_m + 20.0),
        200.0, car);
    const RefereeResult& r = referee.result();
    EXPECT_TRUE(r.completed) << r.dnf_reason;
    EXPECT_EQ(r.laps, 1);
    EXPECT_NEAR(r.raw_time_s, lap_m / 8.0, 2 * kStepS);
    EXPECT_EQ(r.off_course, 0);
  }
}

TEST(Referee, ACarThatDoesNotStopAfterTheLapIsDnf) {
  const VehicleParams car;
  Referee referee(Oval::track(), EventType::kAutocross, car);
  // the lap ends when the front wing crosses the line again, then 30 s are allowed
  const double t_end = run(referee, Oval::drive(10.0, 1e9), 100.0, car);
  EXPECT_TRUE(referee.result().dnf_reason.starts_with("did not stop at ("))
      << referee.result().dnf_reason;
  EXPECT_EQ(referee.result().laps, 1);
  EXPECT_NEAR(t_end,
              (Oval::kGateS - Oval::kStartS - car.front_overhang_from_rear_axle_m) / 10.0 +
                  Oval::length() / 10.0 + 30.0,
              2 * kStepS);
}

// the skidpad figure eight of make_skidpad for the rear axle: entry to the timing line, two
// laps of the first circle, two of the second, 15 m of exit lane, then standing still
Script skidpad_run(double speed_mps, bool left_circle_first) {
  const double d = tracks::kSkidpadStartToTimingLineM;
  const double r = tracks::kSkidpadCentreDistanceM / 2.0;
  const double laps_m = 4.0 * kPi * r;
  return [=](double t) {
    const double s = speed_mps * t;
    if (s < d) return Motion{{s, 0.0, 0.0}, speed_mps};
    double u = s - d;
    for (int circle = 0; circle < 2; ++circle, u -= laps_m) {
      if (u >= laps_m) continue;
      // clockwise around the right circle (y < 0) or counter-clockwise around the left one
      const bool clockwise = (circle == 0) != left_circle_first;
      const double sign = clockwise ? -1.0 : 1.0;
      const double theta = -sign * kPi / 2 + sign * u / r;
      const Vec2 c(d, sign * r);
      return Motion{{c.x() + r * std::cos(theta), c.y() + r * std::sin(theta),
                     core::normalize_angle(theta + sign * kPi / 2)},
                    speed_mps};
    }
    const double x = std::min(u, 15.0);
    return Motion{{d + x, 0.0, 0.0}, u < 15.0 ? speed_mps : 0.0};
  };
}

TEST(Referee, SkidpadFigureEightCompletesWithFourLapsAndTheTimedAverage) {
  const VehicleParams car;
  Referee referee(tracks::make_skidpad(), EventType::kSkidpad, car);
  run(referee, skidpad_run(8.0, false), 90.0, car);

  // laps 2 to 4 are whole circles at the timing line; lap 1 starts on the entry straight
  const RefereeResult& r = referee.result();
  const double circle_s = 2.0 * kPi * tracks::kSkidpadCentreDistanceM / 2.0 / 8.0;
  EXPECT_TRUE(r.completed) << r.dnf_reason;
  EXPECT_EQ(r.laps, 4);
  ASSERT_EQ(r.lap_times_s.size(), 4u);
  for (size_t i = 1; i < 4; ++i) EXPECT_NEAR(r.lap_times_s[i], circle_s, kStepS);
  EXPECT_NEAR(r.raw_time_s, 0.5 * (r.lap_times_s[1] + r.lap_times_s[3]), 1e-9);
  EXPECT_NEAR(r.final_time_s, circle_s, kStepS);
  EXPECT_TRUE(r.cones_hit.empty());
  EXPECT_EQ(r.off_course, 0);
}

// the script moved from make_skidpad's frame to the frame of a file's timing line: the line's
// centre at the origin of the script's line, its normal towards the start heading as +x
Script in_gate_frame(const Script& script, const tracks::Gate& gate, const Pose2& start) {
  const Vec2 d = gate.left - gate.right;
  Vec2 f = Vec2(d.y(), -d.x()).normalized();
  if (f.dot(start.heading()) < 0.0) f = -f;
  const Vec2 mid = 0.5 * (gate.left + gate.right);
  const Pose2 frame = Pose2{mid.x(), mid.y(), std::atan2(f.y(), f.x())}.compose(
      Pose2{-tracks::kSkidpadStartToTimingLineM, 0.0, 0.0});
  return [=](double t) {
    const Motion m = script(t);
    return Motion{frame.compose(m.pose), m.speed_mps};
  };
}

TEST(Referee, SkidpadFilesCompleteWithFourLaps) {
  const VehicleParams car;
  const double circle_s = 2.0 * kPi * tracks::kSkidpadCentreDistanceM / 2.0 / 8.0;
  for (const char* file : {"pacsim/skidpad.yaml", "fssim/skidpad.yaml", "eufs/skidpad.csv"}) {
    SCOPED_TRACE(file);
    const Track track = tracks::read_track(std::string(CONESIM_TEST_DATA) + "/tracks/" + file);
    ASSERT_FALSE(track.timing_gates.empty());
    Referee referee(track, EventType::kSkidpad, car);
    run(referee, in_gate_frame(skidpad_run(8.0, false), track.timing_gates[0], track.start), 90.0,
        car);
    const RefereeResult& r = referee.result();
    EXPECT_TRUE(r.completed) << r.dnf_reason;
    EXPECT_EQ(r.laps, 4);
    EXPECT_NEAR(r.raw_time_s, circle_s, kStepS);
    EXPECT_EQ(r.off_course, 0);
  }
}

TEST(Referee, SkidpadLeftCircleFirstIsDnfWrongDirection) {
  const VehicleParams car;
  Referee referee(tracks::make_skidpad(), EventType::kSkidpad, car);
  run(referee, skidpad_run(8.0, true), 90.0, car);
  EXPECT_TRUE(referee.result().dnf_reason.starts_with("wrong direction at ("))
      << referee.result().dnf_reason;
  EXPECT_EQ(referee.result().laps, 0);
}

TEST(Referee, ATrackWithoutConesOrGatesGetsGatesAheadOfTheStart) {
  const VehicleParams car;
  Track track;
  track.start = {-0.3, 0.0, 0.0};
  Referee referee(track, EventType::kAcceleration, car);
  // the start gate 1 m ahead of the front wing, the finish 75 m on, the braking zone 75 m more
  const Script script = [&](double t) {
    return Motion{front_at(car.front_overhang_from_rear_axle_m - 0.3 + 20.0 * t, 0.0, 0.0, car),
                  20.0};
  };
  run(referee, script, 20.0, car);
  const RefereeResult& r = referee.result();
  EXPECT_EQ(r.laps, 1);
  ASSERT_EQ(r.lap_times_s.size(), 1u);
  EXPECT_NEAR(r.lap_times_s[0], 3.75, kStepS);
  EXPECT_TRUE(r.dnf_reason.starts_with("overran braking zone at (")) << r.dnf_reason;
}

TEST(Referee, UnusableParametersAreRejectedByName) {
  RefereeParams params;
  EXPECT_EQ(params.validate(), "");
  params.stuck_time_s = 0.0;
  EXPECT_NE(params.validate().find("stuck_time_s"), std::string::npos);
  EXPECT_THROW(Referee(Oval::track(), EventType::kAutocross, VehicleParams{}, params),
               std::invalid_argument);
}

}  // namespace
}  // namespace conesim::sim
