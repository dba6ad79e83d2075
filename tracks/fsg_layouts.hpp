#pragma once
// The FSG skidpad and acceleration layouts, generated from the handbook geometry.

#include "tracks/track.hpp"

namespace conesim::tracks {

/// Distance between the two skidpad circle centres (FSG handbook), metres.
inline constexpr double kSkidpadCentreDistanceM = 18.25;
/// Inner and outer diameter of the skidpad driving area (FSG handbook), metres.
inline constexpr double kSkidpadInnerDiameterM = 15.25;
inline constexpr double kSkidpadOuterDiameterM = 21.25;
/// The cones stand this far outside the driving area, as in fssim's skidpad: inner ring radius
/// 7.625 - 0.15 = 7.475 m, outer ring radius 10.625 + 0.15 = 10.775 m.
inline constexpr double kSkidpadConeOffsetM = 0.15;
/// Radius of the ring of inner cones, metres.
inline constexpr double kSkidpadInnerConeRadiusM = kSkidpadInnerDiameterM / 2 - kSkidpadConeOffsetM;
/// Radius of the ring of outer cones, metres.
inline constexpr double kSkidpadOuterConeRadiusM = kSkidpadOuterDiameterM / 2 + kSkidpadConeOffsetM;
/// Distance from the start pose to the timing line (fssim's front-wing start; PacSim: 16.68 m).
inline constexpr double kSkidpadStartToTimingLineM = 16.5;

/// Distance from the acceleration start line to the finish line (FSG handbook), metres.
inline constexpr double kAccelerationLengthM = 75.0;
/// Lateral offset of the acceleration cones from the centre line (fssim and PacSim), metres.
inline constexpr double kAccelerationHalfWidthM = 1.9;
/// Length of the braking zone beyond the finish line (FSG handbook and PacSim; fssim: 100 m).
inline constexpr double kAccelerationBrakingZoneM = 75.0;
/// Distance of the start pose behind the acceleration start line, metres.
inline constexpr double kAccelerationStartSetbackM = 0.3;

/// Skidpad: two circles with centres 18.25 m apart, inner diameter 15.25 m and outer 21.25 m,
/// entry and exit lanes, small orange cones on the lanes and big orange cones at the timing
/// line. Track frame: start pose at the origin facing +x, the timing line where the circles
/// touch. The centre line is the driving path: entry, two right laps, two left laps, exit.
/// The right circle has yellow cones inside and blue outside, the left circle blue inside and
/// yellow outside (PacSim and the FSG handbook; fssim's file swaps them).
Track make_skidpad();

/// The skidpad's driving path for a layout whose timing line has its middle at timing_mid and
/// is crossed along forward: from the start (moved onto the entry line) to the timing line, two
/// clockwise laps of the right circle, two counter-clockwise laps of the left one, and 20 m of
/// exit. Points every 0.5 m or a little less.
std::vector<Vec2> skidpad_driving_path(const Vec2& timing_mid, const Vec2& forward,
                                       const Vec2& start);

/// Acceleration: 75 m between start and finish gate, 3 m or more wide, big orange cones at both
/// gates and a braking zone of orange cones beyond the finish. Start pose 0.3 m behind the
/// start line facing +x.
Track make_acceleration();

}  // namespace conesim::tracks
