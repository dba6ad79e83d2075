#pragma once
// The FSG handbook's track rules, checked per event, and the figures `track info` prints.

#include <string>
#include <vector>

#include "tracks/track.hpp"

namespace conesim::tracks {

/// One rule broken, with where it happens.
struct Violation {
  /// Short rule id, e.g. "max_cone_spacing", "min_width", "lap_length".
  std::string rule;
  /// What is wrong, with the measured and the allowed value.
  std::string message;
  /// Where on the track (track frame, metres).
  Vec2 where = Vec2::Zero();

  /// "rule at (x, y): message".
  std::string to_string() const;
};

/// Limits from the FSG handbook (D8 / DV rules) with a small tolerance for surveyed tracks.
struct RuleLimits {
  double min_lap_m = 200.0;
  double max_lap_m = 500.0;
  double min_width_m = 3.0;
  double max_straight_m = 80.0;
  double max_turn_diameter_m = 50.0;
  double min_hairpin_outer_diameter_m = 9.0;
  double max_cone_spacing_m = 5.0;
  double slalom_min_spacing_m = 7.5;
  double slalom_max_spacing_m = 12.0;
};

/// Geometry figures of a layout (for `conesim track info`).
struct TrackStats {
  /// Centre-line length (one lap for a closed circuit), metres.
  double length_m = 0.0;
  /// Smallest distance between the two boundaries along the track, metres.
  double min_width_m = 0.0;
  /// Largest gap between consecutive cones of a boundary, metres.
  double max_spacing_m = 0.0;
  /// Smallest radius of curvature of the centre line, metres.
  double min_radius_m = 0.0;
};

/// Computes the figures above from the lanes and the centre line.
TrackStats compute_stats(const Track& track);

/// The event whose rules apply: the track's own when it has one, otherwise recognised from the
/// layout (closed circuit: trackdrive; open and straight: acceleration; figure eight: skidpad).
EventType infer_event(const Track& track);

/// Every rule of `event` the track breaks; empty when it is compliant.
std::vector<Violation> check_rules(const Track& track, EventType event,
                                   const RuleLimits& limits = {});

}  // namespace conesim::tracks
