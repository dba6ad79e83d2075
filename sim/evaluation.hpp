#pragma once
// Scoring against ground truth: one-to-one matching (core/assignment.hpp), rigid 2D alignment, and the
// perception scorer (recall, precision, colour and position error per range band).

#include <Eigen/Core>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <vector>

#include "core/assignment.hpp"
#include "core/autonomy_types.hpp"
#include "core/cone.hpp"
#include "core/geometry.hpp"
#include "core/measurements.hpp"

namespace conesim::sim {

using core::hungarian_assign;

/// Points `a` matched one to one to points `b` within `cutoff_m` by hungarian_assign on their
/// distances: for each point of `a` the index of its point of `b`, or -1.
std::vector<int> match_points(const std::vector<core::Vec2>& a, const std::vector<core::Vec2>& b,
                              double cutoff_m);

/// The rigid transform T that best maps `from` onto `to` in the least-squares sense
/// (to[i] ~ T.transform(from[i])), in closed form. Throws std::invalid_argument when the sizes
/// differ; identity for no points, a pure translation for one.
core::Pose2 align_se2(const std::vector<core::Vec2>& from, const std::vector<core::Vec2>& to);

/// A true cone that the sensor could see, in the vehicle frame at the frame's stamp.
struct TrueConeInView {
  int id = -1;
  core::ConeClass cls = core::ConeClass::kUnknown;
  core::Vec2 position = core::Vec2::Zero();
};

/// A cone standing off the track in view (a spare cone of world.clutter), in the same frame:
/// detecting it is neither a true nor a false detection (as KITTI's DontCare regions), and its
/// detections are labelled with ObservationLabels::off_track_cone.
struct OffTrackConeInView {
  int label = core::ObservationLabels::kOffTrackCone;
  core::Vec2 position = core::Vec2::Zero();
};

/// The label of the off-track cone nearest to `at` within `cutoff_m`, or
/// ObservationLabels::kFalsePositive when none is that near.
int off_track_label_near(const std::vector<OffTrackConeInView>& off_track, const core::Vec2& at,
                         double cutoff_m);

/// Scores perception frame by frame against the true cones in view: recall, precision, colour
/// accuracy and position error overall and per range band (metrics.json `perception`).
class PerceptionScorer {
 public:
  /// Ranges are measured from `sensor_in_vehicle`; bands of `band_m` up to `max_range_m`;
  /// detections match true cones one to one within `cutoff_m`.
  explicit PerceptionScorer(core::Vec2 sensor_in_vehicle, double band_m = 5.0,
                            double max_range_m = 30.0, double cutoff_m = 1.0);

  /// Matches the frame's detections to the true cones in view (Hungarian on distance) and
  /// counts them. A true cone falls in the band of its range from the sensor, a matched
  /// detection in its true cone's band, an unmatched one in the band of its own range. Returns
  /// for each detection the id of its true cone, or -1. A detection left unmatched within the
  /// cut-off of an off-track cone is not counted, and gets that cone's label.
  std::vector<int> add_frame(const core::ConeObservations& detections,
                             const std::vector<TrueConeInView>& truth,
                             const std::vector<OffTrackConeInView>& off_track = {});

  /// The figures: recall, precision, colour_accuracy, position_rmse_m (all within
  /// max_range_m), frames, recall_15m, precision_15m, colour_accuracy_10m, and bands (from_m,
  /// to_m, true_cones, detections, matched, recall, precision, position_rmse_m,
  /// colour_accuracy). A ratio without a denominator is null.
  nlohmann::json metrics() const;

  /// Draws recall, precision and colour accuracy per band over the position RMSE per band
  /// (gnuplot PNG).
  void write_bands_plot(const std::filesystem::path& png) const;

 private:
  // counts over one range interval
  struct Tally {
    long true_cones = 0;
    long detections = 0;
    long matched = 0;
    long colour_right = 0;
    double error2_sum_m2 = 0.0;
  };
  static nlohmann::json ratios(const Tally& t);
  // adds a true cone (and its detection when matched) or an unmatched detection at range_m
  void count(double range_m, bool has_true, bool has_detection, bool colour_right, double error_m);

  core::Vec2 sensor_;
  double band_m_;
  double max_range_m_;
  double cutoff_m_;
  long frames_ = 0;
  // detections within max_range_m given to an off-track cone (counted neither way)
  long off_track_detections_ = 0;
  std::vector<Tally> bands_;
  Tally within_15m_;
  Tally within_10m_;
};

}  // namespace conesim::sim
