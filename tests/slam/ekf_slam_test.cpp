// EKF SLAM: its hand-written Jacobians against numerical ones, and two laps of a generated
// circuit with the default cone sensor and noisy odometry, scored against the truth.

#include "slam/backends/ekf_slam.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cstdio>
#include <cstdlib>

#include "slam/association/ml_association.hpp"
#include "numerical.hpp"
#include "slam_drive.hpp"
#include "tracks/generator.hpp"

namespace conesim::slam {
namespace {

using testing::numerical;

Eigen::Vector3d vec(const core::Pose2& p) {
  return {p.x, p.y, p.yaw};
}
core::Pose2 pose(const Eigen::Vector3d& v) {
  return {v(0), v(1), v(2)};
}

TEST(EkfSlamJacobians, MotionModelMatchesNumericalDerivatives) {
  for (const auto& [pose_then, delta] :
       {std::pair{core::Pose2{1.0, -2.0, 0.7}, core::Pose2{0.9, 0.05, 0.03}},
        std::pair{core::Pose2{-3.0, 4.0, -2.9}, core::Pose2{1.4, -0.2, -0.2}}}) {
    // named copies: clang 14 cannot capture structured bindings in a lambda
    const core::Pose2 p = pose_then, d = delta;
    Eigen::Matrix3d f_pose, f_delta;
    EkfSlam::motion(p, d, &f_pose, &f_delta);
    const auto by_pose = numerical<3, 3>(
        [&](const Eigen::Vector3d& x) { return vec(EkfSlam::motion(pose(x), d)); }, vec(p));
    const auto by_delta = numerical<3, 3>(
        [&](const Eigen::Vector3d& x) { return vec(EkfSlam::motion(p, pose(x))); }, vec(d));
    EXPECT_LT((f_pose - by_pose).cwiseAbs().maxCoeff(), 1e-7);
    EXPECT_LT((f_delta - by_delta).cwiseAbs().maxCoeff(), 1e-7);
  }
}

TEST(EkfSlamJacobians, ObservationModelMatchesNumericalDerivatives) {
  const core::Pose2 p{2.0, 1.0, 2.2};
  const core::Vec2 l(6.0, -3.0);
  Eigen::Matrix<double, 2, 3> h_pose;
  Eigen::Matrix2d h_landmark;
  predict_observation(p, l, &h_pose, &h_landmark);
  const auto by_pose = numerical<3, 2>(
      [&](const Eigen::Vector3d& x) { return predict_observation(pose(x), l); }, vec(p));
  const auto by_landmark = numerical<2, 2>(
      [&](const Eigen::Vector2d& x) { return predict_observation(p, x); }, Eigen::Vector2d(l));
  EXPECT_LT((h_pose - by_pose).cwiseAbs().maxCoeff(), 1e-7);
  EXPECT_LT((h_landmark - by_landmark).cwiseAbs().maxCoeff(), 1e-7);
}

TEST(EkfSlamJacobians, LandmarkInitialisationMatchesNumericalDerivatives) {
  const core::Pose2 p{-1.0, 3.0, -0.8};
  const core::Vec2 z(7.5, 2.5);
  Eigen::Matrix<double, 2, 3> l_pose;
  Eigen::Matrix2d l_z;
  EkfSlam::landmark_from(p, z, &l_pose, &l_z);
  const auto by_pose = numerical<3, 2>(
      [&](const Eigen::Vector3d& x) { return EkfSlam::landmark_from(pose(x), z); }, vec(p));
  const auto by_z = numerical<2, 2>(
      [&](const Eigen::Vector2d& x) { return EkfSlam::landmark_from(p, x); }, Eigen::Vector2d(z));
  EXPECT_LT((l_pose - by_pose).cwiseAbs().maxCoeff(), 1e-7);
  EXPECT_LT((l_z - by_z).cwiseAbs().maxCoeff(), 1e-7);
}

using testing::print;

TEST(EkfSlam, TwoLapsOfAGeneratedCircuitMapAndLocaliseWithinTargets) {
  const tracks::Track track = tracks::generate_circuit(3);
  EkfSlam slam;
  testing::DriveParams params;
  params.seed = 3;
  params.trace = std::getenv("CONESIM_SLAM_TRACE") != nullptr;
  const testing::DriveResult r = testing::drive(track, slam, params);
  print("ekf seed 3", r);
  EXPECT_LE(r.map_rmse_m, 0.15);
  EXPECT_LE(r.ate_rmse_m, 0.2);
  EXPECT_GE(r.da_correct_fraction, 0.99);
  EXPECT_EQ(r.loop_closures, 1);
  EXPECT_GT(r.loop_closure_travel_m, 0.8 * r.lap_m);
  EXPECT_LT(r.loop_closure_travel_m, 1.3 * r.lap_m);
  EXPECT_TRUE(r.localising_at_end);
}

TEST(EkfSlam, CovarianceStaysSymmetricPositiveDefiniteOverAWholeTrackdrive) {
  // mapping lap, loop closure, localisation lap; checked after every batch (the Cholesky
  // factorisation of the whole P, which fails on any non-positive pivot, every 5th batch)
  const tracks::Track track = tracks::generate_circuit(4);
  EkfSlam slam;
  testing::DriveParams params;
  params.seed = 4;
  int checked = 0, largest = 0;
  double worst_asymmetry = 0.0, smallest_diagonal = 1e300;
  params.after_batch = [&](int batch) {
    const Eigen::MatrixXd& p = slam.covariance();
    worst_asymmetry = std::max(worst_asymmetry, (p - p.transpose()).cwiseAbs().maxCoeff());
    smallest_diagonal = std::min(smallest_diagonal, p.diagonal().minCoeff());
    largest = std::max(largest, static_cast<int>(p.rows()));
    if (batch % 5 != 0) return;
    ++checked;
    const Eigen::LLT<Eigen::MatrixXd> llt(p);
    ASSERT_EQ(llt.info(), Eigen::Success) << "P not positive definite after batch " << batch;
  };
  const testing::DriveResult r = testing::drive(track, slam, params);
  print("ekf seed 4", r);
  EXPECT_EQ(worst_asymmetry, 0.0);
  EXPECT_GT(smallest_diagonal, 0.0);
  EXPECT_GT(checked, 100);
  // it did map: the joint state grew to the whole track, then the loop closed
  EXPECT_GT(largest, 2 * static_cast<int>(track.cones.size()) * 9 / 10);
  EXPECT_EQ(r.loop_closures, 1);
  EXPECT_TRUE(r.localising_at_end);
}

TEST(EkfSlam, PredictionTouchesOnlyThePoseRowsAndTheirCrossTerms) {
  // two landmarks in the filter, then a prediction with no observations
  EkfSlamConfig config;
  config.confirm_sightings = 1;
  EkfSlam slam(config);
  slam.reset({}, 0);
  SlamInput first;
  first.observations.stamp = 100'000;
  first.observations.cones = {
      {{8.0, 2.0}, core::ConeClass::kBlue, Eigen::Matrix2d::Identity() * 0.01, -1},
      {{8.0, -2.0}, core::ConeClass::kYellow, Eigen::Matrix2d::Identity() * 0.01, -1}};
  slam.process(first);
  ASSERT_EQ(slam.landmarks(), 2);
  const Eigen::MatrixXd before = slam.covariance();
  SlamInput move;
  move.odometry.delta = {1.0, 0.0, 0.05};
  move.odometry.covariance = Eigen::Vector3d(1e-3, 1e-3, 1e-4).asDiagonal();
  move.observations.stamp = 200'000;
  slam.process(move);
  const Eigen::MatrixXd& after = slam.covariance();
  // the landmark block is untouched, the pose block grew, the cross terms moved with the pose
  EXPECT_EQ(after.bottomRightCorner(4, 4), before.bottomRightCorner(4, 4));
  EXPECT_GT(after(0, 0) + after(1, 1) + after(2, 2), before(0, 0) + before(1, 1) + before(2, 2));
  Eigen::Matrix3d f;
  EkfSlam::motion({}, move.odometry.delta, &f);
  EXPECT_LT((after.topRightCorner(3, 4) - f * before.topRightCorner(3, 4)).cwiseAbs().maxCoeff(),
            1e-15);
}

TEST(EkfSlam, LocalisesOnAPriorMapWithoutChangingIt) {
  const tracks::Track track = tracks::generate_circuit(5);
  std::vector<core::MapCone> prior;
  for (const tracks::Cone& cone : track.cones)
    prior.push_back({cone.id, cone.cls, cone.position, Eigen::Matrix2d::Identity() * 1e-4});
  EkfSlam slam;
  testing::DriveParams params;
  params.seed = 5;
  params.laps = 1.0;
  params.prior_map = prior;
  const testing::DriveResult r = testing::drive(track, slam, params);
  print("ekf prior map seed 5", r);
  EXPECT_LE(r.ate_rmse_m, 0.10);
  EXPECT_LE(r.map_rmse_m, 1e-9);
  EXPECT_EQ(r.map_matched, static_cast<int>(track.cones.size()));
  EXPECT_EQ(r.loop_closures, 0);
  EXPECT_GE(r.da_correct_fraction, 0.99);
  EXPECT_EQ(slam.covariance().rows(), 3);
}

TEST(EkfSlamConfig, ValidateNamesTheBadKey) {
  EkfSlamConfig c;
  EXPECT_EQ(c.validate(), "");
  c.confirm_sightings = 0;
  EXPECT_EQ(c.validate().rfind("confirm_sightings:", 0), 0u);
  c = {};
  c.association.joint_probability = 1.5;
  EXPECT_EQ(c.validate().rfind("association.joint_probability:", 0), 0u);
}

}  // namespace
}  // namespace conesim::slam
