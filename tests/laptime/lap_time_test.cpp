#include "laptime/lap_time.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>
#include <vector>

#include "tracks/fsg_layouts.hpp"
#include "tracks/generator.hpp"
#include "tracks/io.hpp"

namespace conesim::laptime {
namespace {

using tracks::EventType;
using tracks::Track;
using vehicle_models::VehicleParams;

// the smallest distance from p to a closed polyline
double distance_to(const Vec2& p, const std::vector<Vec2>& poly) {
  double best = 1e9;
  for (size_t i = 0; i < poly.size(); ++i)
    best = std::min(best, core::distance_to_segment(p, poly[i], poly[(i + 1) % poly.size()]));
  return best;
}

TEST(LapTimeBound, SkidpadIsOneLapOfTheTightestCircle) {
  const VehicleParams car;
  const LapTimeBound b = lap_time_bound(tracks::make_skidpad(), car);
  ASSERT_TRUE(b.usable) << b.message;
  EXPECT_EQ(b.event, EventType::kSkidpad);
  // the inner cone ring plus half the car and a cone's radius
  const double r = tracks::kSkidpadInnerConeRadiusM + 0.5 * car.width_m + 0.114;
  const double v = cornering_speed_mps(PerformanceEnvelope::of(car), 1.0 / r);
  EXPECT_NEAR(b.line_length_m, 2.0 * std::numbers::pi * r, 0.05);
  EXPECT_NEAR(b.lap_time_s, 2.0 * std::numbers::pi * r / v, 0.01);
  // top FS cars: 4.5-5 s a lap
  EXPECT_GT(b.lap_time_s, 4.0);
  EXPECT_LT(b.lap_time_s, 5.5);
}

TEST(LapTimeBound, AccelerationIsAStandingStartOverTheSeventyFiveMetres) {
  const VehicleParams car;
  const LapTimeBound b = lap_time_bound(tracks::make_acceleration(), car);
  ASSERT_TRUE(b.usable) << b.message;
  EXPECT_EQ(b.event, EventType::kAcceleration);
  EXPECT_NEAR(b.line_length_m, 75.0, 0.5);
  // the start 0.3 m behind the line gives the car a little speed at the line
  EXPECT_LT(b.speed_mps.front(), 5.0);
  EXPECT_GT(b.lap_time_s, 3.0);
  EXPECT_LT(b.lap_time_s, 4.5);
  // less grip, no faster
  LapTimeOptions low;
  low.grip_fraction = 0.6;
  EXPECT_GT(lap_time_bound(tracks::make_acceleration(), car, low).lap_time_s, b.lap_time_s);
}

TEST(LapTimeBound, SharedCircuitsGiveSaneLapsOnALineInsideTheLanes) {
  // FS trackdrive: top cars average 12-18 m/s on 200-500 m laps; the bound, at the full grip on
  // the best line, sits at or a little above the top of that
  const VehicleParams car;
  for (const char* name :
       {"pacsim/FSG19.yaml", "pacsim/FSG21.yaml", "pacsim/FSE23.yaml", "fssim/FSG.yaml",
        "fssim/FSI.yaml", "epfl/fsds_competition_1_cones.csv"}) {
    SCOPED_TRACE(name);
    const Track t = tracks::read_track(std::string(CONESIM_TEST_DATA) + "/tracks/" + name);
    LapTimeOptions options;
    options.event = EventType::kTrackdrive;
    const LapTimeBound b = lap_time_bound(t, car, options);
    ASSERT_TRUE(b.usable) << b.message;
    const double mean = b.line_length_m / b.lap_time_s;
    std::printf("%s: bound %.2f s over %.1f m, mean %.1f m/s, %.1f-%.1f m/s\n", name, b.lap_time_s,
                b.line_length_m, mean, b.min_speed_mps, b.top_speed_mps);
    EXPECT_GT(mean, 12.0);
    EXPECT_LT(mean, 22.0);
    EXPECT_LT(b.top_speed_mps, PerformanceEnvelope::of(car).top_speed_mps() + 1e-6);

    // the line keeps clear of both boundaries (the clearance less the chord and step error)
    const std::vector<Vec2> left = t.lane_points(t.left_lane);
    const std::vector<Vec2> right = t.lane_points(t.right_lane);
    for (const Vec2& p : b.line) {
      EXPECT_GT(distance_to(p, left), 0.5 * car.width_m);
      EXPECT_GT(distance_to(p, right), 0.5 * car.width_m);
    }

    // and it beats the middle of the track
    LapTimeOptions middle = options;
    middle.clearance_m = 20.0;  // no room: the line stays half-way between the lanes
    EXPECT_LT(b.lap_time_s, lap_time_bound(t, car, middle).lap_time_s);
  }
}

TEST(LapTimeBound, AutocrossFromStandstillIsSlowerThanAFlyingLap) {
  const Track t = tracks::generate_circuit(3);
  LapTimeOptions flying, standing;
  flying.event = EventType::kTrackdrive;
  standing.event = EventType::kAutocross;
  const LapTimeBound f = lap_time_bound(t, VehicleParams{}, flying);
  const LapTimeBound s = lap_time_bound(t, VehicleParams{}, standing);
  ASSERT_TRUE(f.usable && s.usable);
  EXPECT_GT(s.lap_time_s, f.lap_time_s);
  EXPECT_LT(s.lap_time_s, f.lap_time_s + 2.0);  // 6 m of run-up costs about a second
  EXPECT_NEAR(s.line_length_m, f.line_length_m, 1e-9);
}

}  // namespace
}  // namespace conesim::laptime
