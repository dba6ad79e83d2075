#include "control/straight_course.hpp"

#include <cmath>
#include <optional>

namespace conesim::control {

namespace {

// cones nearer the centre than this are across the lane (stop line), metres
constexpr double kMinLateralM = 0.5;
// and further than this are outside the lane, metres
constexpr double kMaxLateralM = 4.0;
// the first fit uses the cones up to this far along the start heading, the second all, metres
constexpr double kNearReachM = 30.0;
constexpr double kFarReachM = 1e9;
// residual beyond which a cone is dropped from the second fit, metres
constexpr double kOutlierM = 0.5;

// a line y = a + b x through the points
struct Line {
  double a = 0.0;
  double b = 0.0;
};

// least-squares line; the slope is zero when the points span too little x
std::optional<Line> fit_line(const std::vector<Vec2>& pts) {
  if (pts.empty()) return std::nullopt;
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (const Vec2& p : pts) sx += p.x(), sy += p.y(), sxx += p.x() * p.x(), sxy += p.x() * p.y();
  const double n = static_cast<double>(pts.size());
  const double det = n * sxx - sx * sx;
  if (pts.size() < 2 || det < 1.0) return Line{sy / n, 0.0};
  const double b = (n * sxy - sx * sy) / det;
  return Line{(sy - b * sx) / n, b};
}

// the line fitted twice, the second time without the points far from the first
std::optional<Line> robust_fit(const std::vector<Vec2>& pts) {
  const std::optional<Line> first = fit_line(pts);
  if (!first) return first;
  std::vector<Vec2> kept;
  for (const Vec2& p : pts)
    if (std::abs(p.y() - (first->a + first->b * p.x())) < kOutlierM) kept.push_back(p);
  return kept.size() >= 2 ? fit_line(kept) : first;
}

}  // namespace

StraightCourse fit_straight_course(const std::vector<core::MapCone>& cones,
                                   const core::Pose2& start, double half_width_m) {
  // two rounds: the cones near the start sorted by the start heading, then all of them sorted
  // by the side of the first line they lie on (a small heading error would move far cones
  // across the start heading)
  StraightCourse course;
  for (const double reach_m : {kNearReachM, kFarReachM}) {
    std::vector<Vec2> left, right;
    for (const core::MapCone& c : cones) {
      const Vec2 p = start.inverse_transform(c.position);
      const double lateral = p.y() - (course.offset_m + course.slope * p.x());
      if (p.x() < -5.0 || p.x() > reach_m) continue;
      if (std::abs(lateral) < kMinLateralM || std::abs(lateral) > kMaxLateralM) continue;
      (lateral > 0.0 ? left : right).push_back(p);
    }

    // both sides: the middle; one side: offset inwards; none: the start heading
    course.left_cones = static_cast<int>(left.size());
    course.right_cones = static_cast<int>(right.size());
    const std::optional<Line> l = robust_fit(left), r = robust_fit(right);
    if (l && r) {
      course.offset_m = 0.5 * (l->a + r->a);
      course.slope = 0.5 * (l->b + r->b);
    } else if (l) {
      course.offset_m = l->a - half_width_m;
      course.slope = l->b;
    } else if (r) {
      course.offset_m = r->a + half_width_m;
      course.slope = r->b;
    }
  }
  return course;
}

Path straight_course_path(const StraightCourse& course, const core::Pose2& start, double x_from_m,
                          double x_to_m, double spacing_m) {
  Path path;
  const int n = std::max(1, static_cast<int>(std::ceil((x_to_m - x_from_m) / spacing_m)));
  for (int i = 0; i <= n; ++i) {
    const double x = x_from_m + (x_to_m - x_from_m) * i / n;
    path.points.push_back(start.transform({x, course.offset_m + course.slope * x}));
  }
  return path;
}

}  // namespace conesim::control
