#pragma once
// Planar geometry shared by every module: points, SE(2) poses and angle helpers.

#include <Eigen/Core>
#include <cmath>
#include <numbers>
#include <string>

namespace conesim::core {

/// A point or vector in the plane, metres.
using Vec2 = Eigen::Vector2d;

/// Wraps an angle to (-pi, pi].
inline double normalize_angle(double a) {
  a = std::remainder(a, 2.0 * std::numbers::pi);
  return a <= -std::numbers::pi ? a + 2.0 * std::numbers::pi : a;
}

/// A rigid transform in the plane: position in metres and heading in radians (x forward, y left).
struct Pose2 {
  double x = 0.0;
  double y = 0.0;
  double yaw = 0.0;

  /// The position part as a vector.
  Vec2 position() const { return {x, y}; }

  /// Unit vector along the heading.
  Vec2 heading() const { return {std::cos(yaw), std::sin(yaw)}; }

  /// Maps a point from this pose's frame into the parent frame.
  Vec2 transform(const Vec2& p_local) const {
    const double c = std::cos(yaw), s = std::sin(yaw);
    return {x + c * p_local.x() - s * p_local.y(), y + s * p_local.x() + c * p_local.y()};
  }

  /// Maps a point from the parent frame into this pose's frame.
  Vec2 inverse_transform(const Vec2& p) const {
    const double c = std::cos(yaw), s = std::sin(yaw);
    const double dx = p.x() - x, dy = p.y() - y;
    return {c * dx + s * dy, -s * dx + c * dy};
  }

  /// Composition this * other (other expressed in this frame).
  Pose2 compose(const Pose2& other) const {
    const Vec2 p = transform(other.position());
    return {p.x(), p.y(), normalize_angle(yaw + other.yaw)};
  }

  /// The inverse transform.
  Pose2 inverse() const {
    const Vec2 p = inverse_transform({0.0, 0.0});
    return {p.x(), p.y(), normalize_angle(-yaw)};
  }
};

/// 2D cross product (z component of a x b).
inline double cross(const Vec2& a, const Vec2& b) {
  return a.x() * b.y() - a.y() * b.x();
}

/// Distance from point p to the segment [a, b].
double distance_to_segment(const Vec2& p, const Vec2& a, const Vec2& b);

/// True when the open segments [a1, a2] and [b1, b2] cross each other.
bool segments_intersect(const Vec2& a1, const Vec2& a2, const Vec2& b1, const Vec2& b2);

/// A place for people's messages, to a decimetre: "(12.3, -4.5)".
std::string format_place(const Vec2& p);

}  // namespace conesim::core
