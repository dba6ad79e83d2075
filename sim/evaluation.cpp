#include "sim/evaluation.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "sim/gnuplot.hpp"
#include "sim/json_text.hpp"

namespace conesim::sim {

std::vector<int> match_points(const std::vector<core::Vec2>& a, const std::vector<core::Vec2>& b,
                              double cutoff_m) {
  Eigen::MatrixXd distance(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i)
    for (size_t j = 0; j < b.size(); ++j) distance(i, j) = (a[i] - b[j]).norm();
  return hungarian_assign(distance, cutoff_m);
}

core::Pose2 align_se2(const std::vector<core::Vec2>& from, const std::vector<core::Vec2>& to) {
  if (from.size() != to.size())
    throw std::invalid_argument("align_se2: " + std::to_string(from.size()) + " points to " +
                                std::to_string(to.size()));
  if (from.empty()) return {};
  // centroids
  core::Vec2 from_mean = core::Vec2::Zero(), to_mean = core::Vec2::Zero();
  for (size_t i = 0; i < from.size(); ++i) {
    from_mean += from[i];
    to_mean += to[i];
  }
  from_mean /= static_cast<double>(from.size());
  to_mean /= static_cast<double>(to.size());
  // the rotation maximising sum b . R a over the centred points: atan2(sum a x b, sum a . b)
  double sum_cross = 0.0, sum_dot = 0.0;
  for (size_t i = 0; i < from.size(); ++i) {
    const core::Vec2 a = from[i] - from_mean, b = to[i] - to_mean;
    sum_cross += core::cross(a, b);
    sum_dot += a.dot(b);
  }
  const double yaw = (sum_cross == 0.0 && sum_dot == 0.0) ? 0.0 : std::atan2(sum_cross, sum_dot);
  // the translation that carries the rotated centroid onto the target centroid
  const core::Pose2 rotation{0.0, 0.0, yaw};
  const core::Vec2 t = to_mean - rotation.transform(from_mean);
  return {t.x(), t.y(), yaw};
}

PerceptionScorer::PerceptionScorer(core::Vec2 sensor_in_vehicle, double band_m, double max_range_m,
                                   double cutoff_m)
    : sensor_(sensor_in_vehicle), band_m_(band_m), max_range_m_(max_range_m), cutoff_m_(cutoff_m) {
  if (!(band_m > 0.0) || !(max_range_m > 0.0) || !(cutoff_m > 0.0))
    throw std::invalid_argument("PerceptionScorer: band_m, max_range_m and cutoff_m must be > 0");
  bands_.resize(static_cast<size_t>(std::ceil(max_range_m / band_m - 1e-9)));
}

void PerceptionScorer::count(double range_m, bool has_true, bool has_detection, bool colour_right,
                             double error_m) {
  auto add = [&](Tally& t) {
    t.true_cones += has_true;
    t.detections += has_detection;
    if (has_true && has_detection) {
      ++t.matched;
      t.colour_right += colour_right;
      t.error2_sum_m2 += error_m * error_m;
    }
  };
  if (!(range_m < max_range_m_)) return;
  add(bands_[std::min(bands_.size() - 1, static_cast<size_t>(range_m / band_m_))]);
  if (range_m < 15.0) add(within_15m_);
  if (range_m < 10.0) add(within_10m_);
}

int off_track_label_near(const std::vector<OffTrackConeInView>& off_track, const core::Vec2& at,
                         double cutoff_m) {
  int label = core::ObservationLabels::kFalsePositive;
  double nearest_m = cutoff_m;
  for (const OffTrackConeInView& o : off_track)
    if (const double d = (at - o.position).norm(); d <= nearest_m) nearest_m = d, label = o.label;
  return label;
}

std::vector<int> PerceptionScorer::add_frame(const core::ConeObservations& detections,
                                             const std::vector<TrueConeInView>& truth,
                                             const std::vector<OffTrackConeInView>& off_track) {
  ++frames_;
  // one to one by distance within the cut-off
  const auto& cones = detections.cones;
  Eigen::MatrixXd distance(cones.size(), truth.size());
  for (size_t i = 0; i < cones.size(); ++i)
    for (size_t j = 0; j < truth.size(); ++j)
      distance(i, j) = (cones[i].position - truth[j].position).norm();
  const std::vector<int> assignment = hungarian_assign(distance, cutoff_m_);

  // true cones, matched or missed, at their own range
  std::vector<int> detection_of_true(truth.size(), -1);
  for (size_t i = 0; i < cones.size(); ++i)
    if (assignment[i] >= 0) detection_of_true[assignment[i]] = static_cast<int>(i);
  for (size_t j = 0; j < truth.size(); ++j) {
    const double range_m = (truth[j].position - sensor_).norm();
    const int i = detection_of_true[j];
    if (i < 0) {
      count(range_m, true, false, false, 0.0);
    } else {
      count(range_m, true, true, cones[i].cls == truth[j].cls, distance(i, j));
    }
  }
  // unmatched detections at the range they were seen at
  std::vector<int> true_ids(cones.size(), -1);
  for (size_t i = 0; i < cones.size(); ++i) {
    if (assignment[i] >= 0) {
      true_ids[i] = truth[assignment[i]].id;
      continue;
    }
    // the nearest off-track cone within the cut-off takes it (not counted either way)
    true_ids[i] = off_track_label_near(off_track, cones[i].position, cutoff_m_);
    const double range_m = (cones[i].position - sensor_).norm();
    if (true_ids[i] == core::ObservationLabels::kFalsePositive)
      count(range_m, false, true, false, 0.0);
    else if (range_m < max_range_m_)
      ++off_track_detections_;
  }
  return true_ids;
}

nlohmann::json PerceptionScorer::ratios(const Tally& t) {
  auto ratio = [](double num, long den) -> nlohmann::json {
    if (den == 0) return nullptr;
    return num / static_cast<double>(den);
  };
  return {
      {"true_cones", t.true_cones},
      {"detections", t.detections},
      {"matched", t.matched},
      {"recall", ratio(static_cast<double>(t.matched), t.true_cones)},
      {"precision", ratio(static_cast<double>(t.matched), t.detections)},
      {"colour_accuracy", ratio(static_cast<double>(t.colour_right), t.matched)},
      {"position_rmse_m",
       t.matched ? nlohmann::json(std::sqrt(t.error2_sum_m2 / static_cast<double>(t.matched)))
                 : nlohmann::json(nullptr)},
  };
}

nlohmann::json PerceptionScorer::metrics() const {
  // the bands, and their sum for the overall figures
  Tally all;
  nlohmann::json bands = nlohmann::json::array();
  for (size_t b = 0; b < bands_.size(); ++b) {
    const Tally& t = bands_[b];
    all.true_cones += t.true_cones;
    all.detections += t.detections;
    all.matched += t.matched;
    all.colour_right += t.colour_right;
    all.error2_sum_m2 += t.error2_sum_m2;
    nlohmann::json band = ratios(t);
    band["from_m"] = static_cast<double>(b) * band_m_;
    band["to_m"] = std::min(static_cast<double>(b + 1) * band_m_, max_range_m_);
    bands.push_back(band);
  }
  nlohmann::json m = ratios(all);
  const nlohmann::json near15 = ratios(within_15m_), near10 = ratios(within_10m_);
  m["frames"] = frames_;
  m["max_range_m"] = max_range_m_;
  m["off_track_cone_detections"] = off_track_detections_;
  m["recall_15m"] = near15["recall"];
  m["precision_15m"] = near15["precision"];
  m["colour_accuracy_10m"] = near10["colour_accuracy"];
  m["bands"] = bands;
  return m;
}

void PerceptionScorer::write_bands_plot(const std::filesystem::path& png) const {
  // one row per band: centre, recall, precision, colour accuracy, rmse (NaN when undefined)
  const nlohmann::json m = metrics();
  PlotData rows{"bands", {}};
  auto number = [](const nlohmann::json& v) { return v.is_null() ? NAN : v.get<double>(); };
  for (const auto& b : m["bands"])
    rows.rows.push_back({0.5 * (b["from_m"].get<double>() + b["to_m"].get<double>()),
                         number(b["recall"]), number(b["precision"]), number(b["colour_accuracy"]),
                         number(b["position_rmse_m"])});
  if (rows.rows.empty()) rows.rows.push_back({NAN, NAN, NAN, NAN, NAN});
  const std::string range = "set xrange [0:" + std::to_string(max_range_m_) + "]\n";
  // gnuplot refuses a panel without a single point: a fixed scale when no error was measured
  bool any_rmse = false;
  for (const auto& row : rows.rows) any_rmse = any_rmse || std::isfinite(row[4]);
  const std::string rmse_range = any_rmse ? "set yrange [0:*]\n" : "set yrange [0:1]\n";
  render_png(
      "set datafile missing 'nan'\nset grid\nset multiplot layout 2,1\n" + range +
          "set title 'perception per " + json_text(nlohmann::json(band_m_)) +
          " m range band'\nset ylabel 'fraction'\nset yrange [0:1.05]\n"
          "set key bottom left\n"
          "plot $bands using 1:2 with linespoints lw 2 pt 7 lc rgb '#1f4fd8' title 'recall', "
          "$bands using 1:3 with linespoints lw 2 pt 5 lc rgb '#d62728' title 'precision', "
          "$bands using 1:4 with linespoints lw 2 pt 9 lc rgb '#e6b800' "
          "title 'colour accuracy'\n"
          "set title 'position error of matched detections'\n" +
          rmse_range +
          "set xlabel 'range from the sensor [m]'\n"
          "set ylabel 'RMSE [m]'\n"
          "plot $bands using 1:5 with linespoints lw 2 pt 7 lc rgb '#2ca02c' notitle\n"
          "unset multiplot\n",
      {rows}, png, 900, 800);
}

}  // namespace conesim::sim
