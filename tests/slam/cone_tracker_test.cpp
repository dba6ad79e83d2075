// Tests of the frame-to-frame cone tracker: the Bhattacharyya distance against a hand
// computation, ids that stay with their cone over a drive, colour votes, new and lost cones.

#include "slam/frontend/cone_tracker.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>
#include <set>
#include <vector>

#include "core/rng.hpp"
#include "sensors/lidar.hpp"
#include "sensors/pose_history.hpp"
#include "slam/frontend/lidar_cone_detector.hpp"
#include "tracks/generator.hpp"

namespace conesim::slam::frontend {
namespace {

using core::ConeClass;
using core::ConeObservation;
using core::ConeObservations;
using core::Pose2;
using core::Vec2;

ConeObservation seen(double x, double y, ConeClass cls, double sigma_m = 0.03) {
  ConeObservation o;
  o.position = {x, y};
  o.cls = cls;
  o.covariance = Eigen::Matrix2d::Identity() * sigma_m * sigma_m;
  return o;
}

ConeObservations frame_of(std::vector<ConeObservation> cones) {
  ConeObservations f;
  f.cones = std::move(cones);
  return f;
}

TEST(TrackerConfig, ValidateNamesTheBadKey) {
  EXPECT_EQ(TrackerConfig{}.validate(), "");
  TrackerConfig c;
  c.max_missed_frames = 0;
  EXPECT_EQ(c.validate().rfind("max_missed_frames:", 0), 0u) << c.validate();
  c = {};
  c.max_bhattacharyya = -1.0;
  EXPECT_EQ(c.validate().rfind("max_bhattacharyya:", 0), 0u) << c.validate();
  EXPECT_THROW(ConeTracker{c}, std::invalid_argument);
}

// By hand: A = diag(0.04, 0.01), B = diag(0.02, 0.03), d = (0.2, 0.1). S = diag(0.03, 0.02);
// d' S^-1 d = 0.04 / 0.03 + 0.01 / 0.02 = 11/6, an eighth of it 11/48 = 0.2291667;
// det S = 6e-4, sqrt(det A det B) = sqrt(2.4e-7) = 4.898979e-4, half the log of their ratio
// 0.5 ln(1.2247449) = 0.1013663. Total 0.3305330.
TEST(BhattacharyyaDistance, MatchesAHandComputation) {
  const Eigen::Matrix2d a = Eigen::Vector2d(0.04, 0.01).asDiagonal();
  const Eigen::Matrix2d b = Eigen::Vector2d(0.02, 0.03).asDiagonal();
  EXPECT_NEAR(bhattacharyya_distance({0.0, 0.0}, a, {0.2, 0.1}, b), 0.3305330, 1e-6);
  EXPECT_NEAR(bhattacharyya_distance({0.2, 0.1}, b, {0.0, 0.0}, a), 0.3305330, 1e-6);
  EXPECT_NEAR(bhattacharyya_distance({1.0, 2.0}, a, {1.0, 2.0}, a), 0.0, 1e-12);
  // same shapes: an eighth of the squared Mahalanobis distance
  EXPECT_NEAR(bhattacharyya_distance({0.0, 0.0}, a, {0.2, 0.0}, a), 0.125 * 0.04 / 0.04, 1e-12);
}

// A drive through a slalom-free bend at 10 m/s, frames at 10 Hz: cones on both sides every
// 4.5 m, each seen while it is 0-15 m ahead with 3 cm noise, the odometry off by 2 cm and
// 0.2 degrees per frame. Every cone keeps one id for as long as it is seen, and no two cones
// share one.
TEST(ConeTracker, IdsStayWithTheirConesOverADrive) {
  // the cones along an arc of radius 60 m, left and right of the centre
  std::vector<Vec2> cones;
  const double radius = 60.0;
  for (double s = 0.0; s < 150.0; s += 4.5)
    for (const double side : {1.75, -1.75}) {
      const double a = s / radius, r = radius - side;
      cones.push_back({r * std::sin(a), radius - r * std::cos(a)});
    }

  ConeTracker tracker({});
  core::Rng rng(5);
  std::map<int, std::set<int>> ids_of_cone;
  std::map<int, std::set<int>> cones_of_id;
  for (int frame = 0; frame < 120; ++frame) {
    const double s = frame * 1.0;  // 10 m/s, 0.1 s
    const Pose2 vehicle{radius * std::sin(s / radius), radius - radius * std::cos(s / radius),
                        s / radius};
    ConeObservations f;
    std::vector<int> truth;
    for (size_t k = 0; k < cones.size(); ++k) {
      const Vec2 p = vehicle.inverse_transform(cones[k]);
      if (p.x() < 0.0 || p.x() > 15.0) continue;
      f.cones.push_back(seen(p.x() + core::gaussian(rng, 0.0, 0.03),
                             p.y() + core::gaussian(rng, 0.0, 0.03), ConeClass::kBlue));
      truth.push_back(static_cast<int>(k));
    }
    // odometry: the true step with a small error
    const Pose2 motion{1.0 * std::cos(0.5 / radius) + core::gaussian(rng, 0.0, 0.02),
                       1.0 * std::sin(0.5 / radius) + core::gaussian(rng, 0.0, 0.02),
                       1.0 / radius + core::gaussian(rng, 0.0, 0.2 * std::numbers::pi / 180)};
    const ConeObservations out = tracker.update(f, motion);
    ASSERT_EQ(out.cones.size(), f.cones.size());
    for (size_t i = 0; i < out.cones.size(); ++i) {
      ids_of_cone[truth[i]].insert(out.cones[i].track_id);
      cones_of_id[out.cones[i].track_id].insert(truth[i]);
    }
  }
  ASSERT_GT(ids_of_cone.size(), 40u);
  for (const auto& [cone, ids] : ids_of_cone) EXPECT_EQ(ids.size(), 1u) << "cone " << cone;
  for (const auto& [id, owners] : cones_of_id) EXPECT_EQ(owners.size(), 1u) << "id " << id;
}

// A blue cone seen blue five times and yellow once stays blue; unknown frames do not vote, and
// until a colour is seen the class is unknown.
TEST(ConeTracker, ColourVoteOutweighsASingleWrongColour) {
  ConeTracker tracker({});
  const Pose2 still;
  EXPECT_EQ(tracker.update(frame_of({seen(5, 1, ConeClass::kUnknown)}), still).cones[0].cls,
            ConeClass::kUnknown);
  for (int k = 0; k < 5; ++k)
    EXPECT_EQ(tracker.update(frame_of({seen(5, 1, ConeClass::kBlue)}), still).cones[0].cls,
              ConeClass::kBlue);
  const ConeObservations wrong = tracker.update(frame_of({seen(5, 1, ConeClass::kYellow)}), still);
  EXPECT_EQ(wrong.cones[0].cls, ConeClass::kBlue);
  for (int k = 0; k < 3; ++k)
    EXPECT_EQ(tracker.update(frame_of({seen(5, 1, ConeClass::kUnknown)}), still).cones[0].cls,
              ConeClass::kBlue);
  EXPECT_EQ(wrong.cones[0].track_id, 0);
}

// A cone that appears gets a new id; the cones already tracked keep theirs, also when the car
// has moved between the frames (the tracks are predicted with the motion).
TEST(ConeTracker, ANewConeGetsANewId) {
  ConeTracker tracker({});
  const ConeObservations first =
      tracker.update(frame_of({seen(6, 2, ConeClass::kBlue), seen(6, -2, ConeClass::kYellow)}), {});
  const ConeObservations second =
      tracker.update(frame_of({seen(9, 2, ConeClass::kBlue), seen(5, 2, ConeClass::kBlue),
                               seen(5, -2, ConeClass::kYellow)}),
                     {1.0, 0.0, 0.0});
  EXPECT_EQ(second.cones[1].track_id, first.cones[0].track_id);
  EXPECT_EQ(second.cones[2].track_id, first.cones[1].track_id);
  EXPECT_NE(second.cones[0].track_id, first.cones[0].track_id);
  EXPECT_NE(second.cones[0].track_id, first.cones[1].track_id);
  EXPECT_EQ(tracker.live_tracks(), 3);
}

// A track missed fewer than max_missed_frames times comes back with its id; one missed that
// many times is dropped, and the cone starts a new track when seen again.
TEST(ConeTracker, DropsATrackAfterMaxMissedFrames) {
  TrackerConfig config;
  config.max_missed_frames = 3;
  ConeTracker tracker(config);
  const ConeObservations a = frame_of({seen(5, 1, ConeClass::kBlue)});
  const int id = tracker.update(a, {}).cones[0].track_id;
  tracker.update({}, {});
  tracker.update({}, {});
  EXPECT_EQ(tracker.update(a, {}).cones[0].track_id, id);
  for (int k = 0; k < 3; ++k) tracker.update({}, {});
  EXPECT_EQ(tracker.live_tracks(), 0);
  EXPECT_NE(tracker.update(a, {}).cones[0].track_id, id);
}

// Two tracks 1 m apart across; in the next frame the first cone is seen 0.55 m off towards the
// second, the second 0.9 m off away from it. Pair by pair from the closest, the first
// observation would take the second track (0.45 m) and push the second cone onto a new one (a
// swap); the least total distance keeps both on their own tracks.
TEST(ConeTracker, AJointAssignmentAvoidsASwap) {
  ConeTracker tracker({});
  const ConeObservations first = tracker.update(
      frame_of({seen(10, 0.0, ConeClass::kBlue, 0.3), seen(10, 1.0, ConeClass::kBlue, 0.3)}), {});
  const ConeObservations second = tracker.update(
      frame_of({seen(10, 0.55, ConeClass::kBlue, 0.3), seen(10, 1.9, ConeClass::kBlue, 0.3)}),
      {});
  EXPECT_EQ(second.cones[0].track_id, first.cones[0].track_id);
  EXPECT_EQ(second.cones[1].track_id, first.cones[1].track_id);
  EXPECT_EQ(tracker.live_tracks(), 2);
}

// Two cones closer than the gate allows for each other's noise: each observation goes to its
// own track (the nearest pair first), not both to one.
TEST(ConeTracker, AssignsEachObservationToItsNearestTrack) {
  ConeTracker tracker({});
  const ConeObservations first = tracker.update(
      frame_of({seen(5, 0.0, ConeClass::kBlue), seen(5, 0.5, ConeClass::kBlue)}), {});
  const ConeObservations second = tracker.update(
      frame_of({seen(5, 0.52, ConeClass::kBlue), seen(5, 0.03, ConeClass::kBlue)}), {});
  EXPECT_EQ(second.cones[0].track_id, first.cones[1].track_id);
  EXPECT_EQ(second.cones[1].track_id, first.cones[0].track_id);
}

// The LiDAR front-end end to end: a lap and a half of a generated circuit at 10 m/s, a sweep
// every 100 ms into the detector, the detections into the tracker with the true motion between
// sweep ends. Scored with the labels (each detection's cone is the majority label of its
// points): a track id never covers two cones, a cone keeps its id while it stays in view, and
// after the votes the class is right for >= 99 % of the observations within 10 m.
TEST(ConeTracker, TracksLidarConesAroundACircuit) {
  const tracks::Track track = tracks::generate_circuit(7);
  const sensors::LidarConfig lidar_config;
  const sensors::Lidar lidar(lidar_config, track);
  const LidarConeDetector detector({}, lidar_config.mount);
  ConeTracker tracker({});

  // the drive: along the centre line at 10 m/s, heading along a 3 m chord
  const std::vector<Vec2>& line = track.centre_line;
  std::vector<double> along{0.0};
  for (size_t i = 1; i <= line.size(); ++i)
    along.push_back(along.back() + (line[i % line.size()] - line[i - 1]).norm());
  auto point_at = [&](double s) {
    s = std::fmod(s, along.back());
    const size_t i =
        static_cast<size_t>(std::upper_bound(along.begin(), along.end(), s) - along.begin()) - 1;
    const double f = (s - along[i]) / (along[i + 1] - along[i]);
    return Vec2(line[i] + f * (line[(i + 1) % line.size()] - line[i]));
  };
  auto pose_at = [&](double t) {
    const double s = 10.0 * t + along.back();
    const Vec2 p = point_at(s), d = point_at(s + 1.5) - point_at(s - 1.5);
    core::Pose3 q;
    q.position = {p.x(), p.y(), 0.0};
    q.orientation = Eigen::AngleAxisd(std::atan2(d.y(), d.x()), Eigen::Vector3d::UnitZ());
    return q;
  };
  const double duration_s = 1.5 * along.back() / 10.0;
  sensors::PoseHistory poses(core::kUsPerSecond);
  core::Rng rng(2);

  std::map<int, int> cone_of_id;       // track id -> cone (first seen)
  std::map<int, int> last_id_of_cone;  // cone -> id at its last sighting
  std::map<int, int> last_frame_of_cone;
  int impure = 0, switches = 0, observations = 0, near = 0, near_right = 0, near_unknown = 0;
  core::Pose2 previous_end;
  core::TimeUs next_pose = 0;
  int frame = 0;
  for (core::TimeUs start = 0; core::to_seconds(start) < duration_s; start += 100'000, ++frame) {
    for (; next_pose <= start + 110'000; next_pose += 1000)
      poses.push(next_pose, pose_at(core::to_seconds(next_pose)));
    const sensors::LidarScan scan = lidar.sweep(start, poses, rng);

    // odometry over the sweep (speed and yaw rate) and between sweep ends, from the truth
    const core::TimeUs end = start + 100'000;
    const core::Pose2 end_pose = poses.at(end).planar(), start_pose = poses.at(start).planar();
    const double yaw_rate = core::normalize_angle(end_pose.yaw - start_pose.yaw) / 0.1;
    const LidarDetections found = detector.detect(scan.cloud, {10.0, yaw_rate});
    const core::ConeObservations out =
        tracker.update(found.observations(), previous_end.inverse().compose(end_pose));
    previous_end = end_pose;
    ASSERT_EQ(out.cones.size(), found.cones.size());

    for (size_t k = 0; k < out.cones.size(); ++k) {
      std::map<int, int> votes;
      for (const int i : found.cones[k].point_indices) ++votes[scan.labels.cone_id[i]];
      const int cone = std::max_element(votes.begin(), votes.end(), [](auto& a, auto& b) {
                         return a.second < b.second;
                       })->first;
      if (cone < 0) continue;
      ++observations;
      const int id = out.cones[k].track_id;
      if (!cone_of_id.count(id)) cone_of_id[id] = cone;
      if (cone_of_id[id] != cone) ++impure;
      // a new id for a cone seen in the previous frame is a switch
      if (last_frame_of_cone.count(cone) && last_frame_of_cone[cone] == frame - 1 &&
          last_id_of_cone[cone] != id)
        ++switches;
      last_id_of_cone[cone] = id;
      last_frame_of_cone[cone] = frame;
      if (out.cones[k].position.norm() < 10.0) {
        ++near;
        if (out.cones[k].cls == track.cone(cone).cls) ++near_right;
        if (out.cones[k].cls == ConeClass::kUnknown) ++near_unknown;
      }
    }
  }
  std::printf(
      "[tracked] %d frames, %d observations, %zu ids; impure %d, id switches %d; class "
      "after votes within 10 m right %d/%d (%d unknown)\n",
      frame, observations, cone_of_id.size(), impure, switches, near_right, near, near_unknown);
  ASSERT_GT(observations, 1000);
  EXPECT_EQ(impure, 0);
  EXPECT_LE(switches, observations / 1000);
  EXPECT_GE(near_right, 0.99 * near);
}

}  // namespace
}  // namespace conesim::slam::frontend
