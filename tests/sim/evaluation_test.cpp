#include "sim/evaluation.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace conesim::sim {
namespace {

using core::ConeClass;
using core::Pose2;
using core::Vec2;

constexpr double kInf = std::numeric_limits<double>::infinity();

// the matching the map scorer used before: the closest allowed pair first, repeatedly
std::vector<int> greedy_assign(const Eigen::MatrixXd& cost, double cutoff) {
  std::vector<int> out(cost.rows(), -1);
  std::vector<char> col_used(cost.cols(), 0);
  while (true) {
    int bi = -1, bj = -1;
    double best = kInf;
    for (int i = 0; i < cost.rows(); ++i)
      for (int j = 0; j < cost.cols(); ++j)
        if (out[i] < 0 && !col_used[j] && cost(i, j) <= cutoff && cost(i, j) < best)
          best = cost(i, j), bi = i, bj = j;
    if (bi < 0) return out;
    out[bi] = bj;
    col_used[bj] = 1;
  }
}

struct Score {
  int pairs = 0;
  double cost = 0.0;
};

// pairs and total cost of an assignment; fails the test when it is not one to one or uses a
// pair above the cut-off
Score score(const Eigen::MatrixXd& cost, const std::vector<int>& a, double cutoff) {
  EXPECT_EQ(a.size(), static_cast<size_t>(cost.rows()));
  Score s;
  std::set<int> cols;
  for (size_t i = 0; i < a.size(); ++i) {
    if (a[i] < 0) continue;
    EXPECT_LT(a[i], cost.cols());
    EXPECT_TRUE(cols.insert(a[i]).second) << "column " << a[i] << " assigned twice";
    EXPECT_LE(cost(i, a[i]), cutoff) << "row " << i << " paired above the cut-off";
    ++s.pairs;
    s.cost += cost(i, a[i]);
  }
  return s;
}

// every partial one-to-one assignment within the cut-off: the most pairs, then the least cost
void brute_force(const Eigen::MatrixXd& cost, double cutoff, int row, std::vector<char>& used,
                 Score current, Score* best) {
  if (row == cost.rows()) {
    if (current.pairs > best->pairs || (current.pairs == best->pairs && current.cost < best->cost))
      *best = current;
    return;
  }
  brute_force(cost, cutoff, row + 1, used, current, best);  // row left unpaired
  for (int j = 0; j < cost.cols(); ++j) {
    if (used[j] || !(cost(row, j) <= cutoff)) continue;
    used[j] = 1;
    brute_force(cost, cutoff, row + 1, used, {current.pairs + 1, current.cost + cost(row, j)},
                best);
    used[j] = 0;
  }
}

TEST(HungarianAssign, BeatsGreedyWhereTheClosestPairIsNotPartOfTheBestMatching) {
  // two estimated cones and two true cones: pairing the closest pair first leaves the other
  // estimate with its far cone (0.1 + 0.9), crossing the pairs costs 0.3 + 0.2
  Eigen::MatrixXd cost(2, 2);
  cost << 0.1, 0.3,  //
      0.2, 0.9;
  const std::vector<int> greedy = greedy_assign(cost, 1.0);
  const std::vector<int> best = hungarian_assign(cost, 1.0);
  EXPECT_EQ(greedy, (std::vector<int>{0, 1}));
  EXPECT_EQ(best, (std::vector<int>{1, 0}));
  EXPECT_NEAR(score(cost, greedy, 1.0).cost, 1.0, 1e-12);
  EXPECT_NEAR(score(cost, best, 1.0).cost, 0.5, 1e-12);
}

TEST(HungarianAssign, MatchesMoreThanGreedyWhenTheClosestPairBlocksAnother) {
  // greedy takes 0.35 and leaves row 1 with only its forbidden pair; crossing pairs both
  Eigen::MatrixXd cost(2, 2);
  cost << 0.35, 0.45,  //
      0.5, 1.3;
  EXPECT_EQ(score(cost, greedy_assign(cost, 1.0), 1.0).pairs, 1);
  const std::vector<int> best = hungarian_assign(cost, 1.0);
  EXPECT_EQ(best, (std::vector<int>{1, 0}));
}

TEST(HungarianAssign, MatchesBruteForceOnRandomSmallMatrices) {
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> size(0, 5);
  std::uniform_real_distribution<double> uniform(0.0, 2.0);
  for (int trial = 0; trial < 400; ++trial) {
    const int rows = size(rng), cols = size(rng);
    const double cutoff = trial % 4 == 0 ? kInf : 1.0;
    Eigen::MatrixXd cost(rows, cols);
    for (int i = 0; i < rows; ++i)
      for (int j = 0; j < cols; ++j) cost(i, j) = uniform(rng);
    std::vector<char> used(cols, 0);
    Score expected{0, 0.0};
    brute_force(cost, cutoff, 0, used, {0, 0.0}, &expected);
    const Score got = score(cost, hungarian_assign(cost, cutoff), cutoff);
    ASSERT_EQ(got.pairs, expected.pairs) << "trial " << trial << "\n" << cost;
    ASSERT_NEAR(got.cost, expected.cost, 1e-9) << "trial " << trial << "\n" << cost;
  }
}

TEST(HungarianAssign, NeverPairsAboveTheCutoff) {
  // alone above the cut-off: unpaired; exactly at it: paired; NaN: never
  Eigen::MatrixXd one(1, 1);
  one << 1.5;
  EXPECT_EQ(hungarian_assign(one, 1.0), (std::vector<int>{-1}));
  one << 1.0;
  EXPECT_EQ(hungarian_assign(one, 1.0), (std::vector<int>{0}));
  one << std::nan("");
  EXPECT_EQ(hungarian_assign(one, kInf), (std::vector<int>{-1}));
  one << kInf;
  EXPECT_EQ(hungarian_assign(one, kInf), (std::vector<int>{-1}));

  // the cheapest full assignment (0.2 + 1.1) uses a forbidden pair: the answer must not
  Eigen::MatrixXd cost(2, 2);
  cost << 0.2, 0.9,  //
      0.95, 1.1;
  EXPECT_EQ(hungarian_assign(cost, 1.0), (std::vector<int>{1, 0}));
  cost << 0.2, 1.2,  //
      1.3, 1.1;
  EXPECT_EQ(hungarian_assign(cost, 1.0), (std::vector<int>{0, -1}));
}

TEST(HungarianAssign, HandlesRectangularAndEmptyMatrices) {
  Eigen::MatrixXd tall(3, 1);
  tall << 0.7, 0.2, 0.4;
  EXPECT_EQ(hungarian_assign(tall, 1.0), (std::vector<int>{-1, 0, -1}));
  Eigen::MatrixXd wide(1, 3);
  wide << 0.7, 0.2, 0.4;
  EXPECT_EQ(hungarian_assign(wide, 1.0), (std::vector<int>{1}));
  EXPECT_TRUE(hungarian_assign(Eigen::MatrixXd(0, 3), 1.0).empty());
  EXPECT_EQ(hungarian_assign(Eigen::MatrixXd(2, 0), 1.0), (std::vector<int>{-1, -1}));
}

TEST(HungarianAssign, IsDeterministicUnderTies) {
  const Eigen::MatrixXd zeros = Eigen::MatrixXd::Zero(4, 4);
  const std::vector<int> first = hungarian_assign(zeros, 1.0);
  EXPECT_EQ(score(zeros, first, 1.0).pairs, 4);
  for (int k = 0; k < 3; ++k) EXPECT_EQ(hungarian_assign(zeros, 1.0), first);
}

TEST(AlignSe2, RecoversAKnownTransformExactly) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> coord(-40.0, 40.0);
  for (const Pose2 truth : {Pose2{3.0, -2.0, 0.7}, Pose2{-15.0, 8.0, 3.1}, Pose2{0.5, 0.0, -2.9}}) {
    std::vector<Vec2> from, to;
    for (int i = 0; i < 20; ++i) {
      from.push_back({coord(rng), coord(rng)});
      to.push_back(truth.transform(from.back()));
    }
    const Pose2 t = align_se2(from, to);
    EXPECT_NEAR(t.x, truth.x, 1e-9);
    EXPECT_NEAR(t.y, truth.y, 1e-9);
    EXPECT_NEAR(core::normalize_angle(t.yaw - truth.yaw), 0.0, 1e-12);
  }
}

