#pragma once
// The FSG skidpad and acceleration layouts, generated from the handbook geometry.

#include "tracks/track.hpp"

namespace conesim::tracks {

/// Skidpad: two circles with centres 18.25 m apart, inner diameter 15.25 m and outer 21.25 m,
/// entry and exit lanes, small orange cones on the lanes and big orange cones at the timing
/// line. Track frame: start pose at the origin facing +x, the timing line where the circles
/// touch. The centre line is the driving path: entry, two right laps, two left laps, exit.
Track make_skidpad();

/// Acceleration: 75 m between start and finish gate, 3 m or more wide, big orange cones at both
/// gates and a braking zone of orange cones beyond the finish. Start pose 0.3 m behind the
/// start line facing +x.
Track make_acceleration();

}  // namespace conesim::tracks
