// Tests that prove the LiDAR data are right: every point lies on what its label says it hit,
// ranges match geometry, the sweep moves with the car, stripes show in the intensity.

#include "sensors/lidar.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <utility>
#include <vector>

#include "sensors/cone_mesh.hpp"
#include "sensors/lidar_config.hpp"
#include "sensors/pose_history.hpp"
#include "tracks/scenery.hpp"

namespace conesim::sensors {
namespace {

using core::ConeClass;
using core::Pose3;
using core::TimeUs;

constexpr double kDeg = std::numbers::pi / 180.0;

// a pose on the ground plane
Pose3 planar_pose(double x, double y, double yaw) {
  Pose3 p;
  p.position = {x, y, 0.0};
  p.orientation = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ());
  return p;
}

// a track made of the given cones, ids from 1
tracks::Track make_track(const std::vector<std::pair<core::Vec2, ConeClass>>& cones) {
  tracks::Track track;
  track.name = "test";
  int id = 1;
  for (const auto& [position, cls] : cones) track.cones.push_back({id++, cls, position, {}});
  return track;
}

// vehicle poses every physics step (1 ms) moving along the heading at a constant speed
PoseHistory drive(const Pose3& start, double speed_mps, TimeUs from, TimeUs to) {
  PoseHistory history(10 * core::kUsPerSecond);
  const Eigen::Vector3d heading = start.orientation * Eigen::Vector3d::UnitX();
  for (TimeUs t = from; t <= to; t += 1000) {
    Pose3 p = start;
    p.position += heading * speed_mps * core::to_seconds(t - from);
    history.push(t, p);
  }
  return history;
}

// the ideal sensor: thin rays that never fade, no noise (every point lies on what it hit)
LidarConfig noiseless(LidarConfig config = {}) {
  config.clear_realism();
  config.range_noise_sigma_m = 0.0;
  config.intensity_noise_sigma = 0.0;
  config.dropout_probability = 0.0;
  return config;
}

// a point of a scan in the track frame, through the pose its column fired from
Eigen::Vector3d in_track(const Lidar& lidar, const PoseHistory& poses,
                         const core::PointCloud& cloud, const core::LidarPoint& p) {
  const TimeUs t = cloud.stamp + core::from_seconds(p.time_offset_s);
  return lidar.sensor_pose(poses.at(t)).transform(Eigen::Vector3d(p.x, p.y, p.z));
}

// two scans with the same points, bit for bit, in the same order and with the same labels
::testing::AssertionResult same_points(const LidarScan& a, const LidarScan& b) {
  if (a.cloud.points.size() != b.cloud.points.size())
    return ::testing::AssertionFailure()
           << a.cloud.points.size() << " points against " << b.cloud.points.size();
  for (size_t i = 0; i < a.cloud.points.size(); ++i) {
    const core::LidarPoint &p = a.cloud.points[i], &q = b.cloud.points[i];
    if (!(p.x == q.x && p.y == q.y && p.z == q.z && p.intensity == q.intensity &&
          p.ring == q.ring && p.time_offset_s == q.time_offset_s))
      return ::testing::AssertionFailure() << "point " << i << " differs";
  }
  if (a.labels.cone_id != b.labels.cone_id)
    return ::testing::AssertionFailure() << "the labels differ";
  return ::testing::AssertionSuccess();
}

double range_of(const core::LidarPoint& p) {
  return std::sqrt(p.x * p.x + p.y * p.y + p.z * p.z);
}

// cones all around the car at 3-12 m, every class
tracks::Track ring_of_cones() {
  std::vector<std::pair<core::Vec2, ConeClass>> cones;
  const ConeClass classes[] = {ConeClass::kBlue, ConeClass::kYellow, ConeClass::kOrangeSmall,
                               ConeClass::kOrangeBig};
  for (int i = 0; i < 24; ++i) {
    const double a = 2.0 * std::numbers::pi * i / 24.0;
    const double r = 3.0 + 9.0 * (i % 5) / 4.0;
    cones.push_back({core::Vec2(2.1 + r * std::cos(a), r * std::sin(a)), classes[i % 4]});
  }
  return make_track(cones);
}

// ---------------------------------------------------------------------------------------------
// configuration

TEST(LidarConfig, DefaultsAndPresetsAreValid) {
  EXPECT_EQ(LidarConfig{}.validate(), "");
  for (const std::string& name : lidar_preset_names()) {
    const auto config = lidar_preset(name);
    ASSERT_TRUE(config.has_value()) << name;
    EXPECT_EQ(config->validate(), "") << name;
  }
  EXPECT_EQ(lidar_preset("vlp16")->elevations_deg.size(), 16u);
  EXPECT_EQ(lidar_preset("vlp32c")->elevations_deg.size(), 32u);
  EXPECT_EQ(lidar_preset("os1-64")->elevations_deg.size(), 64u);
  EXPECT_FALSE(lidar_preset("hdl-64").has_value());
  EXPECT_NEAR(lidar_mount_preset("front_wing")->position.z(), 0.18, 1e-12);
  EXPECT_NEAR(lidar_mount_preset("main_hoop")->position.z(), 1.0, 1e-12);
  EXPECT_FALSE(lidar_mount_preset("roof").has_value());
}

TEST(LidarConfig, ValidateNamesTheBadKey) {
  LidarConfig c;
  c.max_range_m = 0.1;
  EXPECT_EQ(c.validate().rfind("max_range_m:", 0), 0u) << c.validate();
  c = {};
  c.reflectivity.white = 1.5;
  EXPECT_EQ(c.validate().rfind("reflectivity.white:", 0), 0u) << c.validate();
  c = {};
  c.dropout_probability = -0.1;
  EXPECT_EQ(c.validate().rfind("dropout_probability:", 0), 0u) << c.validate();
  c = {};
  c.elevations_deg.clear();
  EXPECT_EQ(c.validate().rfind("elevations_deg:", 0), 0u) << c.validate();
  EXPECT_THROW(Lidar(c, make_track({})), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// pose history

TEST(PoseHistory, InterpolatesBetweenStepsAndClampsOutside) {
  PoseHistory h;
  h.push(0, planar_pose(0.0, 0.0, 0.0));
  h.push(1000, planar_pose(1.0, 0.0, 0.2));
  EXPECT_NEAR(h.at(250).position.x(), 0.25, 1e-12);
  EXPECT_NEAR(h.at(500).planar().yaw, 0.1, 1e-12);
  EXPECT_NEAR(h.at(-5).position.x(), 0.0, 1e-12);
  EXPECT_NEAR(h.at(5000).position.x(), 1.0, 1e-12);
  EXPECT_TRUE(h.covers(0, 1000));
  EXPECT_FALSE(h.covers(0, 1001));
  EXPECT_THROW(h.push(999, Pose3{}), std::invalid_argument);
}

TEST(PoseHistory, TheCursorGivesTheSamePosesAsTheSearch) {
  PoseHistory h;
  for (TimeUs t = 0; t <= 20'000; t += 1000) h.push(t, planar_pose(1e-4 * t, 0.0, 2e-5 * t));
  size_t cursor = 0;
  for (TimeUs t : {-10, 0, 1, 999, 1000, 1500, 7777, 19'999, 20'000, 25'000, 3000, 12'345}) {
    const Pose3 a = h.at(t), b = h.at(t, cursor);
    EXPECT_EQ(a.position, b.position) << t;
    EXPECT_EQ(a.orientation.coeffs(), b.orientation.coeffs()) << t;
  }
}

TEST(PoseHistory, ForgetsSamplesOlderThanTheWindow) {
  PoseHistory h(10'000);
  for (TimeUs t = 0; t <= 100'000; t += 1000) h.push(t, planar_pose(1e-5 * t, 0.0, 0.0));
  EXPECT_LE(h.oldest(), 90'000);
  EXPECT_GE(h.oldest(), 89'000);
  EXPECT_NEAR(h.at(95'500).position.x(), 0.955, 1e-12);
}

// ---------------------------------------------------------------------------------------------
// geometry of the returns

// A level, stationary car sees the ground at range h / sin(-elevation) on every downward ring,
// in every column, and nothing on the others (empty track, zero noise).
TEST(Lidar, LevelCarSeesTheGroundAtTheAnalyticRangeOnEveryRing) {
  for (const std::string& model : lidar_preset_names()) {
    for (const char* mount : {"front_wing", "main_hoop"}) {
      LidarConfig config = noiseless(*lidar_preset(model));
      config.mount = *lidar_mount_preset(mount);
      const Lidar lidar(config, make_track({}));
      const PoseHistory poses = drive(planar_pose(3.0, -2.0, 0.7), 0.0, 0, 200'000);
      core::Rng rng(1);
      const LidarScan scan = lidar.sweep(0, poses, rng);

      // expected range per ring, sorted by elevation as rings are
      std::vector<double> elevations = config.elevations_deg;
      std::sort(elevations.begin(), elevations.end());
      const double h = config.mount.position.z();
      std::vector<int> count(elevations.size(), 0);
      for (size_t i = 0; i < scan.cloud.points.size(); ++i) {
        const core::LidarPoint& p = scan.cloud.points[i];
        const double e = elevations[p.ring] * kDeg;
        ASSERT_LT(e, 0.0) << model << " " << mount << ": a return on an upward ring";
        const double expected = h / std::sin(-e);
        ASSERT_NEAR(range_of(p), expected, 1e-5 * expected + 1e-5) << model << " ring " << p.ring;
        EXPECT_EQ(scan.labels.cone_id[i], core::PointCloudLabels::kGroundLabel);
        ++count[p.ring];
      }
      for (size_t r = 0; r < elevations.size(); ++r) {
        const bool reachable = elevations[r] < 0.0 &&
                               h / std::sin(-elevations[r] * kDeg) <= config.max_range_m &&
                               h / std::sin(-elevations[r] * kDeg) >= config.min_range_m;
        EXPECT_EQ(count[r], reachable ? config.columns : 0)
            << model << " " << mount << " ring " << r;
      }
      EXPECT_EQ(scan.stats.rays, static_cast<int64_t>(config.columns) * elevations.size());
    }
  }
}

// Every point labelled with a cone lies on that cone's surface within the range noise (five
// sigma plus the facets of the mesh), every ground point on the ground plane.
TEST(Lidar, LabelledPointsLieOnWhatTheyHit) {
  const tracks::Track track = ring_of_cones();
  for (double sigma : {0.0, 0.015}) {
    // thin rays and a constant noise: points off the surfaces only by the noise
    LidarConfig config;
    config.clear_realism();
    config.range_noise_sigma_m = sigma;
    const Lidar lidar(config, track);
    const PoseHistory poses = drive(planar_pose(0.0, 0.0, 0.0), 0.0, 0, 200'000);
    core::Rng rng(7);
    const LidarScan scan = lidar.sweep(0, poses, rng);

    const double facets = facet_deviation_m(cone_shape(ConeClass::kOrangeBig), 24);
    const double tolerance = 5.0 * sigma + facets + 1e-4;
    int cone_points = 0;
    std::vector<int> per_cone(track.cones.size() + 1, 0);
    for (size_t i = 0; i < scan.cloud.points.size(); ++i) {
      const Eigen::Vector3d p = in_track(lidar, poses, scan.cloud, scan.cloud.points[i]);
      const int id = scan.labels.cone_id[i];
      if (id == core::PointCloudLabels::kGroundLabel) {
        ASSERT_NEAR(p.z(), 0.0, 5.0 * sigma + 1e-4) << "ground point " << i;
        continue;
      }
      const tracks::Cone& cone = track.cone(id);
      const Eigen::Vector3d local = p - Eigen::Vector3d(cone.position.x(), cone.position.y(), 0.0);
      ASSERT_LT(cone_shape(cone.cls).surface_distance(local), tolerance)
          << "cone " << id << " point " << local.transpose();
      ++cone_points;
      ++per_cone[id];
    }
    // every cone within 10 m is seen (at 12 m a small cone falls between the beams of a
    // front-wing VLP-16: the -1 degree beam meets the ground first, the +1 degree one passes over)
    EXPECT_GT(cone_points, 300);
    for (const tracks::Cone& cone : track.cones) {
      if ((cone.position - core::Vec2(2.1, 0.0)).norm() < 10.0) {
        EXPECT_GT(per_cone[cone.id], 0) << cone.id;
      }
    }
  }
}

// Returns beyond the maximum range are missed.
TEST(Lidar, NothingBeyondTheMaximumRange) {
  LidarConfig config = noiseless();
  config.max_range_m = 3.0;
  const tracks::Track track = make_track({{core::Vec2(2.1 + 5.0, 0.0), ConeClass::kOrangeBig}});
  const Lidar lidar(config, track);
  const PoseHistory poses = drive(Pose3{}, 0.0, 0, 200'000);
  core::Rng rng(3);
  const LidarScan scan = lidar.sweep(0, poses, rng);
  ASSERT_FALSE(scan.cloud.points.empty());
  for (size_t i = 0; i < scan.cloud.points.size(); ++i) {
    EXPECT_LE(range_of(scan.cloud.points[i]), 3.0 + 1e-5);
    EXPECT_EQ(scan.labels.cone_id[i], core::PointCloudLabels::kGroundLabel);
  }
  // rings -1 and -3 reach the ground beyond 3 m: they are empty
  for (const core::LidarPoint& p : scan.cloud.points) EXPECT_LT(p.ring, 6);
}

// ---------------------------------------------------------------------------------------------
// time: the sweep follows the car

// At 10 m/s the first and last columns fire from poses 1 m apart: a cone right behind the car
// (where the sweep starts and ends) reads 1 m farther in the last column than in the first,
// and every point still lies on its cone when taken through its own column's pose.
TEST(Lidar, AtTenMetresPerSecondTheSweepSpansOneMetre) {
  const double speed = 10.0;
  tracks::Track track = ring_of_cones();
  track.cones.push_back({100, ConeClass::kOrangeBig, core::Vec2(2.1 - 5.0, 0.0), {}});
  const Lidar lidar(noiseless(), track);
  const TimeUs start = 1'000'000;
  const PoseHistory poses = drive(planar_pose(0.0, 0.0, 0.0), speed, 900'000, 1'200'000);
  core::Rng rng(11);
  const LidarScan scan = lidar.sweep(start, poses, rng);

  // the firing poses of the first and last columns
  const TimeUs last = lidar.sweep_end(start);
  EXPECT_EQ(last - start, 99'944);  // column 1799 of 1800 in 100 ms
  const double travelled =
      (scan.labels.sensor_pose_end.position - scan.labels.sensor_pose_start.position).norm();
  EXPECT_NEAR(travelled, speed * core::to_seconds(last - start), 1e-6);
  EXPECT_NEAR(travelled, 1.0, 0.001);

  // the cone behind: first column versus last column, in the sensor frame
  double first_x = 0.0, last_x = 0.0;
  int first_n = 0, last_n = 0;
  for (size_t i = 0; i < scan.cloud.points.size(); ++i) {
    if (scan.labels.cone_id[i] != 100) continue;
    const core::LidarPoint& p = scan.cloud.points[i];
    if (p.time_offset_s == 0.f) {
      first_x += p.x;
      ++first_n;
    }
    if (core::from_seconds(p.time_offset_s) == last - start) {
      last_x += p.x;
      ++last_n;
    }
  }
  ASSERT_GT(first_n, 0);
  ASSERT_GT(last_n, 0);
  EXPECT_NEAR(first_x / first_n - last_x / last_n, travelled, 0.02);

  // through each column's pose every point is on its cone; through the start pose it is not
  const double tolerance = facet_deviation_m(cone_shape(ConeClass::kOrangeBig), 24) + 1e-4;
  double worst_with_start_pose = 0.0;
  for (size_t i = 0; i < scan.cloud.points.size(); ++i) {
    const int id = scan.labels.cone_id[i];
    if (id == core::PointCloudLabels::kGroundLabel) continue;
    const tracks::Cone& cone = track.cone(id);
    const Eigen::Vector3d base(cone.position.x(), cone.position.y(), 0.0);
    const core::LidarPoint& q = scan.cloud.points[i];
    const Eigen::Vector3d right = in_track(lidar, poses, scan.cloud, q) - base;
    ASSERT_LT(cone_shape(cone.cls).surface_distance(right), tolerance) << "cone " << id;
    const Eigen::Vector3d wrong =
        scan.labels.sensor_pose_start.transform(Eigen::Vector3d(q.x, q.y, q.z)) - base;
    worst_with_start_pose =
        std::max(worst_with_start_pose, cone_shape(cone.cls).surface_distance(wrong));
  }
  EXPECT_GT(worst_with_start_pose, 0.5);
}

TEST(Lidar, RefusesASweepThePosesDoNotCover) {
  const Lidar lidar(LidarConfig{}, make_track({}));
  const PoseHistory poses = drive(Pose3{}, 0.0, 0, 50'000);
  core::Rng rng(1);
  EXPECT_THROW((void)lidar.sweep(0, poses, rng), std::invalid_argument);
  EXPECT_THROW((void)lidar.sweep(0, PoseHistory{}, rng), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// intensity

// Blue cones read dark-light-dark along their height, yellow cones light-dark-light: the mean
// intensity of the middle band differs from the outer bands' by far more than its noise.
TEST(Lidar, BlueAndYellowConesShowOppositeStripes) {
  std::vector<std::pair<core::Vec2, ConeClass>> cones;
  for (int i = 0; i < 12; ++i) {
    const double x = 2.1 + 2.0 + 0.45 * i;
    cones.push_back({core::Vec2(x, 1.5 + 0.1 * i), ConeClass::kBlue});
    cones.push_back({core::Vec2(x, -1.5 - 0.1 * i), ConeClass::kYellow});
  }
  const tracks::Track track = make_track(cones);
  const Lidar lidar(LidarConfig{}, track);
  const PoseHistory poses = drive(Pose3{}, 0.0, 0, 200'000);
  core::Rng rng(5);
  const LidarScan scan = lidar.sweep(0, poses, rng);

  // intensity sums of the stripe and of the base colour, per class
  struct Stat {
    double sum = 0.0, sum_sq = 0.0;
    int n = 0;
    void add(double v) { sum += v, sum_sq += v * v, ++n; }
    double mean() const { return sum / n; }
    double std_error() const { return std::sqrt((sum_sq / n - mean() * mean()) / n); }
  };
  Stat blue_stripe, blue_base, yellow_stripe, yellow_base;
  for (size_t i = 0; i < scan.cloud.points.size(); ++i) {
    const int id = scan.labels.cone_id[i];
    if (id == core::PointCloudLabels::kGroundLabel) continue;
    const tracks::Cone& cone = track.cone(id);
    const ConeShape shape = cone_shape(cone.cls);
    const double z = in_track(lidar, poses, scan.cloud, scan.cloud.points[i]).z();
    // skip points within 1 cm of a band boundary (the noise may move them across)
    if (shape.material_at(z - 0.01) != shape.material_at(z + 0.01)) continue;
    const bool stripe = shape.material_at(z) != shape.plate_material;
    const double v = scan.cloud.points[i].intensity;
    if (cone.cls == ConeClass::kBlue) (stripe ? blue_stripe : blue_base).add(v);
    if (cone.cls == ConeClass::kYellow) (stripe ? yellow_stripe : yellow_base).add(v);
  }
  for (const Stat* s : {&blue_stripe, &blue_base, &yellow_stripe, &yellow_base})
    ASSERT_GE(s->n, 20);
  const double blue_margin = 5.0 * std::hypot(blue_stripe.std_error(), blue_base.std_error());
  const double yellow_margin = 5.0 * std::hypot(yellow_stripe.std_error(), yellow_base.std_error());
  EXPECT_GT(blue_stripe.mean(), blue_base.mean() + blue_margin)
      << "blue: white stripe " << blue_stripe.mean() << " vs blue " << blue_base.mean();
  EXPECT_LT(yellow_stripe.mean() + yellow_margin, yellow_base.mean())
      << "yellow: black stripe " << yellow_stripe.mean() << " vs yellow " << yellow_base.mean();
}

// ---------------------------------------------------------------------------------------------
// the scene changes, faults, determinism

TEST(Lidar, AKnockedConeGetsNoPoints) {
  const tracks::Track track = make_track({{core::Vec2(2.1 + 4.0, 0.0), ConeClass::kBlue},
                                          {core::Vec2(2.1 + 4.0, 2.0), ConeClass::kYellow}});
  Lidar lidar(LidarConfig{}, track);
  const PoseHistory poses = drive(Pose3{}, 0.0, 0, 200'000);
  auto points_of = [&](int id) {
    core::Rng rng(2);
    const LidarScan scan = lidar.sweep(0, poses, rng);
    return std::count(scan.labels.cone_id.begin(), scan.labels.cone_id.end(), id);
  };
  EXPECT_GT(points_of(1), 10);
  lidar.set_cone_present(1, false);
  EXPECT_FALSE(lidar.cone_present(1));
  EXPECT_EQ(points_of(1), 0);
  EXPECT_GT(points_of(2), 10);
  lidar.set_cone_present(1, true);
  EXPECT_GT(points_of(1), 10);
  EXPECT_THROW(lidar.set_cone_present(99, false), std::out_of_range);
}

// ---------------------------------------------------------------------------------------------
// the sensor's realism: noise that grows with range, weak returns that fade, a spot with a width

// The range noise grows with range as configured: the spread of the ground's ranges on each ring
// (one range per ring for a level car on flat ground) is sigma + growth * range.
TEST(Lidar, RangeNoiseGrowsWithRange) {
  LidarConfig config = noiseless();
  config.range_noise_sigma_m = 0.01;
  config.range_noise_growth = 0.003;  // 3 cm more at 10 m: far above the sampling error
  const Lidar lidar(config, make_track({}));
  const PoseHistory poses = drive(Pose3{}, 0.0, 0, 200'000);
  core::Rng rng(11);
  const LidarScan scan = lidar.sweep(0, poses, rng);
  const double height = config.mount.position.z();
  std::vector<double> sum(16, 0.0), squares(16, 0.0), count(16, 0.0);
  for (const core::LidarPoint& p : scan.cloud.points) {
    const double expected = height / std::sin(-config.elevations_deg[p.ring] * kDeg);
    const double error = range_of(p) - expected;
    sum[p.ring] += error;
    squares[p.ring] += error * error;
    count[p.ring] += 1.0;
  }
  int rings = 0;
  for (int ring = 0; ring < 8; ++ring) {  // the downward rings, ground at 0.7-10 m
    const double expected_range = height / std::sin(-config.elevations_deg[ring] * kDeg);
    if (count[ring] < 500 || expected_range > config.max_range_m) continue;
    const double mean = sum[ring] / count[ring];
    const double spread = std::sqrt(squares[ring] / count[ring] - mean * mean);
    const double sigma = 0.01 + 0.003 * expected_range;
    // the sample's spread within 10 % of sigma: over 20 times its own standard error
    EXPECT_NEAR(spread, sigma, 0.1 * sigma) << "ring " << ring << " at " << expected_range << " m";
    ++rings;
  }
  EXPECT_GE(rings, 6);
}

// Weak returns fade as the configured law says, and a user sees it where it matters: a cone's
// black stripe loses most of its points at 30 m where its white one keeps them, and the ground
// fades with range at its grazing incidence. Each return of the ideal scan (no noise, so its
// intensity is the one before noise) is kept with probability q^4 / (1 + q^4).
TEST(Lidar, DarkAndGrazingReturnsFadeFirst) {
  std::vector<std::pair<core::Vec2, ConeClass>> cones;
  for (int i = 0; i < 60; ++i) {
    const double a = 2.0 * std::numbers::pi * i / 60.0;
    const double r = 30.0;
    cones.push_back({core::Vec2(2.1 + r * std::cos(a), r * std::sin(a)),
                     i % 4 < 2 ? ConeClass::kYellow : ConeClass::kBlue});
  }
  const tracks::Track track = make_track(cones);
  // (the VLP-32C's rays, dense about the horizon, meet small cones at 30 m)
  LidarConfig ideal = noiseless(*lidar_preset("vlp32c"));
  LidarConfig fading = ideal;
  fading.detection_range_10pct_m = 35.0;
  const Lidar all(ideal, track), kept(fading, track);
  const PoseHistory poses = drive(Pose3{}, 0.0, 0, 200'000);
  core::Rng rng_all(5), rng_kept(5);
  const LidarScan before = all.sweep(0, poses, rng_all);
  const LidarScan after = kept.sweep(0, poses, rng_kept);
  EXPECT_EQ(after.stats.hits - after.stats.faded, static_cast<int64_t>(after.cloud.points.size()));

  // the probability of each return of the ideal scan, and what was seen of each kind
  const double falloff = 1.0 / (ideal.intensity_falloff_m * ideal.intensity_falloff_m);
  double expected = 0.0, variance = 0.0;
  struct Kind {
    double before = 0, after = 0;
  } dark_far, bright_far, near_ground, far_ground;
  auto kind_of = [&](const core::LidarPoint& p, int label) -> Kind* {
    const double r = range_of(p);
    const double reflected = p.intensity / 255.0 * (1.0 + r * r * falloff);
    if (label == core::PointCloudLabels::kGroundLabel)
      return r < 3.0 ? &near_ground : r > 6.0 ? &far_ground : nullptr;
    if (r < 25.0) return nullptr;
    if (reflected < 0.06) return &dark_far;
    if (reflected > 0.5) return &bright_far;
    return nullptr;
  };
  for (size_t i = 0; i < before.cloud.points.size(); ++i) {
    const core::LidarPoint& p = before.cloud.points[i];
    const double r = range_of(p);
    const double q = p.intensity / 255.0 * (1.0 + r * r * falloff) * 35.0 * 35.0 / 0.1 / (r * r);
    const double pk = std::pow(q, 4) / (1.0 + std::pow(q, 4));
    expected += pk;
    variance += pk * (1.0 - pk);
    if (Kind* k = kind_of(p, before.labels.cone_id[i])) k->before += 1;
  }
  for (size_t i = 0; i < after.cloud.points.size(); ++i)
    if (Kind* k = kind_of(after.cloud.points[i], after.labels.cone_id[i])) k->after += 1;
  EXPECT_NEAR(static_cast<double>(after.cloud.points.size()), expected, 5.0 * std::sqrt(variance));

  ASSERT_GT(dark_far.before, 20);
  ASSERT_GT(bright_far.before, 20);
  EXPECT_LT(dark_far.after / dark_far.before, 0.5) << dark_far.before;
  EXPECT_GT(bright_far.after / bright_far.before, 0.95) << bright_far.before;
  EXPECT_GT(near_ground.after / near_ground.before, 0.95);
  EXPECT_LT(far_ground.after / far_ground.before, 0.5);
}

// A spot with a width gives mixed returns at the cones' edges: points off every surface (a part
// of the spot on the cone makes the cone look wider, or merges with the ground just behind it),
// which thin rays never give; they are few, and weaker than the cone's own points, since only a
// part of the spot came back from the cone. (10 mrad, three times a VLP-16's, to put the edge
// points well clear of the mesh's facets.)
TEST(Lidar, ASpotWithAWidthGivesMixedReturnsAtConeEdges) {
  const tracks::Track track = ring_of_cones();
  const PoseHistory poses = drive(Pose3{}, 0.0, 0, 200'000);
  const double facets = facet_deviation_m(cone_shape(ConeClass::kOrangeBig), 24);
  for (double divergence : {0.0, 10.0}) {
    LidarConfig config = noiseless();
    config.beam_divergence_mrad = divergence;
    const Lidar lidar(config, track);
    core::Rng rng(9);
    const LidarScan scan = lidar.sweep(0, poses, rng);
    int mixed = 0, on_cones = 0;
    double mixed_intensity = 0.0, cone_intensity = 0.0;
    for (size_t i = 0; i < scan.cloud.points.size(); ++i) {
      const core::LidarPoint& q = scan.cloud.points[i];
      const Eigen::Vector3d p = in_track(lidar, poses, scan.cloud, q);
      double nearest = std::abs(p.z());
      for (const tracks::Cone& cone : track.cones)
        nearest =
            std::min(nearest, cone_shape(cone.cls).surface_distance(
                                  p - Eigen::Vector3d(cone.position.x(), cone.position.y(), 0.0)));
      // (beyond the curvature a spot averages over: a few millimetres)
      if (nearest > facets + 0.01) {
        ++mixed;
        mixed_intensity += q.intensity;
      } else if (scan.labels.cone_id[i] >= 0) {
        ++on_cones;
        cone_intensity += q.intensity;
      }
    }
    ASSERT_GT(on_cones, 300);
    if (divergence == 0.0) {
      EXPECT_EQ(mixed, 0);
    } else {
      EXPECT_GT(mixed, 10) << on_cones;
      EXPECT_LT(mixed, on_cones / 4) << mixed;
      EXPECT_LT(mixed_intensity / mixed, cone_intensity / on_cones);
    }
  }
}

TEST(Lidar, DropoutLosesTheConfiguredShareOfReturns) {
  LidarConfig config;
  config.dropout_probability = 0.1;
  const Lidar lidar(config, ring_of_cones());
  const PoseHistory poses = drive(Pose3{}, 0.0, 0, 200'000);
  core::Rng rng(4);
  const LidarScan scan = lidar.sweep(0, poses, rng);
  const double n = static_cast<double>(scan.stats.hits);
  const double sigma = std::sqrt(n * 0.1 * 0.9);
  EXPECT_NEAR(static_cast<double>(scan.stats.dropped), 0.1 * n, 5.0 * sigma);
  EXPECT_EQ(scan.stats.hits - scan.stats.dropped - scan.stats.faded - scan.stats.out_of_range,
            static_cast<int64_t>(scan.cloud.points.size()));
}

TEST(Lidar, SameSeedSameScan) {
  LidarConfig config;
  config.dropout_probability = 0.05;
  const Lidar lidar(config, ring_of_cones());
  const PoseHistory poses = drive(planar_pose(0.0, 0.0, 0.3), 5.0, 0, 200'000);
  auto scan_with = [&](uint64_t seed) {
    core::Rng rng(seed);
    return lidar.sweep(10'000, poses, rng);
  };
  const LidarScan a = scan_with(42), b = scan_with(42), c = scan_with(43);
  EXPECT_TRUE(same_points(a, b));
  bool differs = a.cloud.points.size() != c.cloud.points.size();
  for (size_t i = 0; !differs && i < a.cloud.points.size(); ++i)
    differs = a.cloud.points[i].x != c.cloud.points[i].x;
  EXPECT_TRUE(differs);
}

// The harness casts a sweep in parts as the poses arrive: with noise and dropout on and the car
// turning, parts of any number of column blocks give exactly the points of one sweep, each
// part seeing only the poses up to its last column.
TEST(Lidar, ASweepCastInPartsGivesTheSamePoints) {
  LidarConfig config;
  config.dropout_probability = 0.05;
  const Lidar lidar(config, ring_of_cones());
  const PoseHistory poses = drive(planar_pose(0.0, 0.0, 0.3), 8.0, 0, 200'000);
  const TimeUs start = 10'000;
  core::Rng whole_rng(7);
  const LidarScan whole = lidar.sweep(start, poses, whole_rng);

  core::Rng parts_rng(7);
  LidarNoise noise(parts_rng);
  LidarScan parts;
  const int block = lidar.column_block();
  int begin = 0;
  for (int blocks = 1; begin < config.columns; blocks = blocks % 5 + 1) {
    const int end = std::min(config.columns, begin + blocks * block);
    // the poses up to the part's last column only
    PoseHistory so_far(10 * core::kUsPerSecond);
    const TimeUs last = lidar.column_time(start, end - 1);
    for (TimeUs t = 0; t < last + 1000; t += 1000) so_far.push(t, poses.at(t));
    lidar.sweep_columns(start, begin, end, so_far, noise, parts);
    begin = end;
  }

  EXPECT_TRUE(same_points(whole, parts));
  EXPECT_EQ(whole.cloud.stamp, parts.cloud.stamp);
  EXPECT_EQ(whole.labels.sensor_pose_end.position, parts.labels.sensor_pose_end.position);
  EXPECT_EQ(whole.stats.hits, parts.stats.hits);
  EXPECT_EQ(whole.stats.dropped, parts.stats.dropped);
  // the generators went through the same numbers
  EXPECT_EQ(whole_rng(), parts_rng());
}

// A pitched, rolled car (the rays of a column no longer share one heading seen from above):
// every labelled point still lies on what it hit and every cone within 8 m is seen, so the
// rays judged clear of every cone really were.
TEST(Lidar, ATiltedCarStillSeesEveryNearCone) {
  const tracks::Track track = ring_of_cones();
  LidarConfig config = noiseless();
  Pose3 tilted = planar_pose(0.0, 0.0, 0.4);
  tilted.position.z() = 0.05;
  tilted.orientation = tilted.orientation *
                       Eigen::AngleAxisd(3.0 * kDeg, Eigen::Vector3d::UnitY()) *
                       Eigen::AngleAxisd(-4.0 * kDeg, Eigen::Vector3d::UnitX());
  const Lidar lidar(config, track);
  const PoseHistory poses = drive(tilted, 0.0, 0, 200'000);
  core::Rng rng(9);
  const LidarScan scan = lidar.sweep(0, poses, rng);

  const double tolerance = facet_deviation_m(cone_shape(ConeClass::kOrangeBig), 24) + 1e-4;
  std::vector<int> per_cone(track.cones.size() + 1, 0);
  for (size_t i = 0; i < scan.cloud.points.size(); ++i) {
    const Eigen::Vector3d p = in_track(lidar, poses, scan.cloud, scan.cloud.points[i]);
    const int id = scan.labels.cone_id[i];
    if (id == core::PointCloudLabels::kGroundLabel) {
      ASSERT_NEAR(p.z(), 0.0, 1e-4) << "ground point " << i;
      continue;
    }
    const tracks::Cone& cone = track.cone(id);
    const Eigen::Vector3d local = p - Eigen::Vector3d(cone.position.x(), cone.position.y(), 0.0);
    ASSERT_LT(cone_shape(cone.cls).surface_distance(local), tolerance) << "cone " << id;
    ++per_cone[id];
  }
  const Eigen::Vector3d sensor = lidar.sensor_pose(tilted).position;
  for (const tracks::Cone& cone : track.cones) {
    if ((cone.position - sensor.head<2>()).norm() < 8.0) {
      EXPECT_GT(per_cone[cone.id], 0) << cone.id;
    }
  }
  // only the rays near a cone went through the scene
  EXPECT_GT(scan.stats.traced, 0);
  EXPECT_LT(scan.stats.traced, scan.stats.rays / 2);
}

// ---------------------------------------------------------------------------------------------
// the noise sampler (core::ziggurat_normal and core::ZigguratNormals)

// The moments and the tails of n samples against the standard normal's: the mean within five
// standard errors (1 / sqrt(n)), the variance within five of its own (sqrt(2 / n)), the share
// beyond 2 and beyond R = 3.654 (the ziggurat's tail) within five binomial sigmas.
template <typename Sample>
void expect_standard_normal(Sample sample, const char* name) {
  constexpr int n = 400'000;
  double sum = 0.0, sum_sq = 0.0;
  int beyond_two = 0, in_tail = 0;
  for (int i = 0; i < n; ++i) {
    const double x = sample();
    sum += x;
    sum_sq += x * x;
    beyond_two += std::abs(x) > 2.0;
    in_tail += std::abs(x) > 3.6541528853610088;
  }
  const double mean = sum / n, variance = sum_sq / n - mean * mean;
  EXPECT_NEAR(mean, 0.0, 5.0 / std::sqrt(n)) << name;
  EXPECT_NEAR(variance, 1.0, 5.0 * std::sqrt(2.0 / n)) << name;
  auto expect_share = [&](int count, double p, const char* what) {
    EXPECT_NEAR(count, n * p, 5.0 * std::sqrt(n * p * (1.0 - p))) << name << " " << what;
  };
  expect_share(beyond_two, 0.0455002638963584, "beyond 2");
  expect_share(in_tail, 2.0 * 0.5 * std::erfc(3.6541528853610088 / std::sqrt(2.0)), "tail");
}

TEST(Ziggurat, SamplesAreStandardNormal) {
  core::Rng rng(123);
  expect_standard_normal([&] { return core::ziggurat_normal(rng); }, "double");
  core::ZigguratNormals normal(rng);
  expect_standard_normal([&] { return static_cast<double>(normal()); }, "single");
}

TEST(Ziggurat, SameSeedSameSamples) {
  core::Rng a(5), b(5), c(6);
  core::ZigguratNormals na(a), nb(b), nc(c);
  bool differs = false;
  for (int i = 0; i < 1000; ++i) {
    const float x = na(), y = nb(), z = nc();
    ASSERT_EQ(x, y) << i;
    differs = differs || x != z;
  }
  EXPECT_TRUE(differs);
  core::Rng d(7), e(7);
  for (int i = 0; i < 1000; ++i) ASSERT_EQ(core::ziggurat_normal(d), core::ziggurat_normal(e));
}

// ---------------------------------------------------------------------------------------------
// cone geometry

TEST(ConeMesh, ShapesHaveTheHandbookSizesAndStripes) {
  const ConeShape small = cone_shape(ConeClass::kBlue);
  EXPECT_DOUBLE_EQ(small.plate_width_m, 0.228);
  EXPECT_DOUBLE_EQ(small.height_m, 0.325);
  EXPECT_EQ(small.material_at(0.05), SurfaceMaterial::kBlue);
  EXPECT_EQ(small.material_at(0.16), SurfaceMaterial::kWhite);
  EXPECT_EQ(small.material_at(0.30), SurfaceMaterial::kBlue);
  EXPECT_EQ(cone_shape(ConeClass::kYellow).material_at(0.16), SurfaceMaterial::kBlack);
  const ConeShape big = cone_shape(ConeClass::kOrangeBig);
  EXPECT_DOUBLE_EQ(big.plate_width_m, 0.285);
  EXPECT_DOUBLE_EQ(big.height_m, 0.505);
  int white_bands = 0;
  for (const ConeBand& band : big.bands) white_bands += band.material == SurfaceMaterial::kWhite;
  EXPECT_EQ(white_bands, 2);

  // every mesh vertex lies on the exact shape
  const ConeMesh mesh = build_cone_mesh(big, 24);
  EXPECT_EQ(mesh.triangles.size(), mesh.materials.size());
  for (const Eigen::Vector3f& v : mesh.vertices)
    EXPECT_LT(big.surface_distance(v.cast<double>()), 1e-6) << v.transpose();
}

// ---------------------------------------------------------------------------------------------
// scenery and clutter (issue 17)

// distance from a point in a solid's frame to its surface: exact for a box, along the radius
// (never less than the true distance) for a cylinder or frustum
double surface_distance(const tracks::ScenePrimitive& part, const Eigen::Vector3d& q) {
  if (part.shape == tracks::ScenePrimitive::Shape::kBox) {
    const Eigen::Vector3d d = q.cwiseAbs() - part.size;
    const double outside = d.cwiseMax(0.0).norm();
    return outside > 0.0 ? outside : -d.maxCoeff();
  }
  const double r0 = part.size.x();
  const double r1 =
      part.shape == tracks::ScenePrimitive::Shape::kCylinder ? part.size.x() : part.size.y();
  const double hz = part.size.z();
  const double t = std::clamp((q.z() + hz) / (2.0 * hz), 0.0, 1.0);
  const double radial = std::hypot(q.x(), q.y()) - (r0 + (r1 - r0) * t);
  const double axial = std::abs(q.z()) - hz;
  return std::abs(std::max(radial, axial));
}

// one object of every class around a car standing at the origin, clear of two cones ahead
std::vector<tracks::SceneryObject> one_of_each() {
  using core::ClutterClass;
  const std::pair<ClutterClass, core::Pose2> placed[] = {
      {ClutterClass::kBarrier, {10.0, 5.0, 0.3}},   {ClutterClass::kFence, {2.0, 12.0, 0.0}},
      {ClutterClass::kTyreStack, {8.0, -5.0, 0.0}}, {ClutterClass::kTent, {-6.0, -7.0, 0.2}},
      {ClutterClass::kPerson, {-3.0, 4.0, 1.0}},    {ClutterClass::kSpareCone, {2.1, -4.0, 0.0}},
      {ClutterClass::kLyingCone, {-1.9, 0.5, 0.7}}, {ClutterClass::kGrassEdge, {6.5, -7.0, 0.0}}};
  std::vector<tracks::SceneryObject> objects;
  for (const auto& [cls, pose] : placed) objects.push_back(tracks::make_scenery_object(cls, pose));
  return objects;
}

// Every object returns points; each carries its class's clutter label and lies on one of the
// object's solids (to the facets of the round ones); no point on clutter carries a cone id.
TEST(Lidar, AClutterObjectReturnsPointsAndNoConeLabel) {
  const tracks::Track track = make_track(
      {{core::Vec2(7.0, 1.5), ConeClass::kBlue}, {core::Vec2(7.0, -1.5), ConeClass::kYellow}});
  const std::vector<tracks::SceneryObject> objects = one_of_each();
  const LidarConfig config = noiseless();
  const Lidar lidar(config, track, objects);
  const PoseHistory poses = drive(Pose3{}, 0.0, 0, 200'000);
  core::Rng rng(3);
  const LidarScan scan = lidar.sweep(0, poses, rng);

  // the facets of the widest round solid (0.3 m tyres), and the single-precision rounding
  const double tolerance = 0.3 * (1.0 - std::cos(std::numbers::pi / config.cone_mesh_sides)) + 2e-3;
  std::vector<int> per_class(core::kClutterClassCount, 0);
  for (size_t i = 0; i < scan.cloud.points.size(); ++i) {
    const Eigen::Vector3d p = in_track(lidar, poses, scan.cloud, scan.cloud.points[i]);
    const int label = scan.labels.cone_id[i];
    if (label >= 0) {
      // a cone's point lies on its cone, never on an object
      const tracks::Cone& cone = track.cone(label);
      ASSERT_LT((p.head<2>() - cone.position).norm(), 0.2) << "cone " << label;
      continue;
    }
    const std::optional<core::ClutterClass> cls = core::clutter_of_label(label);
    if (!cls) {
      ASSERT_EQ(label, core::PointCloudLabels::kGroundLabel);
      continue;
    }
    ++per_class[static_cast<size_t>(*cls)];
    const tracks::SceneryObject& o = objects[static_cast<size_t>(*cls)];
    ASSERT_EQ(o.cls, *cls);
    const Eigen::Matrix3d turn =
        Eigen::AngleAxisd(o.pose.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const Eigen::Vector3d local = turn.transpose() * (p - Eigen::Vector3d(o.pose.x, o.pose.y, 0.0));
    double nearest = std::numeric_limits<double>::infinity();
    for (const tracks::ScenePrimitive& part : o.parts)
      nearest = std::min(nearest,
                         surface_distance(part, part.rotation.transpose() * (local - part.centre)));
    ASSERT_LT(nearest, tolerance) << core::to_string(*cls) << " point " << local.transpose();
  }
  for (core::ClutterClass c : core::kClutterClasses) {
    // the cones lower than the sensor meet one ring or two; the rest many
    const bool low = c == core::ClutterClass::kSpareCone || c == core::ClutterClass::kLyingCone;
    EXPECT_GE(per_class[static_cast<size_t>(c)], low ? 2 : 20) << core::to_string(c);
  }
}

// Scenery beyond the maximum range changes no point and no label, with noise and dropout on:
// the objects draw nothing from the sweep's generator. An empty scenery is today's scene.
TEST(Lidar, SceneryOutOfRangeChangesNoPoint) {
  LidarConfig config;
  config.dropout_probability = 0.05;
  const tracks::Track track = ring_of_cones();
  std::vector<tracks::SceneryObject> far = one_of_each();
  for (tracks::SceneryObject& o : far) o.pose.x += 3.0 * config.max_range_m;
  const PoseHistory poses = drive(planar_pose(0.0, 0.0, 0.3), 5.0, 0, 200'000);
  auto scan_of = [&](const Lidar& lidar) {
    core::Rng rng(42);
    return lidar.sweep(10'000, poses, rng);
  };
  const LidarScan today = scan_of(Lidar(config, track));
  EXPECT_TRUE(same_points(today, scan_of(Lidar(config, track, far))));
  EXPECT_TRUE(same_points(today, scan_of(Lidar(config, track, {}))));
  // the same objects in range do change the scan
  EXPECT_FALSE(same_points(today, scan_of(Lidar(config, track, one_of_each()))));
}

// ---------------------------------------------------------------------------------------------
// ground that is not flat (issue 17)

// A 2 % grade with undulations and bumps: every ground point lies on the height model within the
// range noise (a ray meets the ground at a glancing angle, so the noise moves a point along the
// ray: its height by at most the noise, and the ground under it by the slope times the noise),
// most of them well away from z = 0, where the flat plane would have put them; every cone stands
// on the ground and is seen within 10 m.
TEST(Lidar, OnUnevenGroundThePointsLieOnTheHeightModel) {
  // the grade is zero at the track's start: 40 m from the car, so that the ground around it
  // lies half a metre and more from z = 0
  tracks::Track track = ring_of_cones();
  track.start = {-43.0, 0.0, 0.0};
  // undulating ground, and a grade with bumps between which the ground is planar (met there as
  // its blocks' planes rather than cell by cell)
  tracks::GroundConfig undulating;
  undulating.grade_percent = 2.0;
  undulating.grade_heading_deg = 30.0;
  undulating.undulation_amplitude_m = 0.1;
  undulating.bump_height_m = 0.04;
  undulating.bumps_per_100m2 = 5.0;
  tracks::GroundConfig graded = undulating;
  graded.undulation_amplitude_m = 0.0;
  graded.bumps_per_100m2 = 2.0;
  for (const tracks::GroundConfig& shape : {undulating, graded})
    for (double sigma : {0.0, 0.015}) {
      SCOPED_TRACE(shape.undulation_amplitude_m > 0.0 ? "undulating" : "graded");
      const tracks::GroundModel ground(track, shape, 3);
      ASSERT_FALSE(ground.flat());
      // thin rays (no mixed returns at the cones' edges); the noise grows with range
      LidarConfig config;
      config.beam_divergence_mrad = 0.0;
      config.range_noise_sigma_m = sigma;
      if (sigma == 0.0) config.range_noise_growth = 0.0;
      const Lidar lidar(config, track, {}, ground);
      Pose3 start = planar_pose(-3.0, 1.0, 0.2);
      start.position.z() = ground.height(-3.0, 1.0);
      const PoseHistory poses = drive(start, 0.0, 0, 200'000);
      core::Rng rng(7);
      const LidarScan scan = lidar.sweep(0, poses, rng);

      // the grid holds heights in single precision: a few micrometres at these heights
      const double facets = facet_deviation_m(cone_shape(ConeClass::kOrangeBig), 24);
      int ground_points = 0, off_the_plane = 0;
      std::vector<int> per_cone(track.cones.size() + 1, 0);
      for (size_t i = 0; i < scan.cloud.points.size(); ++i) {
        const Eigen::Vector3d p = in_track(lidar, poses, scan.cloud, scan.cloud.points[i]);
        const int id = scan.labels.cone_id[i];
        // the sigma at the point's range (the range drawn off it by the noise: 1e-4 of 5 sigma)
        const double tolerance =
            5.0 * (sigma + config.range_noise_growth * range_of(scan.cloud.points[i])) *
                (1.0 + 0.1) +
            1e-4;
        if (id == core::PointCloudLabels::kGroundLabel) {
          ASSERT_NEAR(p.z(), ground.height(p.x(), p.y()), tolerance) << "ground point " << i;
          ++ground_points;
          off_the_plane += std::abs(p.z()) > tolerance + 0.02;
          continue;
        }
        const tracks::Cone& cone = track.cone(id);
        const Eigen::Vector3d base(cone.position.x(), cone.position.y(),
                                   ground.height(cone.position.x(), cone.position.y()));
        ASSERT_LT(cone_shape(cone.cls).surface_distance(p - base), tolerance + facets)
            << "cone " << id << " point " << (p - base).transpose();
        ++per_cone[id];
      }
      EXPECT_GT(ground_points, 5000);
      EXPECT_GT(off_the_plane, ground_points / 2);
      for (const tracks::Cone& cone : track.cones) {
        if ((cone.position - core::Vec2(-3.0, 1.0)).norm() < 10.0) {
          EXPECT_GT(per_cone[cone.id], 0) << cone.id;
        }
      }
    }
}

// Grass strips laid on a grade (tracks::lay_on_ground) stay a 6 cm step all along: every point
// on a strip lies at most its height above the ground under it, where a level strip stands out
// of the slope at its downhill end.
TEST(Lidar, GrassLaidOnAGradeFollowsTheGround) {
  tracks::Track track = ring_of_cones();
  track.start = {-43.0, 0.0, 0.0};
  tracks::GroundConfig shape;
  shape.grade_percent = 4.0;
  shape.grade_heading_deg = 0.0;
  const tracks::GroundModel ground(track, shape, 3);
  // strips ahead of the car, along and across the grade
  std::vector<tracks::SceneryObject> strips;
  for (const core::Pose2& at :
       {core::Pose2{6.0, 3.0, 0.0}, core::Pose2{6.0, -3.0, 1.5708}, core::Pose2{9.0, 0.5, 0.0}})
    strips.push_back(tracks::make_scenery_object(core::ClutterClass::kGrassEdge, at));
  const double strip_height = strips[0].height_m;
  Pose3 start = planar_pose(0.0, 0.0, 0.0);
  start.position.z() = ground.height(0.0, 0.0);
  const PoseHistory poses = drive(start, 0.0, 0, 200'000);
  for (const bool laid : {false, true}) {
    std::vector<tracks::SceneryObject> objects = strips;
    if (laid) tracks::lay_on_ground(objects, ground);
    const Lidar lidar(noiseless(), track, objects, ground);
    core::Rng rng(2);
    const LidarScan scan = lidar.sweep(0, poses, rng);
    double highest = 0.0;
    int on_grass = 0;
    for (size_t i = 0; i < scan.cloud.points.size(); ++i) {
      if (core::clutter_of_label(scan.labels.cone_id[i]) != core::ClutterClass::kGrassEdge)
        continue;
      const Eigen::Vector3d p = in_track(lidar, poses, scan.cloud, scan.cloud.points[i]);
      highest = std::max(highest, p.z() - ground.height(p.x(), p.y()));
      ++on_grass;
    }
    ASSERT_GT(on_grass, 50);
    if (laid)
      EXPECT_LT(highest,
                strip_height + 0.002);  // (the grade is a plane: the strip lies flat on it)
    else
      EXPECT_GT(highest, strip_height + 0.02);  // up to 8 cm out of the slope at the downhill end
  }
}

// No ray passes through a long, thin object on the ground: no ground return comes from under a
// grass strip or a fence's feet at any heading, and each strip returns points where
// the rays come down onto it (the traced stretch of a ray is cut to the object's outline about
// its heading, not its disk; an outline turned or too small would let rays through).
TEST(Lidar, NoGroundReturnFromUnderALongThinObjectAtAnyHeading) {
  const tracks::Track track = make_track(
      {{core::Vec2(30.0, 1.5), ConeClass::kBlue}, {core::Vec2(30.0, -1.5), ConeClass::kYellow}});
  std::vector<tracks::SceneryObject> objects;
  const double headings[] = {0.0, 0.5, 1.5708, 2.4, -0.9, 3.0};
  for (int k = 0; k < 6; ++k) {
    const double bearing = 2.0 * std::numbers::pi * k / 6.0 + 0.3;
    const double range = 4.0 + 0.25 * k;  // (where the lower rings come down)
    objects.push_back(tracks::make_scenery_object(
        core::ClutterClass::kGrassEdge,
        {0.6 + range * std::cos(bearing), range * std::sin(bearing), headings[k]}));
  }
  objects.push_back(tracks::make_scenery_object(core::ClutterClass::kFence, {3.0, -9.0, 0.7}));
  // the sensor on the main hoop (from the front wing its rings skip 3.4-10 m), its spot's width
  // on (the rays beside each ray are traced through the same objects), without noise or fading
  LidarConfig config;
  config.mount = LidarConfig::main_hoop_mount();
  config.range_noise_sigma_m = 0.0;
  config.range_noise_growth = 0.0;
  config.intensity_noise_sigma = 0.0;
  config.dropout_probability = 0.0;
  config.detection_range_10pct_m = 0.0;
  ASSERT_GT(config.beam_divergence_mrad, 0.0);
  const Lidar lidar(config, track, objects);
  const PoseHistory poses = drive(Pose3{}, 0.0, 0, 200'000);
  core::Rng rng(5);
  const LidarScan scan = lidar.sweep(0, poses, rng);

  std::vector<int> per_object(objects.size(), 0);
  for (size_t i = 0; i < scan.cloud.points.size(); ++i) {
    const Eigen::Vector3d p = in_track(lidar, poses, scan.cloud, scan.cloud.points[i]);
    const int label = scan.labels.cone_id[i];
    for (size_t k = 0; k < objects.size(); ++k) {
      const tracks::SceneryObject& o = objects[k];
      const Eigen::Matrix3d turn =
          Eigen::AngleAxisd(o.pose.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
      const Eigen::Vector3d local =
          turn.transpose() * (p - Eigen::Vector3d(o.pose.x, o.pose.y, 0.0));
      for (const tracks::ScenePrimitive& part : o.parts) {
        // (a fence's panel stands above the ground: rays pass under it)
        if (part.centre.z() - part.size.z() > 1e-3) continue;
        // inside the solid's outline from above, 2 mm in from its edges
        const Eigen::Vector3d q = part.rotation.transpose() * (local - part.centre);
        if (std::abs(q.x()) > part.size.x() - 2e-3 || std::abs(q.y()) > part.size.y() - 2e-3)
          continue;
        ASSERT_NE(label, core::PointCloudLabels::kGroundLabel)
            << core::to_string(o.cls) << " " << k << ": a ground return from under it at "
            << p.transpose();
        per_object[k] += core::clutter_of_label(label) == o.cls;
      }
    }
  }
  for (size_t k = 0; k < objects.size(); ++k)
    EXPECT_GE(per_object[k], 20) << core::to_string(objects[k].cls) << " " << k;
}

// The flat ground keeps its analytic path: a flat ground model gives the scan of no model,
// bit for bit.
TEST(Lidar, AFlatGroundModelChangesNoPoint) {
  const tracks::Track track = ring_of_cones();
  const tracks::GroundModel flat(track, tracks::GroundConfig{}, 3);
  ASSERT_TRUE(flat.flat());
  const Lidar with(LidarConfig{}, track, {}, flat), without(LidarConfig{}, track);
  const PoseHistory poses = drive(planar_pose(0.0, 0.0, 0.0), 5.0, 0, 200'000);
  core::Rng rng_a(7), rng_b(7);
  EXPECT_TRUE(same_points(with.sweep(0, poses, rng_a), without.sweep(0, poses, rng_b)));
}

}  // namespace
}  // namespace conesim::sensors
