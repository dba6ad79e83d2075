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

double yaw_gain_at(const std::vector<std::pair<double, double>>& table, double d) {
  d = std::abs(d);
  if (table.empty()) return 1.0;
  if (d <= table.front().first) return table.front().second;
  for (size_t i = 1; i < table.size(); ++i) {
    if (d > table[i].first) continue;
    const auto& [d0, g0] = table[i - 1];
    const auto& [d1, g1] = table[i];
    return g0 + (d - d0) / (d1 - d0) * (g1 - g0);
  }
  return table.back().second;
}

double steer_for_curvature(const TrackerParams& params, double k) {
  // tan(d) / L gain(d) = k, by fixed-point iteration from the kinematic angle
  double d = std::atan(params.wheelbase_m * k);
  for (int i = 0; i < 6; ++i)
    d = std::atan(params.wheelbase_m * k / std::max(0.3, yaw_gain_at(params.yaw_gain, d)));
  return std::clamp(d, -params.max_steer_rad, params.max_steer_rad);
}

double curvature_for_steer(const TrackerParams& params, double d) {
  return std::tan(d) * yaw_gain_at(params.yaw_gain, d) / params.wheelbase_m;
}

double track_path(const TrackerParams& params, const core::Pose2& pose, double speed_mps,
                  const Path& path, const PathProjection& from, double curvature_ahead) {
  if (path.segment_count() == 0) return 0.0;

  // errors of the rear axle: lateral (positive left of the path) and heading
  const Vec2 a = path.points[from.segment], b = path.segment_end(from.segment);
  const Vec2 t = (b - a).norm() > 1e-9 ? Vec2((b - a).normalized()) : pose.heading();
  const double lateral = core::cross(t, pose.position() - from.point);
  const double heading = core::normalize_angle(pose.yaw - std::atan2(t.y(), t.x()));

  // second-order error dynamics over distance, the frequency capped in time at speed
  const double v = std::max(1.0, std::abs(speed_mps));
  const double w = std::min(params.frequency_per_m, params.max_frequency_rps / v);
  const double k = curvature_ahead - w * w * lateral - 2.0 * params.damping * w * std::sin(heading);
  return steer_for_curvature(params, k);
}

}  // namespace conesim::control