TEST(AlignSe2, RecoversAKnownTransformFromNoisyPoints) {
  // 400 points spread uniformly over 80 m x 80 m around (20, 10), target noise 0.05 m per axis.
  // Standard errors: yaw sigma / (sqrt(N) * rms radius) = 0.05 / (20 * 32.7) = 7.7e-5 rad;
  // the translation (the centroid's, plus the yaw error times the centroid's distance 22 m)
  // sigma / sqrt(N) = 2.5e-3 m and 1.7e-3 m: tolerances are 5 standard errors
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> coord(-40.0, 40.0);
  std::normal_distribution<double> noise(0.0, 0.05);
  const Pose2 truth{4.0, -6.0, -1.2};
  std::vector<Vec2> from, to;
  for (int i = 0; i < 400; ++i) {
    from.push_back(Vec2{20.0, 10.0} + Vec2{coord(rng), coord(rng)});
    to.push_back(truth.transform(from.back()) + Vec2{noise(rng), noise(rng)});
  }
  const Pose2 t = align_se2(from, to);
  EXPECT_NEAR(core::normalize_angle(t.yaw - truth.yaw), 0.0, 5 * 7.7e-5);
  EXPECT_NEAR(t.x, truth.x, 5 * 3.0e-3);
  EXPECT_NEAR(t.y, truth.y, 5 * 3.0e-3);
}

