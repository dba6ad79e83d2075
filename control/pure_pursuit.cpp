#include "control/pure_pursuit.hpp"

#include <algorithm>
#include <cmath>

namespace conesim::control {

Vec2 lookahead_point(const Path& path, const PathProjection& from, const Vec2& position,
                     double lookahead_m) {
  const size_t segments = path.segment_count();
  if (segments == 0) return path.points.empty() ? position : path.points.front();

  // walk the segments from the projection until one leaves the look-ahead circle
  Vec2 a = from.point;
  size_t i = from.segment;
  for (size_t k = 0; k < segments; ++k) {
    const Vec2 b = path.segment_end(i);
    if ((b - position).norm() >= lookahead_m) {
      // the circle crossing on [a, b]: solve |a + t (b - a) - position| = lookahead for t
      const Vec2 d = b - a, f = a - position;
      const double qa = d.squaredNorm(), qb = 2.0 * f.dot(d),
                   qc = f.squaredNorm() - lookahead_m * lookahead_m;
      const double disc = std::max(0.0, qb * qb - 4.0 * qa * qc);
      const double t = qa > 0.0 ? std::clamp((-qb + std::sqrt(disc)) / (2.0 * qa), 0.0, 1.0) : 1.0;
      return a + t * d;
    }
    a = b;
    if (!path.closed && i + 1 >= segments) break;
    i = (i + 1) % segments;
  }

  // an open path ended inside the circle: extend it straight along its last segment
  const Vec2& last = path.points.back();
  const Vec2 dir = (last - path.points[path.points.size() - 2]).normalized();
  const Vec2 f = last - position;
  const double along = f.dot(dir);
  const double extra =
      -along +
      std::sqrt(std::max(0.0, along * along - f.squaredNorm() + lookahead_m * lookahead_m));
  return last + std::max(0.0, extra) * dir;
}

PurePursuitCommand pure_pursuit(const PurePursuitParams& params, const core::Pose2& pose,
                                double speed_mps, const Path& path, const PathProjection& from) {
  PurePursuitCommand cmd;
  cmd.lookahead_m = std::max(params.lookahead_min_m, params.lookahead_gain_s * std::abs(speed_mps));
  if (path.points.empty()) return cmd;

  // target in the vehicle frame, then the arc through it: curvature 2 y / d^2
  cmd.target = lookahead_point(path, from, pose.position(), cmd.lookahead_m);
  const Vec2 local = pose.inverse_transform(cmd.target);
  const double d2 = std::max(local.squaredNorm(), 1e-6);
  cmd.curvature = 2.0 * local.y() / d2;
  cmd.steer_rad = std::clamp(std::atan(params.wheelbase_m * cmd.curvature), -params.max_steer_rad,
                             params.max_steer_rad);
  return cmd;
}

}  // namespace conesim::control
