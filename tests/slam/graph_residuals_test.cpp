// The pose graph's residuals: values a user can check by hand, whitening with the upper Cholesky
// factor, and each autodiff Jacobian against a central-difference twin of the same functor.

#include "slam/backends/graph_residuals.hpp"

#include <gtest/gtest.h>

#include <array>
#include <memory>
#include <optional>

namespace conesim::slam {
namespace {

// evaluates a cost function's residuals and Jacobians at the given parameter blocks
template <int R>
void evaluate(const ceres::CostFunction& cost, const std::vector<double*>& blocks,
              Eigen::Matrix<double, R, 1>* residual, std::vector<Eigen::MatrixXd>* jacobians) {
  std::vector<std::vector<double>> storage;
  std::vector<double*> pointers;
  for (int size : cost.parameter_block_sizes()) {
    storage.emplace_back(R * size);
    pointers.push_back(storage.back().data());
  }
  ASSERT_TRUE(cost.Evaluate(blocks.data(), residual->data(), pointers.data()));
  jacobians->clear();
  for (size_t b = 0; b < storage.size(); ++b) {
    const int size = cost.parameter_block_sizes()[b];
    jacobians->push_back(
        Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
            storage[b].data(), R, size));
  }
}

// the autodiff cost function and its numeric twin agree on residuals and Jacobians
template <typename Functor, int R, int... Blocks>
void expect_autodiff_matches_numeric(Functor* autodiff_functor, Functor* numeric_functor,
                                     std::vector<double*> blocks) {
  ceres::AutoDiffCostFunction<Functor, R, Blocks...> autodiff(autodiff_functor);
  ceres::NumericDiffCostFunction<Functor, ceres::CENTRAL, R, Blocks...> numeric(numeric_functor);
  Eigen::Matrix<double, R, 1> r_auto, r_num;
  std::vector<Eigen::MatrixXd> j_auto, j_num;
  evaluate<R>(autodiff, blocks, &r_auto, &j_auto);
  evaluate<R>(numeric, blocks, &r_num, &j_num);
  EXPECT_LT((r_auto - r_num).norm(), 1e-12);
  for (size_t b = 0; b < j_auto.size(); ++b) {
    EXPECT_LT((j_auto[b] - j_num[b]).norm(), 1e-6 * (1.0 + j_auto[b].norm()))
        << "block " << b << "\nautodiff\n"
        << j_auto[b] << "\nnumeric\n"
        << j_num[b];
  }
}

TEST(SqrtInformation, IsTheUpperCholeskyFactorOfTheInformation) {
  // a correlated covariance: U^T U must give back the information matrix
  Eigen::Matrix3d cov;
  cov << 0.04, 0.01, 0.002, 0.01, 0.09, -0.003, 0.002, -0.003, 0.0025;
  const Eigen::Matrix3d u = sqrt_information<3>(cov);
  EXPECT_LT((u.transpose() * u - cov.inverse()).norm(), 1e-9 * cov.inverse().norm());
  EXPECT_NEAR(u(1, 0), 0.0, 1e-15);  // upper triangular
  // so the whitened squared norm is the Mahalanobis distance
  const Eigen::Vector3d e(0.1, -0.2, 0.03);
  EXPECT_NEAR((u * e).squaredNorm(), e.dot(cov.inverse() * e), 1e-9);
}

TEST(OdometryResidual, ZeroAtTheMeasuredDeltaAndAngleWrapsAcrossPi) {
  // pose b = a composed with the delta: the residual vanishes, even across the +-pi seam
  const core::Pose2 a{1.0, 2.0, 3.0};
  const core::Pose2 delta{0.9, 0.05, 0.3};
  const core::Pose2 b = a.compose(delta);
  double pa[3] = {a.x, a.y, a.yaw}, pb[3] = {b.x, b.y, b.yaw}, bias[1] = {0.0};
  std::unique_ptr<ceres::CostFunction> cost(
      OdometryResidual::Create(delta, Eigen::Matrix3d::Identity(), 0.1));
  Eigen::Vector3d r;
  double* blocks[3] = {pa, pb, bias};
  ASSERT_TRUE(cost->Evaluate(blocks, r.data(), nullptr));
  EXPECT_LT(r.norm(), 1e-12);
  // one whole turn added to b's heading changes nothing
  pb[2] += 2.0 * M_PI;
  ASSERT_TRUE(cost->Evaluate(blocks, r.data(), nullptr));
  EXPECT_LT(r.norm(), 1e-12);
}

TEST(OdometryResidual, AutodiffMatchesNumeric) {
  Eigen::Matrix3d cov;
  cov << 0.01, 0.002, 0.0, 0.002, 0.004, 0.0005, 0.0, 0.0005, 0.0004;
  const core::Pose2 delta{0.9, 0.05, 0.3};
  double a[3] = {1.0, -2.0, 2.9}, b[3] = {1.5, -1.0, -3.0}, bias[1] = {0.003};
  expect_autodiff_matches_numeric<OdometryResidual, 3, 3, 3, 1>(
      new OdometryResidual(delta, sqrt_information<3>(cov), 0.1),
      new OdometryResidual(delta, sqrt_information<3>(cov), 0.1), {a, b, bias});
}

TEST(OdometryResidual, GyroBiasTakesItsTurnOutOfTheMeasuredHeading) {
  // a gyro reading 0.002 rad/s too high over 0.1 s: the true pose b turned 0.0002 rad less
  const core::Pose2 a{1.0, 2.0, 0.5};
  const core::Pose2 measured{0.9, 0.0, 0.0302};
  const core::Pose2 b = a.compose({0.9, 0.0, 0.0300});
  double pa[3] = {a.x, a.y, a.yaw}, pb[3] = {b.x, b.y, b.yaw}, bias[1] = {0.0};
  std::unique_ptr<ceres::CostFunction> cost(
      OdometryResidual::Create(measured, Eigen::Matrix3d::Identity(), 0.1));
  Eigen::Vector3d r;
  double* blocks[3] = {pa, pb, bias};
  ASSERT_TRUE(cost->Evaluate(blocks, r.data(), nullptr));
  EXPECT_NEAR(r.z(), -0.0002, 1e-12);
  bias[0] = 0.002;
  ASSERT_TRUE(cost->Evaluate(blocks, r.data(), nullptr));
  EXPECT_LT(r.norm(), 1e-12);
}

TEST(GyroBiasPrior, WhitensTheBiasBySigma) {
  std::unique_ptr<ceres::CostFunction> cost(GyroBiasPrior::Create(5e-4));
  double bias[1] = {1e-3};
  double r = 0.0;
  double* blocks[1] = {bias};
  ASSERT_TRUE(cost->Evaluate(blocks, &r, nullptr));
  EXPECT_NEAR(r, 2.0, 1e-12);
}

TEST(ObservationResidual, ZeroWhenTheLandmarkIsWhereItWasSeen) {
  const core::Pose2 pose{3.0, -1.0, 0.7};
  const core::Vec2 z(6.0, 1.5);
  const core::Vec2 l = pose.transform(z);
  double p[3] = {pose.x, pose.y, pose.yaw}, m[2] = {l.x(), l.y()};
  std::unique_ptr<ceres::CostFunction> cost(
      ObservationResidual::Create(z, Eigen::Matrix2d::Identity() * 10.0));
  Eigen::Vector2d r;
  double* blocks[2] = {p, m};
  ASSERT_TRUE(cost->Evaluate(blocks, r.data(), nullptr));
  EXPECT_LT(r.norm(), 1e-12);
  // 10 cm off along the car's x axis is one unit of residual with sqrt-information 10
  m[0] += 0.1 * std::cos(pose.yaw);
  m[1] += 0.1 * std::sin(pose.yaw);
  ASSERT_TRUE(cost->Evaluate(blocks, r.data(), nullptr));
  EXPECT_NEAR(r.x(), 1.0, 1e-9);
  EXPECT_NEAR(r.y(), 0.0, 1e-9);
}

TEST(ObservationResidual, AutodiffMatchesNumeric) {
  Eigen::Matrix2d cov;
  cov << 0.0025, 0.001, 0.001, 0.006;
  double p[3] = {3.0, -1.0, 0.7}, m[2] = {8.0, 4.0};
  expect_autodiff_matches_numeric<ObservationResidual, 2, 3, 2>(
      new ObservationResidual({6.0, 1.5}, sqrt_information<2>(cov)),
      new ObservationResidual({6.0, 1.5}, sqrt_information<2>(cov)), {p, m});
}

TEST(LandmarkPriorResidual, EqualsTheFoldedObservationsUpToAConstant) {
  // three observations of one landmark from fixed poses, folded into one prior: wherever the
  // landmark is, the prior's squared norm differs from the three residuals' by the same constant
  const std::array<core::Pose2, 3> poses = {
      core::Pose2{0.0, 0.0, 0.1}, core::Pose2{2.0, 0.5, 0.3}, core::Pose2{4.5, 1.0, -0.2}};
  const std::array<core::Vec2, 3> seen = {core::Vec2{9.0, 2.1}, core::Vec2{7.2, 0.3},
                                          core::Vec2{4.4, 2.6}};
  Eigen::Matrix2d cov;
  cov << 0.0025, 0.001, 0.001, 0.006;
  const Eigen::Matrix2d sqrt_info = sqrt_information<2>(cov);
  Eigen::Matrix2d information = Eigen::Matrix2d::Zero();
  Eigen::Vector2d weighted_mean = Eigen::Vector2d::Zero();
  for (size_t k = 0; k < poses.size(); ++k)
    fold_observation(poses[k], seen[k], sqrt_info, information, weighted_mean);
  const LandmarkPriorResidual prior(information, weighted_mean);

  std::optional<double> constant;
  for (const core::Vec2& l : {core::Vec2{8.9, 3.4}, core::Vec2{9.3, 2.8}, core::Vec2{7.0, 5.0}}) {
    double sum = 0.0;
    for (size_t k = 0; k < poses.size(); ++k) {
      ObservationResidual r(seen[k], sqrt_info);
      double p[3] = {poses[k].x, poses[k].y, poses[k].yaw}, m[2] = {l.x(), l.y()}, e[2];
      r(p, m, e);
      sum += e[0] * e[0] + e[1] * e[1];
    }
    double m[2] = {l.x(), l.y()};
    Eigen::Matrix<double, 2, 1> residual;
    std::vector<Eigen::MatrixXd> jacobians;
    evaluate<2>(prior, {m}, &residual, &jacobians);
    const double difference = sum - residual.squaredNorm();
    if (!constant) constant = difference;
    EXPECT_NEAR(difference, *constant, 1e-9 * sum);
    // its Jacobian: the whitening factor of the summed information
    EXPECT_LT((jacobians[0] - Eigen::Matrix2d(information.llt().matrixU())).norm(), 1e-12);
  }
  // the prior is least where the three observations agree best
  EXPECT_GE(*constant, 0.0);
}

TEST(IcrResidual, ZeroOnAnArcAndPenalisesSidewaysMotion) {
  // a circular arc of the rear axle: no lateral slip, no residual
  const double radius = 9.0, angle = 0.2;
  const core::Pose2 a{0.0, 0.0, 0.4};
  const core::Pose2 b =
      a.compose({radius * std::sin(angle), radius * (1.0 - std::cos(angle)), angle});
  double pa[3] = {a.x, a.y, a.yaw}, pb[3] = {b.x, b.y, b.yaw};
  std::unique_ptr<ceres::CostFunction> cost(IcrResidual::Create(0.05));
  double r = 0.0;
  double* blocks[2] = {pa, pb};
  ASSERT_TRUE(cost->Evaluate(blocks, &r, nullptr));
  EXPECT_NEAR(r, 0.0, 1e-12);
  // a 5 cm sideways step with no heading change is one sigma
  const core::Pose2 c = a.compose({1.0, 0.05, 0.0});
  double pc[3] = {c.x, c.y, c.yaw};
  blocks[1] = pc;
  ASSERT_TRUE(cost->Evaluate(blocks, &r, nullptr));
  EXPECT_NEAR(r, 1.0, 1e-9);
}

TEST(IcrResidual, AutodiffMatchesNumeric) {
  double a[3] = {1.0, -2.0, 3.0}, b[3] = {1.8, -2.3, -3.05};
  expect_autodiff_matches_numeric<IcrResidual, 1, 3, 3>(new IcrResidual(0.05),
                                                        new IcrResidual(0.05), {a, b});
}

}  // namespace
}  // namespace conesim::slam
