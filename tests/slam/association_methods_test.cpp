// The association methods on a constructed frame where the pose is uncertain along x: pairing
// each cone with its nearest landmark is individually fine and jointly impossible (the two
// innovations ask for opposite pose corrections); the joint methods must see that.

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "slam/association/methods.hpp"
#include "slam/association/ml_association.hpp"
#include "slam/association/track_bindings.hpp"

namespace conesim::slam {
namespace {

// the pose at the origin with sigma_x (m), landmarks and observations in the map frame, the
// measurement noise sigma_r (m) on both axes
class Frame : public AssociationProblem {
 public:
  Frame(double sigma_x, double sigma_r, std::vector<core::Vec2> landmarks,
        std::vector<core::Vec2> observations)
      : landmarks_(std::move(landmarks)), observations_(std::move(observations)) {
    pose_cov_ = Eigen::Vector3d(sigma_x * sigma_x, 1e-6, 1e-8).asDiagonal();
    r_ = Eigen::Matrix2d::Identity() * sigma_r * sigma_r;
  }
  int observations() const override { return static_cast<int>(observations_.size()); }
  int candidates() const override { return static_cast<int>(landmarks_.size()); }
  Eigen::Vector2d innovation(int i, int j) const override {
    return observations_[i] - predict_observation({}, landmarks_[j]);
  }
  Eigen::Matrix2d innovation_covariance(int i, int j, int k, int m) const override {
    Eigen::Matrix<double, 2, 3> a, b;
    predict_observation({}, landmarks_[j], &a);
    predict_observation({}, landmarks_[m], &b);
    Eigen::Matrix2d s = a * pose_cov_ * b.transpose();
    if (i == k) s += r_;
    return s;
  }
  core::Vec2 observation_in_map(int i) const override { return observations_[i]; }
  core::Vec2 candidate_position(int j) const override { return landmarks_[j]; }
  bool allowed(int, int) const override { return true; }
  int observation_track(int i) const override { return tracks_.empty() ? -1 : tracks_[i]; }
  int candidate_landmark(int j) const override { return j; }
  int observation_label(int i) const override { return labels_.empty() ? -1 : labels_[i]; }
  int candidate_label(int j) const override {
    return landmark_labels_.empty() ? -1 : landmark_labels_[j];
  }

  std::vector<int> tracks_, labels_, landmark_labels_;

