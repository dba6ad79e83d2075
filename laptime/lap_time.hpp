#pragma once
// The lap-time bound of a layout: the time the car would take at its full measured grip on a
// line it could drive, the yardstick the driver's laps are measured against. Trackdrive: a
// flying lap of the minimum-curvature line; autocross: the same lap from standstill at the
// start pose; acceleration: the 75 m from standstill 0.3 m behind the line; skidpad: one lap of
// the tightest circle the car fits in.

#include <optional>
#include <string>
#include <vector>

#include "core/geometry.hpp"
#include "laptime/qss.hpp"
#include "laptime/racing_line.hpp"
#include "tracks/track.hpp"
#include "vehicle_models/vehicle_params.hpp"

namespace conesim::laptime {

/// Options of the bound.
struct LapTimeOptions {
  /// Share of the measured grip the bound drives at (1: all of it).
  double grip_fraction = 1.0;
  /// The event whose timing applies; recognised from the layout when not given.
  std::optional<tracks::EventType> event;
  /// Spacing of the speed profile's points, metres.
  double step_m = 0.25;
  /// Distance the line keeps from cone centres; half the car's width plus a small cone's base
  /// radius when not given, metres.
  std::optional<double> clearance_m;
  /// The racing line's other settings (its clearance_m is replaced by the one above).
  RacingLineParams line;

  /// True when usable; otherwise false and a reason in `error` (when given).
  bool is_valid(std::string* error = nullptr) const;
};

/// The bound and the speed profile behind it.
struct LapTimeBound {
  /// False when the layout gives no line to drive (no centre line, no skidpad circles); then
  /// `message` says why and the figures are zero.
  bool usable = false;
  std::string message;
  tracks::EventType event = tracks::EventType::kTrackdrive;
  /// Time of one timed lap (acceleration: start to finish gate), seconds.
  double lap_time_s = 0.0;
  /// Length of the timed line, metres.
  double line_length_m = 0.0;
  double top_speed_mps = 0.0;
  double min_speed_mps = 0.0;
  /// Distance from the timing line along the driven line, metres, with the speed there (one
  /// timed lap: the profile the plot compares the driven speed with).
  std::vector<double> s_m;
  std::vector<double> speed_mps;
  /// The line driven, from the timing line on (closed circuits: one lap).
  std::vector<core::Vec2> line;
};

/// Computes the bound of `track` for the car `vehicle`.
LapTimeBound lap_time_bound(const tracks::Track& track,
                            const vehicle_models::VehicleParams& vehicle,
                            const LapTimeOptions& options = {});

}  // namespace conesim::laptime
