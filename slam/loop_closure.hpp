#pragma once
// Loop closure detection after the FST Lisboa thesis: each landmark runs a small state machine
// (in view, left view, returned), and the loop is closed when enough landmarks first seen long
// ago return into view from the same direction. The big orange start cones are a second cue,
// guarded against the false triggers the RaceUp thesis describes (orange cones seen from the
// wrong place or direction, or before a lap can have been driven). A lap ends where it began:
// landmarks seen again after a hairpin also "return", so the loop closes only near the start
// pose, facing its way, with returned landmarks among the ones first seen at the start.

#include <string>

#include "core/geometry.hpp"

namespace conesim::slam {

/// Where a landmark stands in the loop closure state machine.
enum class LoopState {
  /// Seen and still in the field of view since it was created.
  kInView,
  /// Has left the field of view.
  kLeftView,
  /// Seen again after leaving the view, long after its first sighting, from a similar heading.
  kReturned,
};

/// Loop closure parameters.
struct LoopClosureConfig {
  /// No loop before this distance has been driven, m.
  double min_travel_m = 100.0;
  /// A landmark returns only when first seen at least this far back along the path, m.
  double returned_min_travel_m = 50.0;
  /// And when the heading now is within this of the heading at its first sighting, rad.
  double heading_tolerance_rad = 0.8;
  /// Returned landmarks needed to close the loop on the statistics alone.
  int min_returned = 8;
  /// Of the old landmarks (first seen beyond returned_min_travel_m) matched in the current
  /// batch, at least this fraction must be returned ones (the "loop closure factor", 0.8 in the
  /// FST thesis).
  double returned_fraction = 0.8;
  /// The big orange cue: a re-observed big orange landmark with a heading within this of its
  /// first sighting, plus this many returned landmarks, closes the loop.
  double big_orange_heading_rad = 0.5;
  int big_orange_min_returned = 3;
  /// The lap guard (back_at_start): the estimated pose is within this of the start pose, m,
  /// with its heading within heading_tolerance_rad of the start heading,
  double start_radius_m = 20.0;
  /// within this of the line through the start pose along its heading, m (the lap ends in the
  /// start's lane; on the shared circuits a lap was seen to close up to 4.5 m off that line,
  /// where the lane bends towards the start),
  double start_lateral_m = 8.0;
  /// the car has turned once around since the start, to within heading_tolerance_rad,
  /// and at least start_min_returned of the returned landmarks were first seen within this
  /// distance driven from the start, m.
  double start_window_m = 20.0;
  int start_min_returned = 3;
  /// Mapping goes on for this distance after the loop is seen to close, so that the lap's end
  /// is tied to the start's landmarks by many observations before the whole graph is solved
  /// and the map fixed, m.
  double closure_delay_m = 20.0;

  /// Empty when usable, otherwise "loop_closure.key: what was expected".
  std::string validate() const;
};

/// True when `turned_rad`, a heading change summed over a drive (not wrapped), is one full turn
/// either way, to within `tolerance_rad`: what one lap of a circuit without crossings turns.
bool turned_once_around(double turned_rad, double tolerance_rad);

/// The lap guard on the pose: true when `pose`, having turned by `turned_rad` (the heading
/// change summed since the start, not wrapped) is back where the lap began at `start`: within
/// start_radius_m of it and start_lateral_m of its line, facing its way, and turned once around.
/// A circuit without crossings turns the car by one full turn a lap, either way; a leg that runs
/// alongside the start the same way, reached through two opposite hairpins, has turned by none,
/// and its view of the start's cones is no lap (hard trackdrives 7041 and 7077 closed there).
bool back_at_start(const LoopClosureConfig& config, const core::Pose2& start,
                   const core::Pose2& pose, double turned_rad);

/// What a landmark's state becomes after one batch.
/// in_view: predicted in the field of view; observed: matched in this batch;
/// travel_since_first_m: path length since its first sighting; heading_change_rad: heading now
/// minus heading at its first sighting (wrapped).
LoopState next_loop_state(const LoopClosureConfig& config, LoopState state, bool in_view,
                          bool observed, double travel_since_first_m, double heading_change_rad);

/// The statistics of one batch that the decision rests on.
struct LoopClosureStats {
  /// Path length driven so far, m.
  double travel_m = 0.0;
  /// Landmarks in the returned state (all of them).
  int returned = 0;
  /// Old landmarks (first seen beyond returned_min_travel_m) matched in this batch, and how
  /// many of them are returned.
  int old_matched = 0;
  int old_matched_returned = 0;
  /// A big orange landmark first seen long ago was matched with a consistent heading.
  bool big_orange_returned = false;
  /// The estimated pose is back at the start (back_at_start).
  bool near_start = false;
  /// Returned landmarks that were first seen within start_window_m of the start.
  int start_returned = 0;
};

/// True when the loop has closed, by the returned-landmark statistics or by the big orange cue,
/// and the lap guard holds.
bool loop_closed(const LoopClosureConfig& config, const LoopClosureStats& stats);

}  // namespace conesim::slam