 private:
  std::vector<core::Vec2> landmarks_, observations_;
  Eigen::Matrix3d pose_cov_;
  Eigen::Matrix2d r_;
};

// landmarks 0.8 m apart along x in two rows; the cones seen 0.45/0.35 m off so that the nearest
// landmark of each asks for pose corrections of -0.35 and +0.35 m
Frame ambiguous() {
  return Frame(0.5, 0.05, {{10.0, 0.0}, {10.8, 0.0}, {10.0, 4.0}, {10.8, 4.0}},
               {{10.45, 0.0}, {10.35, 4.0}});
}

std::vector<std::pair<int, int>> pairs_of(const std::vector<int>& pairing) {
  std::vector<std::pair<int, int>> out;
  for (size_t i = 0; i < pairing.size(); ++i)
    if (pairing[i] >= 0) out.emplace_back(static_cast<int>(i), pairing[i]);
  return out;
}

AssociationParams with(AssociationMethod m) {
  AssociationParams p;
  p.method = m;
  return p;
}

TEST(AssociationMethods, IndividualMethodsTakeTheNearestAndBreakJointCompatibility) {
  const Frame f = ambiguous();
  for (AssociationMethod m :
       {AssociationMethod::kMaximumLikelihood, AssociationMethod::kNearestNeighbour}) {
    const std::vector<int> pairing = associate(with(m), f);
    EXPECT_EQ(pairing, (std::vector<int>{1, 2})) << to_string(m);
    // jointly the two innovations cannot both hold: far beyond the 99 % gate of 4 dof
    EXPECT_GT(joint_mahalanobis2(f, pairs_of(pairing)), chi2_quantile(0.99, 4));
  }
}

TEST(AssociationMethods, JcbbAndScnnKeepThePairingsJointlyCompatible) {
  const Frame f = ambiguous();
  for (AssociationMethod m : {AssociationMethod::kJcbb, AssociationMethod::kScnn}) {
    const std::vector<int> pairing = associate(with(m), f);
    ASSERT_EQ(pairs_of(pairing).size(), 2u) << to_string(m);
    // both cones on the same side: one pose correction explains them
    const bool both_left = pairing == std::vector<int>{0, 2};
    const bool both_right = pairing == std::vector<int>{1, 3};
    EXPECT_TRUE(both_left || both_right) << to_string(m);
    EXPECT_LT(joint_mahalanobis2(f, pairs_of(pairing)), chi2_quantile(0.99, 4));
  }
  // and its joint distance is far below that of the nearest landmarks' pairing
  EXPECT_LT(joint_mahalanobis2(f, pairs_of(associate(with(AssociationMethod::kJcbb), f))),
            joint_mahalanobis2(f, {{0, 1}, {1, 2}}));
}

TEST(AssociationMethods, JcbbPairsTheMostObservationsItCan) {
  // a third cone that only landmark 4 explains, and clutter far from everything
  const Frame f(0.5, 0.05, {{10.0, 0.0}, {10.8, 0.0}, {10.0, 4.0}, {10.8, 4.0}, {15.0, 2.0}},
                {{10.45, 0.0}, {10.35, 4.0}, {15.4, 2.0}, {30.0, 30.0}});
  const std::vector<int> pairing = associate(with(AssociationMethod::kJcbb), f);
  EXPECT_EQ(pairs_of(pairing).size(), 3u);
  EXPECT_EQ(pairing[2], 4);
  EXPECT_EQ(pairing[3], -1);
  // the +0.4 m of the third cone agrees with the left pairing's +0.45/+0.35
  EXPECT_EQ(pairing[0], 0);
  EXPECT_EQ(pairing[1], 2);
}

// Tracking-aided association on two cones 0.8 m apart across (landmarks 0 and 1), seen with
// 0.3 m noise: one observation alone cannot tell them apart well, a track's history can.
Frame two_close_cones(double observed_y) {
  return Frame(0.01, 0.3, {{10.0, 0.0}, {10.0, 0.8}}, {{10.0, observed_y}});
}

// the track's evidence pointed at `landmark` for `frames` frames
void vote(TrackBindings& bindings, int track, int landmark, int frames) {
  for (int k = 0; k < frames; ++k) bindings.record({track}, {landmark});
}

// the track's prior alone, every observation paired (its patience is tested below)
AssociationParams impatient_tracking() {
  AssociationParams p = with(AssociationMethod::kTrackingAided);
  p.ambiguity_margin = 0.0;
  return p;
}

TEST(TrackingAided, ATrackHistoryDecidesBetweenTwoCloseCones) {
  // 0.45 m from landmark 0, 0.35 m from landmark 1: maximum likelihood takes landmark 1
  Frame f = two_close_cones(0.45);
  f.tracks_ = {7};
  const AssociationParams tracking = impatient_tracking();
  EXPECT_EQ(associate(with(AssociationMethod::kMaximumLikelihood), f), (std::vector<int>{1}));
  // without a memory, or with a fresh track, tracking-aided is maximum likelihood
  EXPECT_EQ(associate(tracking, f), (std::vector<int>{1}));
  TrackBindings bindings;
  EXPECT_EQ(associate(tracking, f, &bindings), (std::vector<int>{1}));
  // five frames of the track on landmark 0 outweigh the 0.1 m
  vote(bindings, 7, 0, 5);
  EXPECT_EQ(bindings.bound_landmark(7), 0);
  std::vector<int> evidence;
  EXPECT_EQ(associate(tracking, f, &bindings, &evidence), (std::vector<int>{0}));
  // the frame's own evidence is the maximum-likelihood pairing, not the track's
  EXPECT_EQ(evidence, (std::vector<int>{1}));
  // another track's history says nothing about this observation
  f.tracks_ = {8};
  EXPECT_EQ(associate(tracking, f, &bindings), (std::vector<int>{1}));
}

TEST(TrackingAided, ATrackThatSwappedConesFollowsTheEvidence) {
  TrackBindings bindings;
  vote(bindings, 7, 0, 5);
  const AssociationParams tracking = impatient_tracking();
  // the track's observation now sits on landmark 1: d^2 7.1 to landmark 0 (inside the gate)
  // against 0, more than the track's prior makes up
  Frame on_one = two_close_cones(0.8);
  on_one.tracks_ = {7};
  EXPECT_EQ(associate(tracking, on_one, &bindings), (std::vector<int>{1}));
  // and beyond the gate the prior never pairs
  Frame beyond = two_close_cones(1.0);
  beyond.tracks_ = {7};
  EXPECT_EQ(associate(tracking, beyond, &bindings), (std::vector<int>{1}));
  // the evidence keeps pointing at landmark 1: within half the memory the binding moves there,
  // and once the track's frames on landmark 0 have faded (a memory's worth) its ambiguous
  // observations go with it
  vote(bindings, 7, 1, 5);
  EXPECT_EQ(bindings.bound_landmark(7), 1);
  Frame ambiguous_one = two_close_cones(0.35);
  ambiguous_one.tracks_ = {7};
  EXPECT_EQ(associate(with(AssociationMethod::kMaximumLikelihood), ambiguous_one),
            (std::vector<int>{0}));
  vote(bindings, 7, 1, 5);
  EXPECT_EQ(associate(tracking, ambiguous_one, &bindings), (std::vector<int>{1}));
}

TEST(TrackingAided, OneWrongFrameDoesNotBindATrack) {
  // a fresh track paired once with the wrong landmark (noise at long range)
  TrackBindings bindings;
  vote(bindings, 9, 1, 1);
  // its next observation, clearly nearer landmark 0 (0.2 m against 0.6 m), still goes there
  Frame f = two_close_cones(0.2);
  f.tracks_ = {9};
  EXPECT_EQ(associate(impatient_tracking(), f, &bindings), (std::vector<int>{0}));
  // and three frames of evidence for landmark 0 bind it there
  vote(bindings, 9, 0, 3);
  EXPECT_EQ(bindings.bound_landmark(9), 0);
}

TEST(TrackingAided, AnAmbiguousObservationWaitsUntilItsTrackDecides) {
  // 0.3 m from landmark 0 and 0.5 m from landmark 1 with 0.3 m noise: maximum likelihood takes
  // landmark 0 at odds of only 2.4 to 1 (cost 1.0 against 2.8)
  Frame f = two_close_cones(0.3);
  f.tracks_ = {7};
  const AssociationParams tracking = with(AssociationMethod::kTrackingAided);
  ASSERT_NEAR(tracking.ambiguity_margin, 2.0 * std::log(10.0), 1e-12);
  EXPECT_EQ(associate(with(AssociationMethod::kMaximumLikelihood), f), (std::vector<int>{0}));
  // a fresh track's observation waits for a later, nearer frame of its track
  TrackBindings bindings;
  EXPECT_EQ(associate(tracking, f, &bindings), (std::vector<int>{-1}));
  // an observation without a track has no later frame to wait for: paired as by ML
  f.tracks_ = {-1};
  EXPECT_EQ(associate(tracking, f, &bindings), (std::vector<int>{0}));
  // five frames of the track on landmark 0 make it ten times likelier than landmark 1: paired
  f.tracks_ = {7};
  vote(bindings, 7, 0, 5);
  EXPECT_EQ(associate(tracking, f, &bindings), (std::vector<int>{0}));
  // a track whose history says landmark 1 while the frame says landmark 0 waits
  TrackBindings other;
  vote(other, 7, 1, 5);
  EXPECT_EQ(associate(tracking, f, &other), (std::vector<int>{-1}));
  // an unambiguous observation of a fresh track is paired at once (0.05 m from landmark 0)
  Frame clear = two_close_cones(0.05);
  clear.tracks_ = {8};
  EXPECT_EQ(associate(tracking, clear, &bindings), (std::vector<int>{0}));
}

TEST(TrackingAided, AWaitingObservationLeavesItsLandmarkToTheOthers) {
  // observation 0 (a fresh track) lies between landmarks 0 and 1, a little nearer landmark 1;
  // observation 1 (no track) is 0.55 m from landmark 1 and far from the rest. Greedy ML gives
  // landmark 1 to observation 0 and leaves observation 1 unpaired; once observation 0 waits,
  // observation 1 gets landmark 1.
  Frame f(0.01, 0.3, {{10.0, 0.0}, {10.0, 0.8}}, {{10.0, 0.45}, {10.0, 1.35}});
  f.tracks_ = {7, -1};
  EXPECT_EQ(associate(with(AssociationMethod::kMaximumLikelihood), f),
            (std::vector<int>{1, -1}));
  TrackBindings bindings;
  EXPECT_EQ(associate(with(AssociationMethod::kTrackingAided), f, &bindings),
            (std::vector<int>{-1, 1}));
}

TEST(TrackBindings, ForgetsLostTracksAndRejectsABadMemory) {
  TrackBindings bindings;
  vote(bindings, 3, 5, 2);
  EXPECT_EQ(bindings.tracks(), 1);
  EXPECT_GT(bindings.bonus(3, 5), 0.0);
  EXPECT_EQ(bindings.bonus(3, 6), 0.0);
  EXPECT_EQ(bindings.bonus(-1, 5), 0.0);
  // two votes: 1 + (1 - 1/10), the prior 2 ln(1 + 1.9)
  EXPECT_NEAR(bindings.bonus(3, 5), 2.0 * std::log(2.9), 1e-12);
  for (int k = 0; k <= TrackBindings::kForgetFrames; ++k) bindings.record({4}, {-1});
  EXPECT_EQ(bindings.bound_landmark(3), -1);
  EXPECT_EQ(bindings.tracks(), 1);
  EXPECT_THROW(TrackBindings(0.5), std::invalid_argument);
}

TEST(AssociationMethods, IdealPairsByTheLabelsAlone) {
  // the labels say cone 0 is landmark 1's and cone 1 is landmark 3's, against the geometry;
  // an unlabelled (clutter) observation stays unpaired
  Frame f(0.5, 0.05, {{10.0, 0.0}, {10.8, 0.0}, {10.0, 4.0}, {10.8, 4.0}},
          {{10.0, 0.0}, {10.0, 4.0}, {10.8, 0.0}});
  f.labels_ = {11, 13, -1};
  f.landmark_labels_ = {10, 11, 12, 13};
  EXPECT_EQ(associate(with(AssociationMethod::kIdeal), f), (std::vector<int>{1, 3, -1}));
}

TEST(AssociationMethods, NamesRoundTripAndChiSquareQuantilesAreClose) {
  for (AssociationMethod m :
       {AssociationMethod::kNearestNeighbour, AssociationMethod::kMaximumLikelihood,
        AssociationMethod::kScnn, AssociationMethod::kJcbb, AssociationMethod::kTrackingAided})
    EXPECT_EQ(association_from_string(to_string(m)), m);
  EXPECT_FALSE(association_from_string("guess").has_value());
  // tabulated 99 % quantiles: 2 dof 9.210, 4 dof 13.277, 10 dof 23.209, 40 dof 63.691
  EXPECT_NEAR(chi2_quantile(0.99, 2), 9.210, 0.1);
  EXPECT_NEAR(chi2_quantile(0.99, 4), 13.277, 0.1);
  EXPECT_NEAR(chi2_quantile(0.99, 10), 23.209, 0.1);
  EXPECT_NEAR(chi2_quantile(0.99, 40), 63.691, 0.2);
}

}  // namespace
}  // namespace conesim::slam
