#pragma once
// The acceleration course: a straight line fitted to the cones either side of it.

#include <vector>

#include "control/path.hpp"
#include "core/autonomy_types.hpp"

namespace conesim::control {

/// A straight course in the frame of the start pose: lateral offset y = offset_m + slope * x.
struct StraightCourse {
  double offset_m = 0.0;
  double slope = 0.0;
  /// Cones used on the left and right of it.
  int left_cones = 0;
  int right_cones = 0;
};

/// Fits the centre line of a straight lane to the cones ahead of `start` (map frame): a line
/// through each side's cones (least squares, one round of outlier rejection), the centre
/// between them or one side offset by half_width_m. The start heading when no cone is usable.
StraightCourse fit_straight_course(const std::vector<core::MapCone>& cones,
                                   const core::Pose2& start, double half_width_m);

/// The course as a path in the map frame from x_from_m to x_to_m along the start heading.
Path straight_course_path(const StraightCourse& course, const core::Pose2& start, double x_from_m,
                          double x_to_m, double spacing_m = 2.0);

}  // namespace conesim::control
