// Tests of the LiDAR cone detector on real sweeps of a generated circuit, scored against the
// labels: the cones within reach are found, nothing else is, their positions are cm-accurate
// and their colours right, at rest and at speed (where de-skew matters), level or pitched.

#include "slam/frontend/lidar_cone_detector.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>
#include <set>
#include <string>
#include <vector>

#include "core/clutter.hpp"
#include "sdk/builtin/lidar_frontend.hpp"
#include "sensors/lidar.hpp"
#include "sensors/lidar_config.hpp"
#include "sensors/pose_history.hpp"
#include "tracks/generator.hpp"
#include "tracks/scenery.hpp"

namespace conesim::slam::frontend {
namespace {

using core::ConeClass;
using core::Pose2;
using core::Pose3;
using core::TimeUs;
using core::Vec2;

constexpr double kDeg = std::numbers::pi / 180.0;
constexpr TimeUs kSweepStart = 1'000'000;

// the vehicle pose dt after `start` for constant speed and yaw rate (the truth the sweep is cast
// from; written independently of the detector's de-skew)
Pose2 along_arc(const Pose2& start, double speed, double yaw_rate, double dt) {
  const double steps = 1000.0;
  Pose2 p = start;
  for (int k = 0; k < static_cast<int>(steps); ++k) {  // fine Euler: independent of the closed form
    const double h = dt / steps;
    p.x += speed * h * std::cos(p.yaw + 0.5 * yaw_rate * h);
    p.y += speed * h * std::sin(p.yaw + 0.5 * yaw_rate * h);
    p.yaw += yaw_rate * h;
  }
  return p;
}

Pose3 to_pose3(const Pose2& p, double pitch = 0.0, double roll = 0.0) {
  Pose3 q;
  q.position = {p.x, p.y, 0.0};
  q.orientation = Eigen::AngleAxisd(p.yaw, Eigen::Vector3d::UnitZ()) *
                  Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                  Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX());
  return q;
}

// How one drive condition is scored: counts and sums over many sweeps.
struct Score {
  int true_within_15 = 0;     // cones within 15 m of the sensor
  int visible_within_15 = 0;  // ... hit by >= 3 returns above 5 cm
  int found_visible = 0;      // visible ones detected
  int found_within_15 = 0;    // any within 15 m detected
  int detections_within_15 = 0;
  int true_detections_within_15 = 0;
  int coloured_within_10 = 0;  // detected cones within 10 m
  int colour_right_within_10 = 0;
  int colour_unknown_within_10 = 0;
  std::array<double, 4> sq_error{};  // per 5 m band of range
  std::array<int, 4> in_band{};
  std::array<double, 4> sigma_across{};  // sum over detections of the reported sigma across
  double sq_error_side = 0.0;            // cones more to the side than ahead (|bearing| > 45 deg)
  int side = 0;
  int within_3_sigma = 0;  // errors inside the reported covariance's 3-sigma ellipse
  int errors = 0;
  std::vector<double> ms;

