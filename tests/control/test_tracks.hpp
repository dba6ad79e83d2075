#pragma once
// Hard test circuits for the driver: a closed centre line built from straights, arcs, a slalom
// and a chicane, with cones on both boundaries at a set width and spacing (or on one side only
// over a stretch), the start on the first straight.

#include <cmath>
#include <numbers>
#include <vector>

#include "control/path.hpp"
#include "tracks/track.hpp"

namespace conesim::control::testing {

/// A closed counter-clockwise circle about the origin starting at its bottom, points about
/// every spacing_m.
inline Path circle_path(double radius, double spacing_m) {
  Path path;
  path.closed = true;
  const int n = static_cast<int>(std::ceil(2.0 * std::numbers::pi * radius / spacing_m));
  for (int i = 0; i < n; ++i) {
    const double phi = -0.5 * std::numbers::pi + 2.0 * std::numbers::pi * i / n;
    path.points.push_back(radius * core::Vec2(std::cos(phi), std::sin(phi)));
  }
  return path;
}

/// A centre line drawn piece by piece with a pen that has a position and a heading.
class CentreLine {
 public:
  /// A straight of `length_m`.
  CentreLine& straight(double length_m) {
    for (double s = kStepM; s <= length_m + 1e-9; s += kStepM) add(pos_ + s * dir());
    pos_ = points_.back();
    return *this;
  }
  /// An arc of `radius_m` turning by `angle_rad` (positive left).
  CentreLine& arc(double radius_m, double angle_rad) {
    const double sign = angle_rad >= 0.0 ? 1.0 : -1.0;
    const double length = radius_m * std::abs(angle_rad);
    const core::Vec2 centre = pos_ + sign * radius_m * core::Vec2(-dir().y(), dir().x());
    const double start_angle = std::atan2(pos_.y() - centre.y(), pos_.x() - centre.x());
    for (double s = kStepM; s <= length + 1e-9; s += kStepM) {
      const double a = start_angle + sign * s / radius_m;
      add(centre + radius_m * core::Vec2(std::cos(a), std::sin(a)));
    }
    yaw_ += angle_rad;
    pos_ = centre + radius_m * core::Vec2(std::cos(start_angle + angle_rad),
                                          std::sin(start_angle + angle_rad));
    return *this;
  }
  /// A sideways shift by `offset_m` over `length_m` (a chicane), keeping the heading.
  CentreLine& shift(double offset_m, double length_m) {
    const core::Vec2 d = dir(), n(-d.y(), d.x());
    for (double s = kStepM; s <= length_m + 1e-9; s += kStepM)
      add(pos_ + s * d + offset_m * 0.5 * (1.0 - std::cos(std::numbers::pi * s / length_m)) * n);
    pos_ = pos_ + length_m * d + offset_m * n;
    return *this;
  }
  const std::vector<core::Vec2>& points() const { return points_; }
  core::Vec2 position() const { return pos_; }

 private:
  static constexpr double kStepM = 0.1;
  core::Vec2 dir() const { return {std::cos(yaw_), std::sin(yaw_)}; }
  void add(const core::Vec2& p) { points_.push_back(p); }
  std::vector<core::Vec2> points_{core::Vec2::Zero()};
  core::Vec2 pos_ = core::Vec2::Zero();
  double yaw_ = 0.0;
};

/// A closed circuit along `centre` (which must come back to the origin heading +x): blue cones
/// width_m / 2 to the left, yellow to the right, each boundary resampled every spacing_m; the
/// right cones whose centre-line arc length lies in [gap_from_m, gap_to_m) are left out.
inline tracks::Track circuit_from_centre(const std::vector<core::Vec2>& centre, double width_m,
                                         double spacing_m, double gap_from_m = 0.0,
                                         double gap_to_m = 0.0) {
  tracks::Track t;
  t.name = "test-circuit";
  t.closed = true;
  const size_t n = centre.size() - 1;  // the last point repeats the first
  std::vector<core::Vec2> left, right;
  std::vector<double> right_s;
  double s = 0.0;
  for (size_t i = 0; i < n; ++i) {
    const core::Vec2 d = (centre[(i + 1) % n] - centre[(i + n - 1) % n]).normalized();
    const core::Vec2 normal(-d.y(), d.x());
    left.push_back(centre[i] + 0.5 * width_m * normal);
    right.push_back(centre[i] - 0.5 * width_m * normal);
    right_s.push_back(s);
    s += (centre[i + 1] - centre[i]).norm();
  }
  auto place = [&](const std::vector<core::Vec2>& line, core::ConeClass cls, std::vector<int>& lane,
                   bool gap) {
    // a cone every spacing_m along the boundary polyline
    double walked = 0.0, next = 0.0;
    for (size_t i = 0; i < line.size(); ++i) {
      const double step = (line[(i + 1) % line.size()] - line[i]).norm();
      if (walked + 1e-9 >= next) {
        if (!(gap && right_s[i] >= gap_from_m && right_s[i] < gap_to_m)) {
          const int id = static_cast<int>(t.cones.size());
          t.cones.push_back({id, cls, line[i], std::nullopt});
          lane.push_back(id);
        }
        next += spacing_m;
      }
      walked += step;
    }
  };
  place(left, core::ConeClass::kBlue, t.left_lane, false);
  place(right, core::ConeClass::kYellow, t.right_lane, true);
  t.start = {5.0, 0.0, 0.0};
  t.timing_gates.push_back({{5.0, 0.5 * width_m + 0.5}, {5.0, -0.5 * width_m - 0.5}});
  t.centre_line = resample(std::vector<core::Vec2>(centre.begin(), centre.end() - 1), 1.0, true);
  return t;
}

}  // namespace conesim::control::testing
