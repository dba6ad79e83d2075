#pragma once
// Small helpers on the SDK's poses, in the conesim_sdk library.

#include "conesim/sdk/types.hpp"

namespace conesim::sdk {

/// Wraps an angle to (-pi, pi].
double normalize_angle(double rad);

/// Composition a * b (b expressed in a's frame).
Pose2 compose(const Pose2& a, const Pose2& b);

/// The inverse transform of a pose.
Pose2 inverse(const Pose2& a);

/// Maps a point (x, y) from the pose's frame into its parent frame.
void transform(const Pose2& pose, double x, double y, double* out_x, double* out_y);

/// conesim's name of a class: blue, yellow, orange_small, orange_big, unknown.
const char* to_string(ConeClass c);

}  // namespace conesim::sdk
