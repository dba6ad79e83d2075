#pragma once
// A closed loop for the driver tests: a kinematic bicycle with a steering rate limit and a
// lagged, limited acceleration drives a Track, with perfect perception (cones within range and
// field of view, in the vehicle frame) and a perfect estimate (true pose in the map frame plus
// every cone seen so far). It measures what a user notices: cones hit, clearance to the cones,
// distance from the centre line, timing-gate crossings, where the car stops.

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <vector>

#include "control/driver.hpp"
#include "control/pure_pursuit.hpp"
#include "tracks/track.hpp"
#include "tracks/track_area.hpp"
#include "vehicle_models/kinematics.hpp"

namespace conesim::control::testing {

using core::Pose2;
using core::Vec2;

/// The simulated car and sensor.
struct LoopParams {
  /// Physics step and driver period, seconds.
  double dt_s = 0.005;
  double driver_period_s = 0.02;
  /// Steering actuator: rate limit rad/s; acceleration: first-order lag s, and limits m/s^2.
  double steer_rate_rps = 2.5;
  /// The turning follows the steering with this first-order lag, s: the MuJoCo car's tyres
  /// build their side force after the wheels turn. Fitted to the MuJoCo car's path after a
  /// 0.03 rad step of the steering at 8-20 m/s: with 0.04 s within 0.021 m over 1 s, without a
  /// lag 0.04-0.26 m off (nearer the grip limit, 0.08 rad at 16 m/s, the best fit is 0.06 s).
  /// Without it the driver's steering preview, set on the MuJoCo car, made the bicycle cut
  /// inside every bend.
  double steer_lag_s = 0.04;
  double accel_lag_s = 0.1;
  double max_accel_mps2 = 10.0;
  double max_decel_mps2 = 12.0;
  /// Footprint about the rear axle: front wing ahead, rear end behind, half width, metres.
  double front_m = 2.25;
  double rear_m = 0.65;
  double half_width_m = 0.7;
  /// Perception: range and half field of view.
  double range_m = 20.0;
  double half_fov_rad = 100.0 * std::numbers::pi / 180.0;
  /// Imperfect perception, by cone id: every n-th cone is never seen, every m-th is seen with
  /// the other boundary colour (blue and yellow swapped); 0 turns either off.
  int missing_every = 0;
  int recolour_every = 0;
  /// Yaw rate over the kinematic one at a steering angle (the MuJoCo car's anti-Ackermann
  /// loss, as the driver knows it); empty: kinematic.
  std::vector<std::pair<double, double>> yaw_gain = VehicleGeometry{}.yaw_gain;
  /// An error of the estimate's map: the offset (track frame, metres) of the cone at this true
  /// position at this time, as a SLAM map before its loop closure has it; empty: none.
  std::function<Vec2(double, const Vec2&)> map_error;
  /// Give up after this much simulated time, seconds.
  double max_time_s = 600.0;
  /// Called after each driver update with the time, the true pose and the driver's status
  /// (for debugging a run); may be empty.
  std::function<void(double, const Pose2&, const DriverStatus&)> on_update;
};

/// What one run did.
struct LoopResult {
  bool finished = false;
  double time_s = 0.0;
  int laps_counted = 0;
  /// Distinct cones whose base the footprint touched.
  int cones_hit = 0;
  /// Smallest distance between the footprint and a cone base, metres.
  double min_clearance_m = std::numeric_limits<double>::infinity();
  /// Largest distance of the car's middle point from the track's centre line, metres.
  double max_deviation_m = 0.0;
  /// Where that was (track frame) and how far the car had gone, seconds.
  Vec2 max_deviation_at = Vec2::Zero();
  double max_deviation_time_s = 0.0;
  /// Farthest a corner of the footprint went outside the boundaries (the lanes' polylines, as
  /// the referee judges them), metres; 0 when the whole car stayed between the lanes.
  double max_outside_m = 0.0;
  /// Where that was (track frame).
  Vec2 max_outside_at = Vec2::Zero();
  double max_speed_mps = 0.0;
  /// Times the front wing crossed each timing gate, seconds.
  std::vector<std::vector<double>> gate_crossings;
  /// Final rear-axle pose, track frame.
  Pose2 final_pose;
};

/// Distance from p to the rectangle [x0, x1] x [-hw, hw].
inline double distance_to_box(const Vec2& p, double x0, double x1, double hw) {
  const double dx = std::max({x0 - p.x(), 0.0, p.x() - x1});
  const double dy = std::max(std::abs(p.y()) - hw, 0.0);
  return std::hypot(dx, dy);
}

/// Distance from p to a polyline (closed: with the closing segment).
inline double distance_to_polyline(const Vec2& p, const std::vector<Vec2>& line, bool closed) {
  double best = std::numeric_limits<double>::infinity();
  const size_t n = line.size();
  for (size_t i = 0; i + 1 < n + (closed ? 1 : 0); ++i)
    best = std::min(best, core::distance_to_segment(p, line[i], line[(i + 1) % n]));
  return best;
}

/// Drives the event on the track: the car starts at rest with its front wing at track.start;
/// the map frame is the car's start pose. `prior_map` (track frame) goes to the driver in the map
/// frame.
inline LoopResult run_loop(const tracks::Track& track, core::EventType event,
                           const DriverParams& params, const LoopParams& loop = {},
                           const std::vector<core::MapCone>& prior_track_frame = {}) {
  // the start: rear axle behind the front wing; the map frame sits there
  VehicleGeometry vehicle;
  vehicle.rear_axle_to_front_m = loop.front_m;
  vehicle.rear_axle_to_back_m = loop.rear_m;
  vehicle.width_m = 2.0 * loop.half_width_m;
  vehicle.yaw_gain = loop.yaw_gain;
  Pose2 pose = track.start.compose({-loop.front_m, 0.0, 0.0});
  const Pose2 map_origin = pose;
  std::vector<core::MapCone> prior;
  for (core::MapCone c : prior_track_frame) {
    c.position = map_origin.inverse_transform(c.position);
    prior.push_back(c);
  }
  Driver driver(event, params, vehicle, prior);

  const tracks::TrackArea area = tracks::TrackArea::of(track);
  LoopResult result;
  result.gate_crossings.resize(track.timing_gates.size());
  std::vector<bool> seen(track.cones.size(), false), hit(track.cones.size(), false);
  std::vector<core::MapCone> map;
  // `wheels`: the steering the turning follows (lagged); `turning`: the single-track angle it
  // turns on (with the yaw-gain loss)
  double v = 0.0, steer = 0.0, wheels = 0.0, turning = 0.0, accel = 0.0;
  core::VehicleCommand cmd;
  const int steps_per_driver =
      std::max(1, static_cast<int>(std::lround(loop.driver_period_s / loop.dt_s)));
  const int max_steps = static_cast<int>(loop.max_time_s / loop.dt_s);
  for (int step = 0; step < max_steps; ++step) {
    const double t = step * loop.dt_s;

    // the driver: perception of the cones in view, the estimate in the map frame
    if (step % steps_per_driver == 0) {
      DriverInput in;
      in.observations.stamp = static_cast<core::TimeUs>(std::llround(t * 1e6));
      for (size_t i = 0; i < track.cones.size(); ++i) {
        const tracks::Cone& cone = track.cones[i];
        const Vec2 local = pose.inverse_transform(cone.position);
        if (local.norm() > loop.range_m ||
            std::abs(std::atan2(local.y(), local.x())) > loop.half_fov_rad)
          continue;
        if (loop.missing_every > 0 && cone.id % loop.missing_every == loop.missing_every / 2)
          continue;
        core::ConeClass cls = cone.cls;
        if (loop.recolour_every > 0 && cone.id % loop.recolour_every == 1) {
          if (cls == core::ConeClass::kBlue)
            cls = core::ConeClass::kYellow;
          else if (cls == core::ConeClass::kYellow)
            cls = core::ConeClass::kBlue;
        }
        in.observations.cones.push_back({local, cls, Eigen::Matrix2d::Identity() * 0.01, -1});
        if (!seen[i]) {
          seen[i] = true;
          map.push_back({cone.id, cls, map_origin.inverse_transform(track.cones[i].position),
                         Eigen::Matrix2d::Identity() * 0.01});
        }
      }
      in.estimate.stamp = in.observations.stamp;
      in.estimate.pose = map_origin.inverse().compose(pose);
      in.estimate.speed_mps = v;
      in.estimate.yaw_rate_rps = vehicle_models::bicycle_yaw_rate(v, turning, vehicle.wheelbase_m);
      in.estimate.map = map;
      if (loop.map_error)
        for (core::MapCone& c : in.estimate.map) {
          const Vec2 truth = map_origin.transform(c.position);
          c.position = map_origin.inverse_transform(truth + loop.map_error(t, truth));
        }
      cmd = driver.update(in);
      if (loop.on_update) loop.on_update(t, pose, driver.status());
      result.laps_counted = driver.status().laps_counted;
      if (driver.status().finished && v <= 1e-9) {
        result.finished = true;
        break;
      }
    }

    // actuators: rate-limited steering, lagged and limited acceleration, a held stop
    const double max_dsteer = loop.steer_rate_rps * loop.dt_s;
    steer +=
        std::clamp(std::clamp(cmd.steer_rad, -vehicle.max_steer_rad, vehicle.max_steer_rad) - steer,
                   -max_dsteer, max_dsteer);
    const double wanted =
        cmd.hold_stopped ? -loop.max_decel_mps2
                         : std::clamp(cmd.accel_mps2, -loop.max_decel_mps2, loop.max_accel_mps2);
    accel += (wanted - accel) * std::min(1.0, loop.dt_s / loop.accel_lag_s);

    // motion
    const Vec2 front_before = pose.transform({loop.front_m, 0.0});
    wheels += (steer - wheels) * std::min(1.0, loop.dt_s / std::max(loop.steer_lag_s, 1e-9));
    turning = std::atan(std::tan(wheels) * yaw_gain_at(loop.yaw_gain, wheels));
    pose = vehicle_models::bicycle_step(pose, v, turning, vehicle.wheelbase_m, loop.dt_s);
    v = std::max(0.0, v + accel * loop.dt_s);
    result.max_speed_mps = std::max(result.max_speed_mps, v);
    const Vec2 front_after = pose.transform({loop.front_m, 0.0});

    // referee: gates, cones against the footprint, distance from the centre line
    for (size_t g = 0; g < track.timing_gates.size(); ++g)
      if (core::segments_intersect(front_before, front_after, track.timing_gates[g].left,
                                   track.timing_gates[g].right))
        result.gate_crossings[g].push_back(t + loop.dt_s);
    for (size_t i = 0; i < track.cones.size(); ++i) {
      const Vec2 local = pose.inverse_transform(track.cones[i].position);
      if (local.squaredNorm() > 36.0) continue;
      const double clearance =
          distance_to_box(local, -loop.rear_m, loop.front_m, loop.half_width_m) -
          0.5 * core::cone_size(track.cones[i].cls).base_m;
      result.min_clearance_m = std::min(result.min_clearance_m, clearance);
      if (clearance <= 0.0 && !hit[i]) {
        hit[i] = true;
        ++result.cones_hit;
      }
    }
    if (!area.empty()) {
      for (const Vec2& corner :
           {Vec2(loop.front_m, loop.half_width_m), Vec2(loop.front_m, -loop.half_width_m),
            Vec2(-loop.rear_m, loop.half_width_m), Vec2(-loop.rear_m, -loop.half_width_m)}) {
        const Vec2 p = pose.transform(corner);
        if (area.contains(p)) continue;
        const double outside = area.nearest_boundary(p)->distance_m;
        if (outside > result.max_outside_m) {
          result.max_outside_m = outside;
          result.max_outside_at = p;
        }
      }
    }
    if (!track.centre_line.empty()) {
      const Vec2 middle = pose.transform({0.5 * (loop.front_m - loop.rear_m), 0.0});
      const double deviation = distance_to_polyline(middle, track.centre_line, track.closed);
      if (deviation > result.max_deviation_m) {
        result.max_deviation_m = deviation;
        result.max_deviation_at = middle;
        result.max_deviation_time_s = t;
      }
    }
    result.time_s = t + loop.dt_s;
  }
  result.final_pose = pose;
  return result;
}

}  // namespace conesim::control::testing
