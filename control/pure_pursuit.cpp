#include "control/pure_pursuit.hpp"

#include <algorithm>
#include <cmath>
#include <optional>

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

namespace {

// the tangent of the smooth curve through a path's points at a projection: each point's tangent
// is the mean of its two chords' directions, and along a chord the tangent turns from the one at
// its start to the one at its end; `turn_rad` is that turn (signed, left positive)
struct SmoothTangent {
  bool valid = false;
  Vec2 tangent = Vec2::UnitX();
  double turn_rad = 0.0;
};

SmoothTangent smooth_tangent(const Path& path, const PathProjection& on) {
  SmoothTangent r;
  const size_t n = path.segment_count();
  if (n == 0) return r;
  const size_t i = on.segment;
  auto direction = [&](size_t j) -> std::optional<Vec2> {
    const Vec2 d = path.segment_end(j) - path.points[j];
    if (d.norm() < 1e-9) return std::nullopt;
    return Vec2(d.normalized());
  };
  const std::optional<Vec2> here = direction(i);
  if (!here) return r;
  const bool has_prev = path.closed || i > 0;
  const bool has_next = path.closed || i + 1 < n;
  const std::optional<Vec2> prev = has_prev ? direction((i + n - 1) % n) : here;
  const std::optional<Vec2> next = has_next ? direction((i + 1) % n) : here;
  // a cusp (a chord turning back) has no tangent: fall back on the chord
  auto mean = [](const std::optional<Vec2>& u, const Vec2& v) -> std::optional<Vec2> {
    if (!u || u->dot(v) < 0.0) return std::nullopt;
    return Vec2((*u + v).normalized());
  };
  const std::optional<Vec2> ta = mean(prev, *here), tb = mean(next, *here);
  if (!ta || !tb) return r;
  r.turn_rad = std::atan2(core::cross(*ta, *tb), ta->dot(*tb));
  const double start = std::atan2(ta->y(), ta->x()) + on.t * r.turn_rad;
  r.tangent = Vec2(std::cos(start), std::sin(start));
  r.valid = true;
  return r;
}

}  // namespace

double track_path(const TrackerParams& params, const core::Pose2& pose, double speed_mps,
                  const Path& path, const PathProjection& from, double curvature_ahead) {
  if (path.segment_count() == 0) return 0.0;

  // errors of the rear axle: lateral (positive left of the path) and heading, against the
  // smooth curve through the path's points rather than its chords. The chords' directions jump
  // at every point by the turn between two points (0.24 rad on a 4 m radius at 1 m spacing):
  // measured against them, the heading error saw-toothed as the car passed each point and the
  // steering command with it, by 0.2-0.4 rad every few ticks in the PacSim hairpins, enough to
  // touch the saturated-steering speed cap tick after tick
  const SmoothTangent st = smooth_tangent(path, from);
  const Vec2 a = path.points[from.segment], b = path.segment_end(from.segment);
  const Vec2 chord = (b - a).norm() > 1e-9 ? Vec2((b - a).normalized()) : pose.heading();
  const Vec2 t = st.valid ? st.tangent : chord;
  // the curve bows outwards of the chord by k L^2 t (1 - t) / 2 (k: signed turn over length)
  const double bow = st.valid ? 0.5 * st.turn_rad * (b - a).norm() * from.t * (1.0 - from.t) : 0.0;
  const double lateral = core::cross(chord, pose.position() - from.point) + bow;
  const double heading = core::normalize_angle(pose.yaw - std::atan2(t.y(), t.x()));

  // second-order error dynamics over distance, the frequency capped in time at speed
  const double v = std::max(1.0, std::abs(speed_mps));
  const double w = std::min(params.frequency_per_m, params.max_frequency_rps / v);
  const double k = curvature_ahead - w * w * lateral - 2.0 * params.damping * w * std::sin(heading);
  return steer_for_curvature(params, k);
}

}  // namespace conesim::control
