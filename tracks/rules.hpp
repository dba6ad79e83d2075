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
  /// Advice only (no big orange cones at the start): the layout is still legal.
  bool warning = false;

  /// "rule at (x, y): message", with " (warning)" appended for advice.
  std::string to_string() const;
};

/// Limits from the FSG handbook (D8 / DV rules) with a small tolerance for surveyed tracks.
/// Lengths, widths and spacings are measured between cone centres.
struct RuleLimits {
  /// Lap (closed) or course (open autocross) length along the centre line.
  double min_lap_m = 200.0;
  double max_lap_m = 500.0;
  /// Smallest distance from a boundary cone to the other boundary.
  double min_width_m = 3.0;
  /// Longest straight: a stretch whose heading stays within straight_heading_tolerance_deg.
  double max_straight_m = 80.0;
  /// Largest diameter of a constant turn: a stretch turning one way by wide_turn_min_sweep_deg
  /// or more while its radius of curvature stays above max_turn_diameter_m / 2 is a violation.
  double max_turn_diameter_m = 50.0;
  /// Smallest outer diameter of a hairpin: twice the radius of the outer boundary (about the
  /// centre-line radius + half the width) at the tightest point, fitted to that boundary's cones
  /// over +-3 m; counted only where the centre line turns the same way at least as tightly, so
  /// one misplaced cone on a straight is no hairpin.
  double min_hairpin_outer_diameter_m = 9.0;
  /// Largest gap between consecutive cones of a boundary (closed lanes: the closing gap too).
  double max_cone_spacing_m = 5.0;
  /// Slalom cone spacing (not checked yet: slaloms are not recognised).
  double slalom_min_spacing_m = 7.5;
  double slalom_max_spacing_m = 12.0;

  /// A measured length within this of a limit passes: surveyed cones are placed and measured to
  /// a few centimetres. Real tracks' 5.3 m gaps still fail the 5 m spacing rule.
  double survey_tolerance_m = 0.05;
  /// Heading change allowed along a straight, degrees (chord headings over about 3 m).
  double straight_heading_tolerance_deg = 3.0;
  /// Turning angle from which a wide turn counts as a constant turn, degrees (a quarter circle).
  double wide_turn_min_sweep_deg = 90.0;
  /// Fewest cones a boundary lane may have.
  int min_lane_cones = 3;
  /// Big orange cones must lie this close to the start pose on closed circuits (a warning).
  double start_finish_search_m = 20.0;
  /// Skidpad: circle centres 18.25 m apart within this tolerance.
  double skidpad_centre_distance_tolerance_m = 0.5;
  /// Skidpad: fitted cone-ring radii within this of 7.475 m (inner) and 10.775 m (outer).
  double skidpad_radius_tolerance_m = 0.3;
  /// Acceleration: 75 m between the start and the finish gate within this tolerance.
  double acceleration_length_tolerance_m = 1.0;
  /// Acceleration: largest sideways departure of the centre line from the gate-to-gate line.
  double acceleration_max_deviation_m = 1.0;

  /// True when the limits are usable; otherwise false and a reason in `error` (when given).
  bool is_valid(std::string* error = nullptr) const;
};

/// Geometry figures of a layout (for `conesim track info`).
struct TrackStats {
  /// Centre-line length (one lap for a closed circuit, closing segment included), metres.
  double length_m = 0.0;
  /// Smallest distance between the two boundaries along the track (from each cone of a lane to
  /// the other lane's polyline), metres; 0 when a lane is empty.
  double min_width_m = 0.0;
  /// Largest gap between consecutive cones of a boundary (closing gap included), metres.
  double max_spacing_m = 0.0;
  /// Smallest radius of curvature of the centre line, from circles fitted over 8 m of line
  /// around each point (adjacent 1 m samples are too noisy), metres; infinity for a straight.
  double min_radius_m = 0.0;
};

/// Computes the figures above from the lanes and the centre line (derived when the track has
/// none).
TrackStats compute_stats(const Track& track);

/// One skidpad circle as fitted to the cones.
struct SkidpadCircleFit {
  Vec2 centre = Vec2::Zero();
  /// Radius of the inner ring of cones, metres.
  double inner_radius_m = 0.0;
  /// Radius of the outer ring of cones, metres; 0 when only one ring was found.
  double outer_radius_m = 0.0;
  /// Cones on each ring.
  int inner_cones = 0;
  int outer_cones = 0;
};

/// Fits the skidpad circles to the blue, yellow and unknown cones: rings of 8 or more cones
/// within 0.3 m of a circle, grouped by centre (at most four rings). A skidpad gives two
/// entries; other layouts give fewer or rings that make no figure eight.
std::vector<SkidpadCircleFit> fit_skidpad_circles(const Track& track);

/// The event whose rules apply: the track's own when it has one, otherwise recognised from the
/// layout (closed circuit: trackdrive; two rings of cones in a figure eight: skidpad; open,
/// nearly straight and 60-100 m between the gates or along the cones: acceleration; anything
/// else: autocross).
EventType infer_event(const Track& track);

/// Every rule of `event` the track breaks (and warnings); empty when it is compliant. Autocross
/// and trackdrive: lane_cones, lap_length, min_width, max_cone_spacing, max_straight,
/// max_turn_diameter, min_hairpin_diameter, boundary_crossing, boundary_self_crossing,
/// start_on_track, start_finish_cones (warning, closed circuits only). Skidpad: skidpad_circles,
/// skidpad_centre_distance, skidpad_inner_radius, skidpad_outer_radius, timing_gate.
/// Acceleration: lane_cones, timing_gates, acceleration_length, acceleration_straight,
/// min_width, braking_zone, start_on_track.
std::vector<Violation> check_rules(const Track& track, EventType event,
                                   const RuleLimits& limits = {});

/// True when none of the violations is more than a warning.
bool is_compliant(const std::vector<Violation>& violations);

}  // namespace conesim::tracks