TEST(AlignSe2, DegenerateInputs) {
  EXPECT_THROW(align_se2({{0, 0}}, {}), std::invalid_argument);
  const Pose2 none = align_se2({}, {});
  EXPECT_EQ(none.x, 0.0);
  EXPECT_EQ(none.yaw, 0.0);
  const Pose2 one = align_se2({{1.0, 2.0}}, {{4.0, -1.0}});
  EXPECT_NEAR(one.x, 3.0, 1e-12);
  EXPECT_NEAR(one.y, -3.0, 1e-12);
  EXPECT_NEAR(one.yaw, 0.0, 1e-12);
}

core::ConeObservations detections(std::vector<std::pair<Vec2, ConeClass>> cones) {
  core::ConeObservations obs;
  for (const auto& [p, cls] : cones) {
    core::ConeObservation o;
    o.position = p;
    o.cls = cls;
    obs.cones.push_back(o);
  }
  return obs;
}

// the JSON number, or NaN for null
double value(const nlohmann::json& v) {
  return v.is_null() ? std::nan("") : v.get<double>();
}

TEST(PerceptionScorer, CountsOneFrameByRangeBand) {
  // the sensor 1 m ahead of the reference point; true cones at ranges 3, 7.6, 12, 20 and 39 m
  PerceptionScorer scorer(Vec2{1.0, 0.0});
  const std::vector<TrueConeInView> truth = {
      {10, ConeClass::kBlue, {4.0, 0.0}},        // band 0, found, right colour, 0.3 m off
      {11, ConeClass::kYellow, {8.0, 3.0}},      // band 1, found as blue, 0.4 m off
      {12, ConeClass::kOrangeBig, {13.0, 0.0}},  // band 2, found as unknown, 0.5 m off
      {13, ConeClass::kBlue, {21.0, 0.0}},       // band 4, missed
      {14, ConeClass::kYellow, {40.0, 0.0}},     // beyond 30 m: not counted
  };
  const auto ids = scorer.add_frame(detections({{{4.3, 0.0}, ConeClass::kBlue},
                                                {{8.0, 3.4}, ConeClass::kBlue},
                                                {{13.0, 0.5}, ConeClass::kUnknown},
                                                {{17.0, 0.0}, ConeClass::kBlue},    // 16 m: false
                                                {{51.0, 0.0}, ConeClass::kBlue}}),  // beyond
                                    truth);
  EXPECT_EQ(ids, (std::vector<int>{10, 11, 12, -1, -1}));

  const nlohmann::json m = scorer.metrics();
  EXPECT_EQ(m["frames"], 1);
  EXPECT_EQ(m["true_cones"], 4);
  EXPECT_EQ(m["detections"], 4);
  EXPECT_EQ(m["matched"], 3);
  EXPECT_DOUBLE_EQ(value(m["recall"]), 0.75);
  EXPECT_DOUBLE_EQ(value(m["precision"]), 0.75);
  EXPECT_DOUBLE_EQ(value(m["colour_accuracy"]), 1.0 / 3.0);
  EXPECT_NEAR(value(m["position_rmse_m"]), std::sqrt((0.09 + 0.16 + 0.25) / 3.0), 1e-12);
  // within 15 m: the three found cones and their detections; within 10 m one of two colours
  EXPECT_DOUBLE_EQ(value(m["recall_15m"]), 1.0);
  EXPECT_DOUBLE_EQ(value(m["precision_15m"]), 1.0);
  EXPECT_DOUBLE_EQ(value(m["colour_accuracy_10m"]), 0.5);

  const auto& bands = m["bands"];
  ASSERT_EQ(bands.size(), 6u);
  EXPECT_EQ(bands[0]["from_m"], 0.0);
  EXPECT_EQ(bands[5]["to_m"], 30.0);
  const std::vector<int> true_cones = {1, 1, 1, 0, 1, 0}, dets = {1, 1, 1, 1, 0, 0},
                         matched = {1, 1, 1, 0, 0, 0};
  for (size_t b = 0; b < 6; ++b) {
    EXPECT_EQ(bands[b]["true_cones"], true_cones[b]) << "band " << b;
    EXPECT_EQ(bands[b]["detections"], dets[b]) << "band " << b;
    EXPECT_EQ(bands[b]["matched"], matched[b]) << "band " << b;
  }
  EXPECT_NEAR(value(bands[0]["position_rmse_m"]), 0.3, 1e-12);
  EXPECT_NEAR(value(bands[1]["position_rmse_m"]), 0.4, 1e-12);
  EXPECT_DOUBLE_EQ(value(bands[0]["colour_accuracy"]), 1.0);
  EXPECT_DOUBLE_EQ(value(bands[1]["colour_accuracy"]), 0.0);
  EXPECT_DOUBLE_EQ(value(bands[2]["colour_accuracy"]), 0.0);  // unknown is not right
  EXPECT_TRUE(bands[3]["recall"].is_null());                  // no true cone in 15-20 m
  EXPECT_DOUBLE_EQ(value(bands[3]["precision"]), 0.0);
  EXPECT_DOUBLE_EQ(value(bands[4]["recall"]), 0.0);
  EXPECT_TRUE(bands[4]["precision"].is_null());
  EXPECT_TRUE(bands[5]["position_rmse_m"].is_null());
}

