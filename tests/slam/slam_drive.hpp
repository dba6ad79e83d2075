#pragma once
// An offline drive for the SLAM tests: a kinematic bicycle follows a track's centre line with
// pure pursuit; the vehicle sensors (IMU, wheel encoders, steering) and the detection-level cone
// sensor sample it on their own clocks; the odometry integrates between cone batches and a SLAM
// backend processes each batch. Everything a user would look at is scored against the truth by
// the same scorer the closed loop uses (sim/slam_score.hpp): map RMSE (no alignment),
// trajectory RMSE, association accuracy, loop closures; and the update times.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <functional>
#include <map>
#include <numbers>
#include <vector>

#include "core/time.hpp"
#include "sensors/cone_sensor.hpp"
#include "sensors/vehicle_sensors.hpp"
#include "sim/slam_score.hpp"
#include "slam/backend.hpp"
#include "slam/odometry.hpp"
#include "tracks/track.hpp"
#include "vehicle_models/kinematics.hpp"

namespace conesim::slam::testing {

using core::Pose2;
using core::Vec2;

/// How the drive is run.
struct DriveParams {
  double speed_mps = 9.0;
  /// The car stands this long at the start (the odometry learns the gyro bias), then
  /// accelerates at accel_mps2.
  double standstill_s = 1.0;
  double accel_mps2 = 4.0;
  double laps = 2.0;
  double step_s = 0.001;
  double lookahead_m = 5.0;
  double wheelbase_m = 1.53;
  double wheel_radius_m = 0.23;
  double track_width_m = 1.2;
  /// Constant gyro bias added on top of the IMU model's own, rad/s.
  double extra_gyro_bias_rps = 0.002;
  uint64_t seed = 1;
  sensors::ConeSensorConfig cone_sensor;
  /// The odometry's noise model and motion model (its geometry comes from the fields above).
  OdometryConfig odometry;
  /// A known map given to the backend after reset (localisation only), empty for SLAM.
  std::vector<core::MapCone> prior_map;
  /// Print a line every 10 batches (error, associations, map size, update time).
  bool trace = false;
  /// Called after every batch's update with the batch's number (from 1), when set.
  std::function<void(int)> after_batch;
};

/// What the drive measured.
struct DriveResult {
  double lap_m = 0.0;
  double travel_m = 0.0;
  int batches = 0;
  /// Final map against the true cones (the scorer's one-to-one match within 1 m): RMSE over the
  /// matched, the counts; missed: true cones once in the cone sensor's view that the map lacks.
  double map_rmse_m = 0.0;
  int map_matched = 0;
  int map_spurious = 0;
  int map_missed = 0;
  /// Online estimate against the true pose at each batch (no alignment).
  double ate_rmse_m = 0.0;
  double yaw_rmse_rad = 0.0;
  double max_position_error_m = 0.0;
  /// The same over the batches in the localisation phase only (after the loop closed).
  double ate_localisation_rmse_m = 0.0;
  /// Associations checked against the labels by the scorer (a match is right when the
  /// landmark's majority true cone so far is the observation's); rejected ones counted apart.
  int da_correct = 0;
  int da_wrong = 0;
  int da_rejected = 0;
  double da_correct_fraction = 0.0;
  /// Loop closures and the true distance driven at the first one.
  int loop_closures = 0;
  double loop_closure_travel_m = -1.0;
  bool localising_at_end = false;
  /// Update time per batch, ms.
  double update_ms_median = 0.0;
  double update_ms_p99 = 0.0;
  double update_ms_max = 0.0;
  /// The same in thread CPU time (what the update costs, without the time other processes
  /// take the core away), ms.
  double update_cpu_ms_median = 0.0;
  double update_cpu_ms_p99 = 0.0;
  /// The true pose at each batch's stamp.
  std::map<core::TimeUs, Pose2> truth;
};

/// Position RMSE of a trajectory (pose per stamp) against the truth at the same stamps.
inline double trajectory_rmse_m(const std::vector<core::TimeUs>& stamps,
                                const std::vector<Pose2>& poses,
                                const std::map<core::TimeUs, Pose2>& truth) {
  double sq = 0.0;
  int n = 0;
  for (size_t i = 0; i < stamps.size(); ++i) {
    const auto it = truth.find(stamps[i]);
    if (it == truth.end()) continue;
    sq += (poses[i].position() - it->second.position()).squaredNorm();
    ++n;
  }
  return std::sqrt(sq / std::max(1, n));
}

/// Index of the closest centre-line point.
inline size_t closest_index(const std::vector<Vec2>& line, const Vec2& p) {
  size_t best = 0;
  double best_d = 1e300;
  for (size_t i = 0; i < line.size(); ++i) {
    const double d = (line[i] - p).squaredNorm();
    if (d < best_d) {
      best_d = d;
      best = i;
    }
  }
  return best;
}

/// One line of a drive's figures on stdout (the test logs show what a run reached).
inline void print(const char* what, const DriveResult& r) {
  std::printf(
      "%s: lap %.0f m, %d batches | map RMSE %.3f m (%d matched, %d spurious, %d missed) | ATE "
      "%.3f m (max %.3f) | DA %.3f %% (%d wrong) | loop closures %d at %.0f m | update median "
      "%.3f ms, p99 %.3f ms\n",
      what, r.lap_m, r.batches, r.map_rmse_m, r.map_matched, r.map_spurious, r.map_missed,
      r.ate_rmse_m, r.max_position_error_m, 100.0 * r.da_correct_fraction, r.da_wrong,
      r.loop_closures, r.loop_closure_travel_m, r.update_ms_median, r.update_ms_p99);
}

/// Drives the track with the backend in the loop (the backend never steers: the car follows
/// the true centre line) and scores the backend.
inline DriveResult drive(const tracks::Track& track, Backend& backend, const DriveParams& p) {
  DriveResult r;
  const std::vector<Vec2>& line = track.centre_line;
  for (size_t i = 0; i < line.size(); ++i)
    r.lap_m += (line[(i + 1) % line.size()] - line[i]).norm();

  // the sensors, each with its own seed
  sensors::ImuConfig imu_config;
  sensors::Imu imu(imu_config, core::derive_seed(p.seed, 1));
  sensors::WheelEncoders wheels({}, core::derive_seed(p.seed, 2));
  sensors::SteeringSensor steering({}, core::derive_seed(p.seed, 3));
  sensors::ConeSensor cone_sensor(p.cone_sensor, core::derive_seed(p.seed, 4));
  OdometryConfig odo_config = p.odometry;
  odo_config.wheelbase_m = p.wheelbase_m;
  odo_config.wheel_radius_m = p.wheel_radius_m;
  Odometry odometry(odo_config);

  // the car starts at rest at the start pose, and the map frame is the track frame
  Pose2 pose = track.start;
  backend.reset(pose, 0);
  if (!p.prior_map.empty()) backend.set_prior_map(p.prior_map);
  odometry.reset(0);
  const core::TimeUs step_us = core::from_seconds(p.step_s);
  const core::TimeUs imu_us = imu_config.timing.period_us();
  const core::TimeUs wheel_us = wheels.config().timing.period_us();
  const core::TimeUs steer_us = steering.config().timing.period_us();
  const core::TimeUs cone_us = p.cone_sensor.timing.period_us();
  std::array<double, 4> wheel_angle{};
  size_t target = closest_index(line, pose.position());

  // the closed loop's scorer, with the cone sensor's view
  const sim::PerceptionView view{p.cone_sensor.mount_x_m, p.cone_sensor.min_range_m,
                                 p.cone_sensor.max_range_m, p.cone_sensor.fov_deg};
  sim::SlamScorer scorer(track, view);
  if (!p.prior_map.empty()) scorer.set_prior_map_identities();
  std::map<int, int> landmark_first_truth;
  std::vector<double> update_ms, update_cpu_ms;
  double sq_pos = 0.0, sq_yaw = 0.0, sq_loc = 0.0;
  int n_loc = 0;

  for (core::TimeUs t = step_us; r.travel_m < p.laps * r.lap_m; t += step_us) {
    // stand, accelerate, then hold the speed
    const double elapsed_s = core::to_seconds(t) - p.standstill_s;
    const double speed = std::clamp(elapsed_s * p.accel_mps2, 0.0, p.speed_mps);

    // pure pursuit on the true centre line
    while ((line[target] - pose.position()).norm() < p.lookahead_m)
      target = (target + 1) % line.size();
    const Vec2 local = pose.inverse_transform(line[target]);
    const double curvature = 2.0 * local.y() / local.squaredNorm();
    const double steer = std::clamp(std::atan(curvature * p.wheelbase_m), -0.47, 0.47);
    const double yaw_rate = vehicle_models::bicycle_yaw_rate(speed, steer, p.wheelbase_m);
    pose = vehicle_models::bicycle_step(pose, speed, steer, p.wheelbase_m, p.step_s);
    r.travel_m += speed * p.step_s;

    // what the vehicle sensors measure
    const double half_track = 0.5 * p.track_width_m;
    const std::array<double, 4> wheel_speed = {
        speed - yaw_rate * half_track, speed + yaw_rate * half_track, speed - yaw_rate * half_track,
        speed + yaw_rate * half_track};
    for (int w = 0; w < 4; ++w) wheel_angle[w] += wheel_speed[w] / p.wheel_radius_m * p.step_s;
    sensors::VehicleSensorTruth truth;
    truth.stamp = t;
    truth.vehicle_pose.position = {pose.x, pose.y, 0.0};
    truth.vehicle_pose.orientation = Eigen::AngleAxisd(pose.yaw, Eigen::Vector3d::UnitZ());
    truth.angular_rate_rps = {0.0, 0.0, yaw_rate};
    truth.specific_force_mps2 = {0.0, speed * yaw_rate, 9.81};
    truth.wheel_angle_rad = wheel_angle;
    truth.steer_rad = steer;
    if (t % imu_us == 0) {
      core::ImuSample s = imu.sample(truth);
      s.gyro_rps.z() += p.extra_gyro_bias_rps;
      odometry.add_imu(s);
    }
    if (t % wheel_us == 0) odometry.add_wheel_speeds(wheels.sample(truth));
    if (t % steer_us == 0) odometry.add_steering(steering.sample(truth));
    if (t % 50'000 == 0) scorer.note_cones_in_view(pose);
    if (t % cone_us != 0) continue;

    // one cone batch: odometry delta, observations, SLAM update (timed)
    auto [observations, labels] = cone_sensor.sample(track, pose, t, nullptr);
    SlamInput input{odometry.take_delta(t), observations, {}};
    const auto start = std::chrono::steady_clock::now();
    const double cpu_start = core::thread_cpu_ms();
    backend.process(input);
    update_cpu_ms.push_back(core::thread_cpu_ms() - cpu_start);
    const auto end = std::chrono::steady_clock::now();
    update_ms.push_back(std::chrono::duration<double, std::milli>(end - start).count());
    ++r.batches;
    r.truth[t] = pose;
    if (p.after_batch) p.after_batch(r.batches);

    // score the online estimate and log the associations
    const core::Estimate e = backend.estimate();
    const double err = (e.pose.position() - pose.position()).norm();
    sq_pos += err * err;
    if (e.phase == core::SlamPhase::kLocalisation) {
      sq_loc += err * err;
      ++n_loc;
    }
    sq_yaw += std::pow(core::normalize_angle(e.pose.yaw - pose.yaw), 2);
    r.max_position_error_m = std::max(r.max_position_error_m, err);
    const auto& associations = backend.last_associations();
    {
      sim::SlamScorer::Update u;
      u.stamp = t;
      u.true_pose = pose;
      u.observations = &observations;
      u.true_ids = &labels.cone_id;
      u.estimate = &e;
      u.associations = &associations;
      u.loop_closures = backend.loop_closures();
      u.wall_ms = update_ms.back();
      u.cpu_ms = update_cpu_ms.back();
      u.association_us = backend.last_association_us();
      scorer.score(u);
    }
    if (p.trace && r.batches % 10 == 0) {
      int matched = 0, created = 0, rejected = 0;
      for (const Association& a : associations) {
        (a.kind == Association::Kind::kMatched ? matched
         : a.kind == Association::Kind::kNew   ? created
                                               : rejected)++;
      }
      std::printf(
          "batch %d at %.0f m: error %.3f m, yaw %.4f rad | %d matched, %d new, %d "
          "rejected | map %zu | %.2f ms\n",
          r.batches, r.travel_m, err, core::normalize_angle(e.pose.yaw - pose.yaw), matched,
          created, rejected, e.map.size(), update_ms.back());
    }
    for (size_t i = 0; i < associations.size(); ++i) {
      const Association& a = associations[i];
      if (a.kind == Association::Kind::kRejected) {
        ++r.da_rejected;
        continue;
      }
      if (p.trace && !landmark_first_truth.count(a.landmark_id))
        landmark_first_truth[a.landmark_id] = labels.cone_id[i];
      if (p.trace && landmark_first_truth[a.landmark_id] != labels.cone_id[i])
        std::printf("  mixed: batch %d at %.0f m, landmark %d (first true %d) got true %d%s\n",
                    r.batches, r.travel_m, a.landmark_id, landmark_first_truth[a.landmark_id],
                    labels.cone_id[i], a.kind == Association::Kind::kNew ? " new" : "");
    }
    if (backend.loop_closures() > 0 && r.loop_closure_travel_m < 0.0)
      r.loop_closure_travel_m = r.travel_m;
  }

  // associations and the map by the scorer
  const core::Estimate e = backend.estimate();
  const nlohmann::json m = scorer.metrics(e);
  r.da_correct = scorer.da_correct();
  r.da_wrong = scorer.da_wrong();
  r.da_correct_fraction =
      m["da_correct_fraction"].is_null() ? 0.0 : m["da_correct_fraction"].get<double>();
  r.map_rmse_m = m["map_rmse_m"].is_null() ? 0.0 : m["map_rmse_m"].get<double>();
  r.map_matched = m["map_matched"].get<int>();
  r.map_spurious = m["map_spurious"].get<int>();
  r.map_missed = m["map_missed"].get<int>();
  r.ate_rmse_m = std::sqrt(sq_pos / std::max(1, r.batches));
  r.yaw_rmse_rad = std::sqrt(sq_yaw / std::max(1, r.batches));
  r.ate_localisation_rmse_m = std::sqrt(sq_loc / std::max(1, n_loc));
  r.loop_closures = backend.loop_closures();
  r.localising_at_end = e.phase == core::SlamPhase::kLocalisation;

  // timing
  std::sort(update_ms.begin(), update_ms.end());
  if (!update_ms.empty()) {
    r.update_ms_median = update_ms[update_ms.size() / 2];
    r.update_ms_p99 = update_ms[std::min(update_ms.size() - 1, update_ms.size() * 99 / 100)];
    r.update_ms_max = update_ms.back();
    std::sort(update_cpu_ms.begin(), update_cpu_ms.end());
    r.update_cpu_ms_median = update_cpu_ms[update_cpu_ms.size() / 2];
    r.update_cpu_ms_p99 =
        update_cpu_ms[std::min(update_cpu_ms.size() - 1, update_cpu_ms.size() * 99 / 100)];
  }
  return r;
}

}  // namespace conesim::slam::testing
