// The association methods on a constructed frame where the pose is uncertain along x: pairing
// each cone with its nearest landmark is individually fine and jointly impossible (the two
// innovations ask for opposite pose corrections); the joint methods must see that.

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <chrono>

#include "slam/association/methods.hpp"
#include "slam/association/ml_association.hpp"

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
  int candidate_track(int j) const override {
    return landmark_tracks_.empty() ? -1 : landmark_tracks_[j];
  }
  int observation_label(int i) const override { return labels_.empty() ? -1 : labels_[i]; }
  int candidate_label(int j) const override {
    return landmark_labels_.empty() ? -1 : landmark_labels_[j];
  }

  std::vector<int> tracks_, landmark_tracks_, labels_, landmark_labels_;

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

TEST(AssociationMethods, TrackingAidedFollowsTheTrackWithinItsLooseGate) {
  Frame f = ambiguous();
  f.tracks_ = {7, 8};
  f.landmark_tracks_ = {7, -1, 8, -1};
  EXPECT_EQ(associate(with(AssociationMethod::kTrackingAided), f), (std::vector<int>{0, 2}));
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