// A spare cone standing off the track is a cone: a detection on it is neither true nor false
// (KITTI's DontCare), carries that cone's label, and never takes a track cone's detection.
TEST(PerceptionScorer, ADetectionOfAConeOffTheTrackIsNeitherTrueNorFalse) {
  PerceptionScorer scorer(Vec2::Zero());
  const std::vector<TrueConeInView> truth = {{1, ConeClass::kBlue, {5.0, 0.0}}};
  const int spare = core::ObservationLabels::off_track_cone(3);
  const std::vector<OffTrackConeInView> off_track = {{spare, {5.0, 0.9}}, {spare - 1, {9.0, 4.0}}};
  const auto ids = scorer.add_frame(detections({{{5.0, 0.2}, ConeClass::kBlue},     // the track's
                                                {{5.0, 0.8}, ConeClass::kBlue},     // the spare's
                                                {{9.0, 4.6}, ConeClass::kYellow},   // the other's
                                                {{12.0, 0.0}, ConeClass::kBlue}}),  // nothing's
                                    truth, off_track);
  EXPECT_EQ(ids, (std::vector<int>{1, spare, spare - 1, -1}));
  EXPECT_TRUE(core::ObservationLabels::is_off_track_cone(ids[1]));
  EXPECT_FALSE(core::ObservationLabels::is_off_track_cone(core::ObservationLabels::kFalsePositive));
  const nlohmann::json m = scorer.metrics();
  EXPECT_EQ(m["detections"], 2);
  EXPECT_EQ(m["matched"], 1);
  EXPECT_EQ(m["off_track_cone_detections"], 2);
  EXPECT_DOUBLE_EQ(value(m["precision"]), 0.5);
  // without the off-track cones the same frame has three false detections
  PerceptionScorer plain(Vec2::Zero());
  plain.add_frame(detections({{{5.0, 0.2}, ConeClass::kBlue},
                              {{5.0, 0.8}, ConeClass::kBlue},
                              {{9.0, 4.6}, ConeClass::kYellow},
                              {{12.0, 0.0}, ConeClass::kBlue}}),
                  truth);
  EXPECT_DOUBLE_EQ(value(plain.metrics()["precision"]), 0.25);
}

