#pragma once
// Whether a circuit can be driven by the car at all, checked before a run from the layout's
// lanes: the narrowest place against the car's width, and the tightest turn of the widest way
// through (the least-curvature line with the footprint just clear of the cones) against the
// car's turning circle. A refusal names the place and the reason.

#include <string>
#include <vector>

#include "control/driver.hpp"
#include "control/path.hpp"

namespace conesim::control {

/// What the check needs to know of the car beyond its geometry.
struct DrivabilityLimits {
  /// Lateral tracking error the driver is allowed either side on top of the car's width
  /// (the narrowest lane the car is sent through is width + cone base + twice this), metres.
  double tracking_tolerance_m = 0.1;
  /// Tightest rear-axle radius the car turns at low speed on full lock (full_lock_radius_m of
  /// the vehicle when zero), metres.
  double min_turn_radius_m = 0.0;
  /// A line is refused only when it turns tighter than this share of that radius: the least-
  /// curvature line is not the line of the largest smallest radius, its 3 m chords read a
  /// polyline's corner as tighter than the car turns, and the car's corners may sweep between
  /// two cones of a boundary. Generated circuits whose line reads 3.9 m are driven clean.
  double radius_share = 0.8;
};

/// The verdict.
struct Drivability {
  bool drivable = true;
  /// Why not, with the place in the track frame, e.g. "lanes 1.90 m apart at (12.3, -4.5),
  /// the car needs 1.83 m"; empty when drivable.
  std::string reason;
  Vec2 where = Vec2::Zero();
  /// Narrowest lane width and the tightest radius of the widest line, metres.
  double min_width_m = 0.0;
  double min_line_radius_m = 0.0;
};

/// The rear-axle radius of the car on full lock at low speed: the kinematic radius over the
/// measured yaw gain at full lock, metres.
double full_lock_radius_m(const VehicleGeometry& vehicle);

/// Checks a closed or open layout: `left` and `right` are the ordered boundary cones, `centre`
/// the layout's centre line (evenly spaced, closed when the circuit is), `cones` every cone.
Drivability check_drivability(const std::vector<Vec2>& left, const std::vector<Vec2>& right,
                              const std::vector<Vec2>& centre, bool closed,
                              const std::vector<core::MapCone>& cones,
                              const VehicleGeometry& vehicle, const DrivabilityLimits& limits = {});

}  // namespace conesim::control
