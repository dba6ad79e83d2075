// FastSLAM 1.0 and 2.0: the Jacobians of the proposal, the weights on constructed cases, the
// resampling, the copy-on-write sharing of the landmark tree, and offline drives.
#include "slam/backends/fastslam.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <random>

#include "numerical.hpp"
#include "slam_drive.hpp"
#include "tracks/generator.hpp"

namespace conesim::slam {
namespace {

using testing::print;

using testing::numerical;

TEST(FastSlamJacobians, MeasurementModelMatchesNumericalDerivatives) {
  // G_s and G_theta of the proposal and the landmark filters, at a few poses and landmarks
  for (const auto& [pose_at, landmark_at] :
       std::vector<std::pair<core::Pose2, core::Vec2>>{{{1.0, -2.0, 0.3}, {7.0, 1.5}},
                                                       {{-4.0, 3.0, -2.6}, {-9.0, 0.5}},
                                                       {{0.0, 0.0, 1.4}, {0.5, 6.0}}}) {
    // named copies: clang 14 cannot capture structured bindings in a lambda
    const core::Pose2 pose = pose_at;
    const core::Vec2 landmark = landmark_at;
    Eigen::Matrix<double, 2, 3> gs;
    Eigen::Matrix2d gl;
    predict_observation(pose, landmark, &gs, &gl);
    const Eigen::Matrix<double, 2, 3> gs_num = numerical<3, 2>(
        [&](const Eigen::Vector3d& s) {
          return Eigen::Vector2d(predict_observation({s(0), s(1), s(2)}, landmark));
        },
        Eigen::Vector3d(pose.x, pose.y, pose.yaw));
    const Eigen::Matrix2d gl_num = numerical<2, 2>(
        [&](const Eigen::Vector2d& l) { return Eigen::Vector2d(predict_observation(pose, l)); },
        Eigen::Vector2d(landmark));
    EXPECT_LT((gs - gs_num).cwiseAbs().maxCoeff(), 1e-7);
    EXPECT_LT((gl - gl_num).cwiseAbs().maxCoeff(), 1e-7);
  }
}

TEST(FastSlamJacobians, ProposalEqualsTheInformationFormOfTheThesis) {
  // one fold: Sigma' = [G_s^T Q^-1 G_s + Sigma^-1]^-1, mu' = mu + Sigma' G_s^T Q^-1 (z - z^),
  // with the Jacobian taken numerically
  const core::Pose2 mean{2.0, 1.0, 0.4};
  const Eigen::Matrix3d sigma = Eigen::Vector3d(0.04, 0.02, 0.003).asDiagonal();
  const core::Vec2 landmark(9.0, 4.0);
  const Eigen::Matrix2d landmark_cov = Eigen::Vector2d(0.01, 0.02).asDiagonal();
  const Eigen::Matrix2d r = Eigen::Vector2d(0.0025, 0.004).asDiagonal();
  const core::Vec2 z = predict_observation(mean, landmark) + core::Vec2(0.12, -0.07);
  const Eigen::Matrix<double, 2, 3> gs = numerical<3, 2>(
      [&](const Eigen::Vector3d& s) {
        return Eigen::Vector2d(predict_observation({s(0), s(1), s(2)}, landmark));
      },
      Eigen::Vector3d(mean.x, mean.y, mean.yaw));
  Eigen::Matrix2d gl;
  predict_observation(mean, landmark, nullptr, &gl);
  const Eigen::Matrix2d q = r + gl * landmark_cov * gl.transpose();
  const Eigen::Matrix3d sigma_thesis =
      (gs.transpose() * q.inverse() * gs + sigma.inverse()).inverse();
  const Eigen::Vector3d mu_thesis =
      Eigen::Vector3d(mean.x, mean.y, mean.yaw) +
      sigma_thesis * gs.transpose() * q.inverse() * (z - predict_observation(mean, landmark));

  core::Pose2 m = mean;
  Eigen::Matrix3d c = sigma;
  const double log_likelihood = FastSlam::fold_observation(m, c, z, r, landmark, landmark_cov);
  EXPECT_LT((Eigen::Vector3d(m.x, m.y, m.yaw) - mu_thesis).cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_LT((c - sigma_thesis).cwiseAbs().maxCoeff(), 1e-9);
  // the weight: the observation's density under L = G_s Sigma G_s^T + Q
  const Eigen::Matrix2d l = gs * sigma * gs.transpose() + q;
  const Eigen::Vector2d v = z - predict_observation(mean, landmark);
  const double expected =
      -0.5 * v.dot(l.inverse() * v) - 0.5 * std::log((2 * M_PI) * (2 * M_PI) * l.determinant());
  EXPECT_NEAR(log_likelihood, expected, 1e-6);
}

// two cones ahead, inside the sensor's view, seen from a car standing at the origin
core::ConeObservation cone(double x, double y, core::ConeClass cls) {
  return {{x, y}, cls, Eigen::Matrix2d::Identity() * 0.0025, -1};
}

SlamInput frame(core::TimeUs stamp, std::vector<core::ConeObservation> cones) {
  SlamInput in;
  in.odometry.from = stamp - 100'000;
  in.odometry.to = stamp;
  in.odometry.covariance = Eigen::Vector3d(1e-8, 1e-8, 1e-10).asDiagonal();
  in.observations.stamp = stamp;
  in.observations.cones = std::move(cones);
  return in;
}

FastSlamConfig constructed_config(int version) {
  FastSlamConfig c;
  c.version = version;
  c.particles = 1;
  c.confirm_sightings = 1;
  return c;
}

TEST(FastSlamWeights, ALandmarkInViewButUnseenLowersTheWeight) {
  // A mapped both cones, B only the first; then both see only the first while the second is in
  // view: A's factor is B's times the unseen penalty (all else equal, the same draws)
  for (int version : {1, 2}) {
    FastSlam a(constructed_config(version)), b(constructed_config(version));
    a.reset({}, 0);
    b.reset({}, 0);
    a.process(frame(100'000,
                    {cone(8, 2, core::ConeClass::kBlue), cone(8, -2, core::ConeClass::kYellow)}));
    b.process(frame(100'000, {cone(8, 2, core::ConeClass::kBlue)}));
    ASSERT_TRUE(a.in_field_of_view({}, {8, -2}));
    ASSERT_EQ(a.particles()[0].map.size(), 2);
    ASSERT_EQ(b.particles()[0].map.size(), 1);
    a.process(frame(200'000, {cone(8, 2, core::ConeClass::kBlue)}));
    b.process(frame(200'000, {cone(8, 2, core::ConeClass::kBlue)}));
    ASSERT_EQ(a.last_associations()[0].kind, Association::Kind::kMatched);
    ASSERT_EQ(b.last_associations()[0].kind, Association::Kind::kMatched);
    EXPECT_NEAR(a.last_log_factors()[0] - b.last_log_factors()[0], std::log(0.9), 1e-9)
        << "version " << version;
  }
}

TEST(FastSlamWeights, AColourMismatchLowersTheWeight) {
  // the same cone mapped blue (A) or without a colour (B), then seen yellow: only A's pairing
  // disagrees in colour (one blue vote does not lead by the margin, so it still pairs)
  for (int version : {1, 2}) {
    FastSlam a(constructed_config(version)), b(constructed_config(version));
    a.reset({}, 0);
    b.reset({}, 0);
    a.process(frame(100'000, {cone(8, 2, core::ConeClass::kBlue)}));
    b.process(frame(100'000, {cone(8, 2, core::ConeClass::kUnknown)}));
    a.process(frame(200'000, {cone(8, 2, core::ConeClass::kYellow)}));
    b.process(frame(200'000, {cone(8, 2, core::ConeClass::kYellow)}));
    ASSERT_EQ(a.last_associations()[0].kind, Association::Kind::kMatched);
    ASSERT_EQ(b.last_associations()[0].kind, Association::Kind::kMatched);
    EXPECT_NEAR(a.last_log_factors()[0] - b.last_log_factors()[0], std::log(0.5), 1e-9)
        << "version " << version;
  }
}

TEST(FastSlamWeights, ACloserMatchWeighsMore) {
  // two particles: the one whose map agrees with the observation gets the larger weight
  FastSlam slam(constructed_config(2));
  slam.reset({}, 0);
  slam.process(frame(100'000, {cone(8, 2, core::ConeClass::kBlue)}));
  const double near = slam.last_log_factors()[0];
  FastSlam off(constructed_config(2));
  off.reset({}, 0);
  off.process(frame(100'000, {cone(8, 2, core::ConeClass::kBlue)}));
  off.process(frame(200'000, {cone(8.1, 2, core::ConeClass::kBlue)}));
  slam.process(frame(200'000, {cone(8, 2, core::ConeClass::kBlue)}));
  EXPECT_GT(slam.last_log_factors()[0], off.last_log_factors()[0]);
  EXPECT_LT(near, 0.0);  // a new landmark: the new-landmark factor alone
  EXPECT_NEAR(near, std::log(0.02), 1e-12);
}

TEST(FastSlam, AReturnKeepsItsDriftAllowanceUntilThePoseHasCaughtUp) {
  // A cone is mapped, the car drives 200 m out of its sight and comes back 0.5 m off (the
  // odometry's drift). The first sighting pairs inside the drift allowance; the pose, held by
  // its tight odometry, is still 0.5 m off on the next frame, so that sighting pairs only while
  // the allowance is held (otherwise it fails the gate and is rejected or starts a duplicate).
  for (const bool hold : {true, false}) {
    FastSlamConfig config = constructed_config(2);
    if (!hold) config.return_gap_m = 1e9;
    FastSlam slam(config);
    slam.reset({}, 0);
    core::TimeUs t = 100'000;
    slam.process(frame(t, {cone(8, 2, core::ConeClass::kBlue)}));
    auto move = [&](double dx, std::vector<core::ConeObservation> cones) {
      SlamInput in = frame(t += 100'000, std::move(cones));
      in.odometry.delta = {dx, 0.0, 0.0};
      in.odometry.distance_m = std::abs(dx);
      slam.process(in);
    };
    for (int k = 0; k < 10; ++k) move(10.0, {});  // away: the cone behind, out of view
    move(-100.0, {cone(8.5, 2, core::ConeClass::kBlue)});
    ASSERT_EQ(slam.last_associations()[0].kind, Association::Kind::kMatched) << hold;
    move(0.0, {cone(8.5, 2, core::ConeClass::kBlue)});
    EXPECT_EQ(slam.last_associations()[0].kind == Association::Kind::kMatched, hold) << hold;
    EXPECT_EQ(slam.particles()[0].map.size(), 1) << hold;
  }
}

TEST(FastSlamResampling, LowVarianceKeepsTheExpectedCountsWithMinimalSpread) {
  // every particle is drawn M w times on average, and each draw gives it floor(M w) or
  // ceil(M w) copies: the spread of systematic resampling is the least possible
  const std::vector<double> w = {0.02, 0.31, 0.0, 0.115, 0.2, 0.055, 0.3};
  const int m = static_cast<int>(w.size());
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0 / m);
  std::vector<double> mean(m, 0.0);
  const int trials = 20000;
  for (int t = 0; t < trials; ++t) {
    const std::vector<int> drawn = FastSlam::low_variance_resample(w, u(rng));
    ASSERT_EQ(static_cast<int>(drawn.size()), m);
    ASSERT_TRUE(std::is_sorted(drawn.begin(), drawn.end()));
    std::vector<int> count(m, 0);
    for (int i : drawn) ++count[i];
    for (int i = 0; i < m; ++i) {
      ASSERT_GE(count[i], std::floor(m * w[i]) - 1e-9) << i;
      ASSERT_LE(count[i], std::ceil(m * w[i]) + 1e-9) << i;
      mean[i] += count[i] / static_cast<double>(trials);
    }
  }
  // the mean of a count in {floor, ceil}: standard error below 0.5 / sqrt(trials)
  for (int i = 0; i < m; ++i) EXPECT_NEAR(mean[i], m * w[i], 0.02) << i;
  // a particle of weight 0 is never drawn
  EXPECT_EQ(mean[2], 0.0);
}

TEST(PersistentMap, CopiesShareTheirNodesAndAWriteCopiesOnlyItsPath) {
  PersistentMap<int> map;
  for (int k = 0; k < 1000; ++k) map.set(k, k * 10);
  ASSERT_EQ(map.size(), 1000);
  const size_t one = PersistentMap<int>::distinct_nodes({&map});
  // 50 copies (a resampling that drew one particle 50 times): no node more
  std::vector<PersistentMap<int>> copies(50, map);
  std::vector<const PersistentMap<int>*> all;
  for (const auto& c : copies) all.push_back(&c);
  EXPECT_EQ(PersistentMap<int>::distinct_nodes(all), one);
  // one copy changes one landmark: its path, depth + 1 nodes, is new; the rest still shared
  *copies[3].find_mut(517) = -1;
  EXPECT_EQ(PersistentMap<int>::distinct_nodes(all), one + map.depth() + 1);
  EXPECT_EQ(*copies[3].find(517), -1);
  EXPECT_EQ(*copies[4].find(517), 5170);
  EXPECT_EQ(*map.find(517), 5170);
  // a second write under the same parent copies only its leaf (the path is the copy's own now)
  *copies[3].find_mut(516) = -2;
  EXPECT_EQ(PersistentMap<int>::distinct_nodes(all), one + map.depth() + 2);
  // adding and erasing
  copies[5].set(4000, 1);
  EXPECT_EQ(copies[5].size(), 1001);
  EXPECT_EQ(*copies[5].find(4000), 1);
  EXPECT_EQ(copies[6].find(4000), nullptr);
  copies[5].erase(3);
  EXPECT_EQ(copies[5].find(3), nullptr);
  EXPECT_EQ(*copies[6].find(3), 30);
  EXPECT_EQ(copies[5].size(), 1000);
  int visited = 0, last = -1;
  copies[5].for_each([&](int key, int) {
    EXPECT_GT(key, last);
    last = key;
    ++visited;
  });
  EXPECT_EQ(visited, 1000);
  // the depth is the logarithm of the key range, base 8
  EXPECT_EQ(map.depth(), 4);  // 8^3 < 1000 <= 8^4
}

TEST(FastSlam, ParticlesShareTheirLandmarksAfterResampling) {
  // most of a lap before the loop closes: the particles' trees share every landmark not updated
  // since their last common ancestor, so what they hold beyond one tree is the paths to the
  // landmarks around the car, which does not grow with the map. Unshared, each landmark added
  // to the map would add a leaf and its path to each of the 50 trees.
  const tracks::Track track = tracks::generate_circuit(4);
  FastSlamConfig config;
  config.seed = 4;
  FastSlam slam(config);
  testing::DriveParams params;
  params.seed = 4;
  params.laps = 0.95;
  size_t nodes_early = 0, tree_early = 0;
  params.after_batch = [&](int batch) {
    if (batch != 100) return;
    nodes_early = slam.distinct_map_nodes();
    tree_early =
        PersistentMap<FastLandmark>::distinct_nodes({&slam.particles()[slam.best_particle()].map});
  };
  testing::drive(track, slam, params);
  ASSERT_EQ(slam.loop_closures(), 0);  // (after the closure all particles hold one tree)
  ASSERT_GT(slam.resamplings(), 10);
  const size_t nodes = slam.distinct_map_nodes();
  const size_t tree =
      PersistentMap<FastLandmark>::distinct_nodes({&slam.particles()[slam.best_particle()].map});
  std::printf("batch 100: %zu nodes, one tree %zu; end: %zu nodes, one tree %zu\n", nodes_early,
              tree_early, nodes, tree);
  ASSERT_GT(tree, 2 * tree_early);  // the map more than doubled
  EXPECT_LT(nodes, 3 * nodes_early / 2);
  EXPECT_LT(static_cast<double>(nodes) - static_cast<double>(nodes_early),
            10.0 * static_cast<double>(tree - tree_early));
}

TEST(FastSlam, SameSeedSameEstimateAndAnotherSeedDrawsDifferently) {
  const tracks::Track track = tracks::generate_circuit(5);
  auto run = [&](std::uint64_t seed) {
    FastSlamConfig config;
    config.seed = seed;
    FastSlam slam(config);
    testing::DriveParams params;
    params.seed = 5;
    params.laps = 0.3;
    testing::drive(track, slam, params);
    return slam.estimate();
  };
  const core::Estimate a = run(1), b = run(1), c = run(2);
  EXPECT_EQ(a.pose.x, b.pose.x);
  EXPECT_EQ(a.pose.y, b.pose.y);
  ASSERT_EQ(a.map.size(), b.map.size());
  for (size_t k = 0; k < a.map.size(); ++k) EXPECT_EQ(a.map[k].position, b.map[k].position);
  EXPECT_NE(a.pose.x, c.pose.x);
}

TEST(FastSlam, LocalisesOnAPriorMapWithoutChangingIt) {
  const tracks::Track track = tracks::generate_circuit(5);
  std::vector<core::MapCone> prior;
  for (const tracks::Cone& c : track.cones)
    prior.push_back({c.id, c.cls, c.position, Eigen::Matrix2d::Identity() * 1e-4});
  for (int version : {1, 2}) {
    FastSlamConfig config;
    config.version = version;
    FastSlam slam(config);
    testing::DriveParams params;
    params.seed = 5;
    params.laps = 1.0;
    params.prior_map = prior;
    const testing::DriveResult r = testing::drive(track, slam, params);
    print(version == 1 ? "fastslam1 prior map" : "fastslam2 prior map", r);
    // Monte Carlo localisation on an exact map: within a few observation sigmas (5 cm range)
    EXPECT_LE(r.ate_rmse_m, 0.10);
    EXPECT_LE(r.map_rmse_m, 1e-9);
    EXPECT_EQ(r.map_matched, static_cast<int>(track.cones.size()));
    EXPECT_GE(r.da_correct_fraction, 0.99);
    EXPECT_EQ(slam.estimate().phase, core::SlamPhase::kLocalisation);
  }
}

TEST(FastSlamConfig, ValidateNamesTheBadKey) {
  FastSlamConfig c;
  EXPECT_EQ(c.validate(), "");
  c.particles = 0;
  EXPECT_EQ(c.validate().rfind("particles:", 0), 0u);
  c = {};
  c.unseen_penalty = 1.5;
  EXPECT_EQ(c.validate().rfind("unseen_penalty:", 0), 0u);
  c = {};
  c.resample_fraction = -0.1;
  EXPECT_EQ(c.validate().rfind("resample_fraction:", 0), 0u);
  c = {};
  c.loop_closure.returned_fraction = 2.0;
  EXPECT_EQ(c.validate().rfind("loop_closure.returned_fraction:", 0), 0u);
}

}  // namespace
}  // namespace conesim::slam