TEST(PerceptionScorer, MatchesOneToOneAtTheLeastTotalDistance) {
  // the first detection is closest to P, but taking P would leave the second with nothing
  // within 1 m: both are detections of a cone
  PerceptionScorer scorer(Vec2::Zero());
  const std::vector<TrueConeInView> truth = {{1, ConeClass::kBlue, {5.0, 0.0}},
                                             {2, ConeClass::kBlue, {5.0, 0.8}}};
  const auto ids = scorer.add_frame(
      detections({{{5.0, 0.35}, ConeClass::kBlue}, {{5.0, -0.5}, ConeClass::kBlue}}), truth);
  EXPECT_EQ(ids, (std::vector<int>{2, 1}));
  EXPECT_DOUBLE_EQ(value(scorer.metrics()["recall"]), 1.0);
  EXPECT_DOUBLE_EQ(value(scorer.metrics()["precision"]), 1.0);
}

TEST(PerceptionScorer, AMatchedDetectionCountsInItsTrueConesBandAcrossFrames) {
  PerceptionScorer scorer(Vec2::Zero());
  // frame 1: the true cone at 9.8 m (band 1) seen at 10.3 m; frame 2: nothing seen
  const std::vector<TrueConeInView> truth = {{7, ConeClass::kYellow, {9.8, 0.0}}};
  EXPECT_EQ(scorer.add_frame(detections({{{10.3, 0.0}, ConeClass::kYellow}}), truth),
            (std::vector<int>{7}));
  EXPECT_TRUE(scorer.add_frame(detections({}), truth).empty());
  const nlohmann::json m = scorer.metrics();
  EXPECT_EQ(m["frames"], 2);
  EXPECT_EQ(m["bands"][1]["true_cones"], 2);
  EXPECT_EQ(m["bands"][1]["detections"], 1);
  EXPECT_EQ(m["bands"][1]["matched"], 1);
  EXPECT_EQ(m["bands"][2]["detections"], 0);
  EXPECT_DOUBLE_EQ(value(m["recall"]), 0.5);
  EXPECT_DOUBLE_EQ(value(m["precision"]), 1.0);
  EXPECT_NEAR(value(m["position_rmse_m"]), 0.5, 1e-12);
  EXPECT_DOUBLE_EQ(value(m["colour_accuracy_10m"]), 1.0);
}

TEST(PerceptionScorer, RejectsMeaninglessBands) {
  EXPECT_THROW(PerceptionScorer(Vec2::Zero(), 0.0), std::invalid_argument);
  EXPECT_THROW(PerceptionScorer(Vec2::Zero(), 5.0, -1.0), std::invalid_argument);
}

TEST(PerceptionScorer, DrawsTheBandsPlot) {
  namespace fs = std::filesystem;
  PerceptionScorer scorer(Vec2::Zero());
  scorer.add_frame(detections({{{4.0, 0.1}, ConeClass::kBlue}}),
                   {{1, ConeClass::kBlue, {4.0, 0.0}}, {2, ConeClass::kYellow, {14.0, 0.0}}});
  const fs::path png =
      fs::temp_directory_path() / ("conesim-perception-" + std::to_string(::getpid()) + ".png");
  scorer.write_bands_plot(png);
  EXPECT_TRUE(fs::exists(png));
  EXPECT_GT(fs::file_size(png), 1000u);
  fs::remove(png);
  // before any frame: empty axes rather than a gnuplot error
  PerceptionScorer(Vec2::Zero()).write_bands_plot(png);
  EXPECT_TRUE(fs::exists(png));
  fs::remove(png);
}

}  // namespace
}  // namespace conesim::sim