  double recall_visible() const { return double(found_visible) / visible_within_15; }
  double recall_all() const { return double(found_within_15) / true_within_15; }
  double precision() const { return double(true_detections_within_15) / detections_within_15; }
  double colour() const { return double(colour_right_within_10) / coloured_within_10; }
  double rmse_band(int b) const { return in_band[b] ? std::sqrt(sq_error[b] / in_band[b]) : 0.0; }
  double mean_sigma_across(int b) const { return in_band[b] ? sigma_across[b] / in_band[b] : 0.0; }
  double rmse_side() const { return std::sqrt(sq_error_side / side); }
  double rmse_within_15() const {
    return std::sqrt((sq_error[0] + sq_error[1] + sq_error[2]) /
                     (in_band[0] + in_band[1] + in_band[2]));
  }
  double median_ms() {
    std::sort(ms.begin(), ms.end());
    return ms[ms.size() / 2];
  }
  void print(const char* name) {
    std::printf(
        "[%s] recall within 15 m: %.3f of visible (%d/%d), %.3f of all (%d/%d); precision %.3f "
        "(%d/%d); colour within 10 m %.3f (%d/%d, %d unknown)\n  RMSE by band 0-5/5-10/10-15/"
        "15-20 m: %.1f/%.1f/%.1f/%.1f cm (n %d/%d/%d/%d); side cones %.1f cm; within 3 sigma "
        "%.3f; median %.2f ms per sweep\n",
        name, recall_visible(), found_visible, visible_within_15, recall_all(), found_within_15,
        true_within_15, precision(), true_detections_within_15, detections_within_15, colour(),
        colour_right_within_10, coloured_within_10, colour_unknown_within_10, 100 * rmse_band(0),
        100 * rmse_band(1), 100 * rmse_band(2), 100 * rmse_band(3), in_band[0], in_band[1],
        in_band[2], in_band[3], 100 * rmse_side(), double(within_3_sigma) / errors, median_ms());
  }
};

// How the car moves through each sweep.
struct Drive {
  double speed_mps = 0.0;
  double yaw_rate_rps = 0.0;
  double pitch_rad = 0.0;
  double roll_rad = 0.0;
  bool deskew = true;
};

// Sweeps from `positions` poses of the circuit and scores the detections against the labels.
Score score_track(const tracks::Track& track, const std::vector<Pose2>& starts, const Drive& drive,
                  uint64_t seed = 1, LidarDetectorConfig config = {}) {
  const sensors::LidarConfig lidar_config;
  const sensors::Lidar lidar(lidar_config, track);
  config.deskew = drive.deskew;
  const LidarConeDetector detector(config, lidar_config.mount);
  std::map<int, const tracks::Cone*> cone_by_id;
  for (const tracks::Cone& cone : track.cones) cone_by_id[cone.id] = &cone;

  core::Rng rng(seed);
  Score score;
  for (const Pose2& start : starts) {
    // the poses every 1 ms over the sweep and a little after
    sensors::PoseHistory poses(core::kUsPerSecond);
    for (TimeUs t = kSweepStart; t <= kSweepStart + 120'000; t += 1000)
      poses.push(t, to_pose3(along_arc(start, drive.speed_mps, drive.yaw_rate_rps,
                                       core::to_seconds(t - kSweepStart)),
                             drive.pitch_rad, drive.roll_rad));
    const sensors::LidarScan scan = lidar.sweep(kSweepStart, poses, rng);

    const auto t0 = std::chrono::steady_clock::now();
    const LidarDetections found =
        detector.detect(scan.cloud, {drive.speed_mps, drive.yaw_rate_rps});
    score.ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());

    // the truth at the detections' stamp: vehicle and sensor pose, cones in the vehicle frame
    const Pose3 vehicle_end = poses.at(found.stamp);
    const Pose2 vehicle2 = vehicle_end.planar();
    const Vec2 sensor_xy = lidar.sensor_pose(vehicle_end).position.head<2>();

    // returns above 5 cm per cone (track frame, each from its own column's pose)
    std::map<int, int> raised_hits;
    for (size_t i = 0; i < scan.cloud.points.size(); ++i) {
      const int id = scan.labels.cone_id[i];
      if (id < 0) continue;
      const core::LidarPoint& p = scan.cloud.points[i];
      const Pose3 sensor =
          lidar.sensor_pose(poses.at(scan.cloud.stamp + core::from_seconds(p.time_offset_s)));
      if (sensor.transform(Eigen::Vector3d(p.x, p.y, p.z)).z() > 0.05) ++raised_hits[id];
    }

    // each detection's cone: the majority label of its points; the first one of a cone counts
    std::map<int, const LidarCone*> detection_of;
    for (const LidarCone& cone : found.cones) {
      std::map<int, int> votes;
      for (const int i : cone.point_indices) ++votes[scan.labels.cone_id[i]];
      const auto best = std::max_element(votes.begin(), votes.end(),
                                         [](auto& a, auto& b) { return a.second < b.second; });
      const bool real = best->first >= 0 && !detection_of.count(best->first);
      const double range =
          (cone.observation.position - vehicle2.inverse_transform(sensor_xy)).norm();
      if (range < 15.0) {
        ++score.detections_within_15;
        if (real) ++score.true_detections_within_15;
      }
      if (real) detection_of[best->first] = &cone;
    }

    // each true cone: found, visible, position error, colour
    for (const tracks::Cone& truth : track.cones) {
      const double range = (truth.position - sensor_xy).norm();
      if (range >= 20.0) continue;
      const auto it = detection_of.find(truth.id);
      const bool visible = raised_hits[truth.id] >= 3;
      if (range < 15.0) {
        ++score.true_within_15;
        if (visible) ++score.visible_within_15;
        if (it != detection_of.end()) {
          ++score.found_within_15;
          if (visible) ++score.found_visible;
        }
      }
      if (it == detection_of.end()) continue;
      const core::ConeObservation& seen = it->second->observation;
      const Vec2 expected = vehicle2.inverse_transform(truth.position);
      const Vec2 error = seen.position - expected;
      const int band = std::min(3, static_cast<int>(range / 5.0));
      score.sq_error[band] += error.squaredNorm();
      const Vec2 across = Vec2(-(expected - vehicle2.inverse_transform(sensor_xy)).y(),
                               (expected - vehicle2.inverse_transform(sensor_xy)).x())
                              .normalized();
      score.sigma_across[band] += std::sqrt(across.dot(seen.covariance * across));
      ++score.in_band[band];
      const Vec2 sensor_in_vehicle = vehicle2.inverse_transform(sensor_xy);
      const Vec2 line = expected - sensor_in_vehicle;
      if (std::abs(line.y()) > std::abs(line.x())) {
        score.sq_error_side += error.squaredNorm();
        ++score.side;
      }
      ++score.errors;
      if (error.dot(seen.covariance.ldlt().solve(error)) < 9.0) ++score.within_3_sigma;
      if (range < 10.0) {
        ++score.coloured_within_10;
        if (seen.cls == truth.cls) ++score.colour_right_within_10;
        if (seen.cls == ConeClass::kUnknown) ++score.colour_unknown_within_10;
      }
    }
  }
  return score;
}

// Poses along the centre line of a generated circuit (heading to the next point), plus the
// start pose (big orange cones ahead).
std::vector<Pose2> poses_along(const tracks::Track& track, int count) {
  std::vector<Pose2> poses{track.start};
  const size_t n = track.centre_line.size();
  for (int k = 0; k < count; ++k) {
    const size_t i = (static_cast<size_t>(k) * n) / static_cast<size_t>(count);
    const Vec2 a = track.centre_line[i], b = track.centre_line[(i + 1) % n];
    poses.push_back({a.x(), a.y(), std::atan2(b.y() - a.y(), b.x() - a.x())});
  }
  return poses;
}

// ---------------------------------------------------------------------------------------------
// configuration

TEST(LidarDetectorConfig, DefaultsAreValidAndValidateNamesTheBadKey) {
  EXPECT_EQ(LidarDetectorConfig{}.validate(), "");
  LidarDetectorConfig c;
  c.cluster_distance_m = 0.0;
  EXPECT_EQ(c.validate().rfind("cluster_distance_m:", 0), 0u) << c.validate();
  c = {};
  c.min_range_m = 30.0;
  EXPECT_EQ(c.validate().rfind("min_range_m:", 0), 0u) << c.validate();
  c = {};
  c.max_row_cones = 0;
  EXPECT_EQ(c.validate().rfind("max_row_cones:", 0), 0u) << c.validate();
  c = {};
  c.reflectivity_white = 1.2;
  EXPECT_EQ(c.validate().rfind("reflectivity_white:", 0), 0u) << c.validate();
  EXPECT_THROW(LidarConeDetector(c, Pose3{}), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// detection on a generated circuit

// Requirements (issue #6), at rest over 40 places of a generated circuit: recall >= 95 % of the
// cones within 15 m that the beams hit, precision >= 98 %, colour right for >= 90 % of the cones
// found within 10 m. Positions: one return has 1.5 cm range noise and a cone gets >= 3 of them,
// so the fitted centre is good to ~1 cm plus the cone model's ~1 cm; 3 cm RMSE within 15 m
// leaves room for the few-point clusters far out. The reported covariance must hold ~all errors
// in its 3-sigma ellipse (for a consistent 2D Gaussian, 98.9 %; 95 % asked).
TEST(LidarConeDetector, FindsTheConesOfAGeneratedCircuitAtRest) {
  const tracks::Track track = tracks::generate_circuit(7);
  Score s = score_track(track, poses_along(track, 40), {});
  s.print("at rest");
  EXPECT_GE(s.recall_visible(), 0.95);
  EXPECT_GE(s.precision(), 0.98);
  EXPECT_GE(s.colour(), 0.90);
  EXPECT_LE(s.rmse_within_15(), 0.03);
  EXPECT_GE(double(s.within_3_sigma) / s.errors, 0.95);
  // the reported covariance grows with range (bearing error, fewer points)
  EXPECT_GT(s.mean_sigma_across(1), s.mean_sigma_across(0));
  EXPECT_GT(s.mean_sigma_across(2), s.mean_sigma_across(1));
  std::printf("  mean sigma across the line of sight 0-5/5-10/10-15 m: %.1f/%.1f/%.1f cm\n",
              100 * s.mean_sigma_across(0), 100 * s.mean_sigma_across(1),
              100 * s.mean_sigma_across(2));
}

// Every class at 2.5-8 m all around a car at rest, ten sweeps with their own noise: each class
// (orange small ones too, which generated circuits lack) is found and named right for >= 90 %
// of its sightings, and the rest is kUnknown rather than another colour (2 % allowed).
TEST(LidarConeDetector, TellsTheFourClassesApart) {
  tracks::Track track;
  const ConeClass classes[] = {ConeClass::kBlue, ConeClass::kYellow, ConeClass::kOrangeSmall,
                               ConeClass::kOrangeBig};
  for (int i = 0; i < 32; ++i) {
    const double a = 2.0 * std::numbers::pi * (i + 0.5) / 32.0;
    const double r = 2.5 + 5.5 * (i % 7) / 6.0;
    track.cones.push_back({i, classes[i % 4], Vec2(2.1 + r * std::cos(a), r * std::sin(a)), {}});
  }
  std::array<Score, 4> by_class;
  for (int k = 0; k < 4; ++k) {
    tracks::Track one = track;
    std::erase_if(one.cones, [&](const tracks::Cone& c) { return c.cls != classes[k]; });
    by_class[k] = score_track(one, std::vector<Pose2>(10, Pose2{}), {}, 20 + k);
  }
  for (int k = 0; k < 4; ++k) {
    Score& s = by_class[k];
    std::printf("[%s] found %d/%d, colour right %d/%d, unknown %d\n",
                std::string(core::to_string(classes[k])).c_str(), s.found_within_15,
                s.true_within_15, s.colour_right_within_10, s.coloured_within_10,
                s.colour_unknown_within_10);
    EXPECT_EQ(s.found_within_15, s.true_within_15) << core::to_string(classes[k]);
    EXPECT_GE(s.colour(), 0.90) << core::to_string(classes[k]);
    EXPECT_LE(s.coloured_within_10 - s.colour_right_within_10 - s.colour_unknown_within_10,
              0.02 * s.coloured_within_10)
        << core::to_string(classes[k]);
  }
}

// The same at 15 m/s along a bend (0.5 rad/s): the car moves 1.5 m during a sweep, so without
// de-skew a cone to the side is off by up to that; with it, the cones stay where they are at
// rest, within the de-skew error of the odometry (exact here) plus the at-rest figures.
TEST(LidarConeDetector, DeskewKeepsConesInPlaceAt15Mps) {
  const tracks::Track track = tracks::generate_circuit(7);
  const std::vector<Pose2> starts = poses_along(track, 40);
  Score on = score_track(track, starts, {15.0, 0.5, 0.0, 0.0, true});
  Score off = score_track(track, starts, {15.0, 0.5, 0.0, 0.0, false});
  on.print("15 m/s, de-skew");
  off.print("15 m/s, no de-skew");
  EXPECT_GE(on.recall_visible(), 0.95);
  EXPECT_GE(on.precision(), 0.98);
  EXPECT_GE(on.colour(), 0.90);
  EXPECT_LE(on.rmse_within_15(), 0.03);
  EXPECT_LE(on.rmse_side(), 0.03);
  // a side cone fired on average half a sweep before the end moves by ~0.75 m without de-skew
  EXPECT_GE(off.rmse_side(), 10.0 * on.rmse_side());
}

// At 10 m/s straight on a car pitched 1.5 degrees nose down and rolled 1 degree (braking in a
// turn): the fitted ground follows, heights stay right, so do recall and positions. The nose-down
// beams reach cones at 8-10 m that a level car does not see, often with 3-5 returns all on the
// stripe, which blue and orange cones share (white): those are kUnknown by design (the tracker's
// votes decide them as the car closes in). So here: no colour wrong (2 % allowed), and >= 90 %
// right among the cones whose colour was decided.
TEST(LidarConeDetector, FollowsAPitchedAndRolledCar) {
  const tracks::Track track = tracks::generate_circuit(11);
  Score s = score_track(track, poses_along(track, 30), {10.0, 0.0, 1.5 * kDeg, 1.0 * kDeg, true});
  s.print("10 m/s, pitch 1.5 deg, roll 1 deg");
  EXPECT_GE(s.recall_visible(), 0.95);
  EXPECT_GE(s.precision(), 0.98);
  const int decided = s.coloured_within_10 - s.colour_unknown_within_10;
  EXPECT_LE(decided - s.colour_right_within_10, 0.02 * s.coloured_within_10);
  EXPECT_GE(s.colour_right_within_10, 0.90 * decided);
  EXPECT_LE(s.rmse_within_15(), 0.03);
}

// Same cloud, same detections: the detector holds no state and draws no random numbers.
// The grass edge's 6 cm step along both sides of a circuit, seen by a VLP-32C on the front wing
// from 40 places: one ring meets the step (or the grass behind it) and leaves a short run of
// points just above the asphalt, which a cone at that range would have had more rings on. No
// such run is taken for a cone, while the cones with points still are; the same scene with the
// ring test off does take the step for cones (so the scene has the case).
// A start gate whose cones touch (EUFS peanut's: a yellow cone and two big orange cones in a
// row 0.26 m apart on one side, two big orange cones 0.30 m apart on the other), seen while
// driving up to it: the bases touch, so each row is one cluster, too wide for one cone. Split
// into a row of cones, each gate cone with returns is found and placed as any cone is (the
// at-rest figures: recall 0.95, 3 cm); without the split (max_row_cones 1) the rows are lost.
// From 3 to 10 m: farther out a VLP-16 gives each cone 2-4 returns, too few to cut a row (it
// stays one detection between its cones, as before).
TEST(LidarConeDetector, FindsTheConesOfATouchingRow) {
  tracks::Track track;
  const Vec2 right[] = {{-0.26, -1.8}, {0.0, -1.8}, {0.26, -1.8}};
  track.cones.push_back({0, ConeClass::kYellow, right[0], {}});
  track.cones.push_back({1, ConeClass::kOrangeBig, right[1], {}});
  track.cones.push_back({2, ConeClass::kOrangeBig, right[2], {}});
  track.cones.push_back({3, ConeClass::kOrangeBig, Vec2(0.0, 1.8), {}});
  track.cones.push_back({4, ConeClass::kOrangeBig, Vec2(0.30, 1.8), {}});
  std::vector<Pose2> approach;
  for (double x = -10.0; x <= -3.0; x += 0.5)
    for (const double y : {-0.6, 0.0, 0.6}) approach.push_back({x, y, 0.0});
  LidarDetectorConfig unsplit;
  unsplit.max_row_cones = 1;
  Score split = score_track(track, approach, {}, 3);
  Score merged = score_track(track, approach, {}, 3, unsplit);
  split.print("touching row");
  merged.print("touching row, no split");
  EXPECT_GE(split.recall_visible(), 0.95);
  EXPECT_GE(split.precision(), 0.98);
  EXPECT_LE(split.rmse_within_15(), 0.03);
  EXPECT_LE(merged.recall_visible(), 0.5);
}

// Scenery that is not a cone (tyre stacks, people, fences, barriers, tents' legs) is no cone
// after the row cut either: around a car at rest, 3-12 m out at many headings, the detections
// whose points are mostly clutter are no more with the cut than without it (VLP-16 and
// VLP-32C).
TEST(LidarConeDetector, CutsNoClutterIntoCones) {
  const core::ClutterClass classes[] = {core::ClutterClass::kTyreStack, core::ClutterClass::kPerson,
                                        core::ClutterClass::kFence, core::ClutterClass::kBarrier,
                                        core::ClutterClass::kTent};
  std::vector<tracks::SceneryObject> scenery;
  for (int i = 0; i < 40; ++i) {
    const double a = 2.0 * std::numbers::pi * (i + 0.5) / 40.0;
    const double r = 3.0 + 9.0 * (i % 8) / 7.0;
    scenery.push_back(tracks::make_scenery_object(classes[i % 5],
                                                  {r * std::cos(a), r * std::sin(a), 0.7 * i}, i));
  }
  for (const char* model : {"vlp16", "vlp32c"}) {
    sensors::LidarConfig lidar_config = *sensors::lidar_preset(model);
    const tracks::Track empty;
    const sensors::Lidar lidar(lidar_config, empty, scenery);
    LidarDetectorConfig cut = sdk_bridge::lidar_detector_config(lidar_config);
    LidarDetectorConfig uncut = cut;
    uncut.max_row_cones = 1;
    const LidarConeDetector with_cut(cut, lidar_config.mount);
    const LidarConeDetector without_cut(uncut, lidar_config.mount);
    core::Rng rng(9);
    int detections_cut = 0, detections_uncut = 0;
    for (int k = 0; k < 12; ++k) {
      sensors::PoseHistory poses;
      const Pose2 pose{0.3 * k, -0.2 * k, 0.5 * k};
      for (TimeUs t = 0; t <= 120'000; t += 1000) poses.push(t, to_pose3(pose));
      const sensors::LidarScan scan = lidar.sweep(0, poses, rng);
      detections_cut += static_cast<int>(with_cut.detect(scan.cloud, {}).cones.size());
      detections_uncut += static_cast<int>(without_cut.detect(scan.cloud, {}).cones.size());
    }
    std::printf("[clutter, %s] %d detections with the row cut, %d without\n", model, detections_cut,
                detections_uncut);
    EXPECT_LE(detections_cut, detections_uncut) << model;
  }
}

TEST(LidarConeDetector, TheGrassEdgesStepIsNoCone) {
  const tracks::Track track = tracks::generate_circuit(7);
  tracks::ClutterConfig clutter;
  clutter.grass_edge = true;
  clutter.margin_m = 2.0;
  const auto scenery = tracks::place_scenery(track, clutter, 1);
  ASSERT_GT(scenery.size(), 20u);
  sensors::LidarConfig lidar_config = *sensors::lidar_preset("vlp32c");
  lidar_config.mount = *sensors::lidar_mount_preset("front_wing");
  const sensors::Lidar lidar(lidar_config, track, scenery);
  LidarDetectorConfig with_test = sdk_bridge::lidar_detector_config(lidar_config);
  LidarDetectorConfig without_test = with_test;
  without_test.ring_above_margin_m = 1.0;  // the ring above never "should have hit" a cone
  const LidarConeDetector detector(with_test, lidar_config.mount);
  const LidarConeDetector unchecked(without_test, lidar_config.mount);
  const int grass = -2 - static_cast<int>(core::ClutterClass::kGrassEdge);

  core::Rng rng(5);
  int on_grass = 0, on_grass_unchecked = 0, detections = 0, visible = 0, found = 0;
  for (const Pose2& pose : poses_along(track, 40)) {
    sensors::PoseHistory poses;
    for (TimeUs t = 0; t <= 120'000; t += 1000) poses.push(t, to_pose3(pose));
    const sensors::LidarScan scan = lidar.sweep(0, poses, rng);
    // the label most of a detection's points carry
    auto majority = [&scan](const LidarCone& cone) {
      std::map<int, int> votes;
      for (const int i : cone.point_indices) ++votes[scan.labels.cone_id[i]];
      return std::max_element(votes.begin(), votes.end(),
                              [](auto& a, auto& b) { return a.second < b.second; })
          ->first;
    };
    std::map<int, int> returns;
    for (const int id : scan.labels.cone_id)
      if (id >= 0) ++returns[id];
    std::set<int> found_ids;
    for (const LidarCone& cone : detector.detect(scan.cloud, {}).cones) {
      ++detections;
      const int label = majority(cone);
      if (label == grass) ++on_grass;
      if (label >= 0) found_ids.insert(label);
    }
    for (const LidarCone& cone : unchecked.detect(scan.cloud, {}).cones)
      if (majority(cone) == grass) ++on_grass_unchecked;
    // the cones within 15 m with at least 5 returns
    const Vec2 sensor_xy = lidar.sensor_pose(poses.at(0)).position.head<2>();
    for (const tracks::Cone& cone : track.cones)
      if ((cone.position - sensor_xy).norm() < 15.0 && returns[cone.id] >= 5) {
        ++visible;
        found += found_ids.count(cone.id) ? 1 : 0;
      }
  }
  std::printf(
      "[grass edge] %d detections, %d on the grass edge (%d with the ring test off); "
      "%d of %d cones with points found\n",
      detections, on_grass, on_grass_unchecked, found, visible);
  EXPECT_GE(on_grass_unchecked, 10);
  EXPECT_EQ(on_grass, 0);
  EXPECT_GE(static_cast<double>(found) / visible, 0.95);
}

TEST(LidarConeDetector, IsDeterministic) {
  const tracks::Track track = tracks::generate_circuit(7);
  const sensors::LidarConfig lidar_config;
  const sensors::Lidar lidar(lidar_config, track);
  sensors::PoseHistory poses;
  for (TimeUs t = 0; t <= 120'000; t += 1000) poses.push(t, to_pose3(track.start));
  core::Rng rng(3);
  const sensors::LidarScan scan = lidar.sweep(0, poses, rng);
  const LidarConeDetector detector({}, lidar_config.mount);
  const LidarDetections a = detector.detect(scan.cloud, {});
  const LidarDetections b = detector.detect(scan.cloud, {});
  ASSERT_EQ(a.cones.size(), b.cones.size());
  ASSERT_GT(a.cones.size(), 4u);
  for (size_t i = 0; i < a.cones.size(); ++i) {
    EXPECT_EQ(a.cones[i].observation.position, b.cones[i].observation.position);
    EXPECT_EQ(a.cones[i].point_indices, b.cones[i].point_indices);
  }
  EXPECT_EQ(a.stamp, core::from_seconds(0.1));
}

}  // namespace
}  // namespace conesim::slam::frontend
