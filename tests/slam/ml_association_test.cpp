// Data association: ML with the individual-compatibility gate on a synthetic map seen with the
// cone sensor's noise; an outlier is rejected by the gate, a class mismatch is rejected, an
// observation far from everything starts a new landmark, and track ids associate directly.

#include "slam/association/ml_association.hpp"

#include <gtest/gtest.h>

#include "core/rng.hpp"

namespace conesim::slam {
namespace {

using core::ConeClass;

// a noisy observation of a map point from a pose, with the cone sensor's polar noise
core::ConeObservation observe(const core::Pose2& pose, const core::Vec2& point, ConeClass cls,
                              core::Rng& rng) {
  const core::Vec2 local = pose.inverse_transform(point);
  const double r = local.norm() + core::gaussian(rng, 0.0, 0.05);
  const double b = std::atan2(local.y(), local.x()) + core::gaussian(rng, 0.0, 0.007);
  core::ConeObservation o;
  o.position = {r * std::cos(b), r * std::sin(b)};
  Eigen::Matrix2d j;
  j << std::cos(b), -r * std::sin(b), std::sin(b), r * std::cos(b);
  o.covariance = j * Eigen::Vector2d(0.05 * 0.05, 0.007 * 0.007).asDiagonal() * j.transpose();
  o.cls = cls;
  return o;
}

// two lanes of cones 3.5 m apart, 4.5 m spacing, blue left and yellow right
std::vector<LandmarkCandidate> lane_map() {
  std::vector<LandmarkCandidate> map;
  for (int i = 0; i < 8; ++i) {
    for (const int side : {1, -1}) {
      LandmarkCandidate c;
      c.id = static_cast<int>(map.size());
      c.position = {4.5 * i, 1.75 * side};
      c.covariance = Eigen::Matrix2d::Identity() * 0.02 * 0.02;
      c.class_votes[static_cast<int>(side > 0 ? ConeClass::kBlue : ConeClass::kYellow)] = 5;
      map.push_back(c);
    }
  }
  return map;
}

TEST(PredictObservation, JacobiansMatchNumerical) {
  const core::Pose2 pose{1.0, -2.0, 0.6};
  const core::Vec2 landmark(7.0, 3.0);
  Eigen::Matrix<double, 2, 3> h_pose;
  Eigen::Matrix2d h_landmark;
  predict_observation(pose, landmark, &h_pose, &h_landmark);
  const double h = 1e-6;
  for (int k = 0; k < 3; ++k) {
    core::Pose2 plus = pose, minus = pose;
    (k == 0 ? plus.x : k == 1 ? plus.y : plus.yaw) += h;
    (k == 0 ? minus.x : k == 1 ? minus.y : minus.yaw) -= h;
    const core::Vec2 col =
        (predict_observation(plus, landmark) - predict_observation(minus, landmark)) / (2 * h);
    EXPECT_LT((col - h_pose.col(k)).norm(), 1e-6) << "pose column " << k;
  }
  for (int k = 0; k < 2; ++k) {
    core::Vec2 plus = landmark, minus = landmark;
    plus[k] += h;
    minus[k] -= h;
    const core::Vec2 col =
        (predict_observation(pose, plus) - predict_observation(pose, minus)) / (2 * h);
    EXPECT_LT((col - h_landmark.col(k)).norm(), 1e-6) << "landmark column " << k;
  }
}

TEST(MlAssociation, CorrectOnANoisySyntheticMap) {
  // many frames from poses along the lane, each seeing the cones ahead within 15 m
  const std::vector<LandmarkCandidate> map = lane_map();
  core::Rng rng(11);
  int correct = 0, wrong = 0, total = 0;
  for (int frame = 0; frame < 200; ++frame) {
    const core::Pose2 pose{core::uniform(rng, -2.0, 15.0), core::uniform(rng, -0.5, 0.5),
                           core::uniform(rng, -0.2, 0.2)};
    core::ConeObservations obs;
    std::vector<int> truth;
    for (const LandmarkCandidate& c : map) {
      const core::Vec2 local = pose.inverse_transform(c.position);
      if (local.x() < 1.0 || local.norm() > 15.0) continue;
      const bool colour = core::bernoulli(rng, 0.5);
      obs.cones.push_back(observe(pose, c.position,
                                  colour ? voted_class(c.class_votes) : ConeClass::kUnknown, rng));
      truth.push_back(c.id);
    }
    const std::vector<Association> a = associate({}, pose, nullptr, map, obs, true);
    for (size_t i = 0; i < a.size(); ++i) {
      ++total;
      if (a[i].kind != Association::Kind::kMatched) continue;
      (a[i].landmark_id == truth[i] ? correct : wrong)++;
    }
  }
  // with 5 cm / 7 mrad noise and cones 3.5 m apart no association is wrong, and the 99 % gate
  // turns away about 1 % of the true ones (never more than 3 %)
  ASSERT_GT(total, 1000);
  EXPECT_EQ(wrong, 0);
  EXPECT_GE(correct, 0.97 * total);
}

TEST(MlAssociation, OutlierIsRejectedByTheGate) {
  // an observation 60 cm off a landmark: far outside the gate, too close to start a new one
  const std::vector<LandmarkCandidate> map = lane_map();
  core::ConeObservations obs;
  core::ConeObservation o;
  o.position = core::Vec2(9.0, 1.75 + 0.6);
  o.covariance = Eigen::Matrix2d::Identity() * 0.05 * 0.05;
  obs.cones.push_back(o);
  const std::vector<Association> a = associate({}, {}, nullptr, map, obs, true);
  EXPECT_EQ(a[0].kind, Association::Kind::kRejected);
  EXPECT_GT(mahalanobis2({}, nullptr, map[4], o), AssociationConfig{}.gate_chi2);
}

TEST(MlAssociation, ClassMismatchIsRejectedAndUnknownMatchesAnything) {
  const std::vector<LandmarkCandidate> map = lane_map();
  core::ConeObservations obs;
  core::ConeObservation o;
  o.position = map[4].position;  // exactly on a blue cone
  o.covariance = Eigen::Matrix2d::Identity() * 0.05 * 0.05;
  o.cls = ConeClass::kYellow;
  obs.cones.push_back(o);
  EXPECT_EQ(associate({}, {}, nullptr, map, obs, true)[0].kind, Association::Kind::kRejected);
  obs.cones[0].cls = ConeClass::kUnknown;
  const Association a = associate({}, {}, nullptr, map, obs, true)[0];
  EXPECT_EQ(a.kind, Association::Kind::kMatched);
  EXPECT_EQ(a.landmark_id, map[4].id);
  EXPECT_EQ(a.code(), map[4].id);
  // a landmark with a single colour vote does not yet veto the other colour
  EXPECT_TRUE(class_compatible(ConeClass::kYellow, {1, 0, 0, 0, 0}, 2));
  EXPECT_FALSE(class_compatible(ConeClass::kYellow, {3, 0, 0, 0, 0}, 2));
}

TEST(MlAssociation, FarObservationStartsANewLandmarkUnlessTheMapIsFixed) {
  const std::vector<LandmarkCandidate> map = lane_map();
  core::ConeObservations obs;
  core::ConeObservation o;
  o.position = core::Vec2(6.75, 6.0);
  obs.cones.push_back(o);
  const Association a = associate({}, {}, nullptr, map, obs, true)[0];
  EXPECT_EQ(a.kind, Association::Kind::kNew);
  EXPECT_EQ(a.code(), -1);
  EXPECT_EQ(associate({}, {}, nullptr, map, obs, false)[0].kind, Association::Kind::kRejected);
}

TEST(MlAssociation, TrackingAidedHoldsBackAnAmbiguousObservationOfATrack) {
  // two cones 0.8 m apart, an observation with 0.3 m noise 0.3 m from one and 0.5 m from the
  // other: ML pairs it with the nearer at odds of 2.4 to 1
  std::vector<LandmarkCandidate> map(2);
  for (int k = 0; k < 2; ++k) {
    map[k].id = 10 + k;
    map[k].position = {10.0, 0.8 * k};
    map[k].covariance = Eigen::Matrix2d::Identity() * 1e-4;
  }
  core::ConeObservations obs;
  core::ConeObservation o;
  o.position = {10.0, 0.3};
  o.covariance = Eigen::Matrix2d::Identity() * 0.09;
  o.track_id = 4;
  obs.cones.push_back(o);
  TrackBindings fresh;
  // with the tracks, a fresh track's ambiguous observation waits (rejected, never a new one)
  const Association waits = associate({}, {}, nullptr, map, obs, true, &fresh)[0];
  EXPECT_EQ(waits.kind, Association::Kind::kRejected);
  // without the tracks, or without a track id, or with no margin, it is paired as before
  EXPECT_EQ(associate({}, {}, nullptr, map, obs, true)[0].landmark_id, 10);
  AssociationConfig impatient;
  impatient.ambiguity_margin = 0.0;
  EXPECT_EQ(associate(impatient, {}, nullptr, map, obs, true, &fresh)[0].landmark_id, 10);
  obs.cones[0].track_id = -1;
  EXPECT_EQ(associate({}, {}, nullptr, map, obs, true, &fresh)[0].landmark_id, 10);
  // a track that followed cone 10 for five frames makes it ten times likelier: paired
  obs.cones[0].track_id = 4;
  TrackBindings followed;
  for (int k = 0; k < 5; ++k) followed.record({4}, {10});
  const Association paired = associate({}, {}, nullptr, map, obs, true, &followed)[0];
  EXPECT_EQ(paired.kind, Association::Kind::kMatched);
  EXPECT_EQ(paired.landmark_id, 10);
}

TEST(MlAssociation, OneLandmarkPerObservation) {
  // two observations on the same cone: the likelier wins, the other is rejected
  const std::vector<LandmarkCandidate> map = lane_map();
  core::ConeObservations obs;
  core::ConeObservation o;
  o.covariance = Eigen::Matrix2d::Identity() * 0.05 * 0.05;
  o.position = map[4].position + core::Vec2(0.02, 0.0);
  obs.cones.push_back(o);
  o.position = map[4].position + core::Vec2(0.08, 0.0);
  obs.cones.push_back(o);
  const std::vector<Association> a = associate({}, {}, nullptr, map, obs, true);
  EXPECT_EQ(a[0].kind, Association::Kind::kMatched);
  EXPECT_EQ(a[1].kind, Association::Kind::kRejected);
}

}  // namespace
}  // namespace conesim::slam
