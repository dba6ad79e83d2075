#include "control/path.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace conesim::control {

namespace {
// the car's heading is taken this far off the path's at most when it joins, radians
constexpr double kMaxJoinAngleRad = 0.5;
}  // namespace

size_t Path::segment_count() const {
  if (points.size() < 2) return 0;
  return closed ? points.size() : points.size() - 1;
}

std::vector<double> Path::arc_lengths() const {
  std::vector<double> s;
  if (points.empty()) return s;
  s.reserve(points.size() + 1);
  s.push_back(0.0);
  for (size_t i = 0; i < segment_count(); ++i)
    s.push_back(s.back() + (segment_end(i) - points[i]).norm());
  return s;
}

double Path::length() const {
  const std::vector<double> s = arc_lengths();
  return s.empty() ? 0.0 : s.back();
}

PathProjection project_onto(const Path& path, const Vec2& p, size_t first, size_t count) {
  PathProjection best;
  best.distance_m = std::numeric_limits<double>::infinity();
  const size_t segments = path.segment_count();

  // a single point is its own projection
  if (segments == 0) {
    if (!path.points.empty()) {
      best.point = path.points.front();
      best.distance_m = (p - best.point).norm();
    }
    return best;
  }

  // nearest point over the window of segments
  count = std::min(count, segments);
  for (size_t k = 0; k < count; ++k) {
    size_t i = first + k;
    if (path.closed) {
      i %= segments;
    } else if (i >= segments) {
      break;
    }
    const Vec2& a = path.points[i];
    const Vec2 ab = path.segment_end(i) - a;
    const double len2 = ab.squaredNorm();
    const double t = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
    const Vec2 q = a + t * ab;
    const double d = (p - q).norm();
    if (d < best.distance_m) best = {i, t, q, d};
  }
  return best;
}

Path join_from(const Path& path, const Vec2& from, const PathProjection& at, double length_m,
               std::optional<double> heading) {
  Path joined = path;
  const size_t n = path.points.size();
  if (n < 2 || length_m <= 0.0) return joined;
  const Vec2 offset = from - at.point;
  // the car's heading against the path's, as a sideways slope along the path's normal at the
  // projection (none without a heading or on a degenerate segment)
  const Vec2 chord = path.segment_end(at.segment) - path.points[at.segment];
  Vec2 slope = Vec2::Zero();
  if (heading && chord.norm() > 1e-9) {
    const Vec2 t = chord.normalized();
    const double off = std::clamp(core::normalize_angle(*heading - std::atan2(t.y(), t.x())),
                                  -kMaxJoinAngleRad, kMaxJoinAngleRad);
    slope = std::tan(off) * Vec2(-t.y(), t.x());
  }
  // behind the projection the offset (continued along the car's heading) fades in over a few
  // metres as well, so that the car is on the joined path (the segment it is on moves with it)
  // and the path has no step behind it
  constexpr double kBehindM = 8.0;
  double back = (at.point - path.points[at.segment]).norm();
  for (size_t k = 0; k < n && back < kBehindM; ++k) {
    if (!path.closed && k > at.segment) break;
    const size_t j = (at.segment + n - k) % n;
    const double share = 0.5 * (1.0 + std::cos(std::numbers::pi * back / kBehindM));
    joined.points[j] = path.points[j] + share * (offset - back * slope);
    back += (path.points[j] - path.points[(j + n - 1) % n]).norm();
  }
  // from the projection forwards: the offset fades out over length_m along a half cosine, and
  // the slope along the cubic Hermite basis that starts at the slope and ends flat (the joined
  // path leaves the car along its heading and meets the path with the path's own heading)
  double d = (path.segment_end(at.segment) - at.point).norm();
  for (size_t k = 1; k < n && d < length_m; ++k) {
    const size_t i = at.segment + k;
    if (!path.closed && i >= n) break;
    const size_t j = i % n;
    const double u = d / length_m;
    const double share = 0.5 * (1.0 + std::cos(std::numbers::pi * u));
    joined.points[j] = path.points[j] + share * offset + d * (1.0 - u) * (1.0 - u) * slope;
    d += (path.points[(j + 1) % n] - path.points[j]).norm();
  }
  return joined;
}

std::vector<Vec2> resample(const std::vector<Vec2>& points, double spacing_m, bool closed) {
  if (points.size() < 2 || spacing_m <= 0.0) return points;

  // walk the polyline (closed: back to the first point) and drop a point every spacing_m
  std::vector<Vec2> pts = points;
  if (closed) pts.push_back(points.front());
  double total = 0.0;
  for (size_t i = 0; i + 1 < pts.size(); ++i) total += (pts[i + 1] - pts[i]).norm();
  const int steps = std::max(1, static_cast<int>(std::round(total / spacing_m)));
  const double step = closed ? total / steps : spacing_m;
  std::vector<Vec2> out{pts.front()};
  double next = step, walked = 0.0;
  for (size_t i = 0; i + 1 < pts.size(); ++i) {
    const double len = (pts[i + 1] - pts[i]).norm();
    while (len > 0.0 && next <= walked + len + 1e-9 && next < total - 1e-6) {
      out.push_back(pts[i] + (next - walked) / len * (pts[i + 1] - pts[i]));
      next += step;
    }
    walked += len;
  }
  if (!closed && (out.back() - pts.back()).norm() > 1e-6) out.push_back(pts.back());
  return out;
}

std::vector<Vec2> closed_lap(std::vector<Vec2> trace, double reach_m, double lateral_m) {
  if (trace.size() < 3) return trace;
  const Vec2 first = trace.front();
  // the heading over the trace's first metre (its points may be closer than that)
  Vec2 heading = Vec2::Zero();
  for (size_t i = 1; i < trace.size() && heading.norm() < 1.0; ++i) heading = trace[i] - first;
  if (heading.norm() < 1e-9) return trace;
  heading.normalize();
  const Vec2 left(-heading.y(), heading.x());
  while (trace.size() > 3) {
    const Vec2 d = trace.back() - first;
    const double along = d.dot(heading);
    if (along < 0.0 || along > reach_m || std::abs(d.dot(left)) > lateral_m) break;
    trace.pop_back();
  }
  return trace;
}

std::vector<Vec2> smooth(const std::vector<Vec2>& points, int half_window, bool closed) {
  const int n = static_cast<int>(points.size());
  if (n < 3 || half_window <= 0) return points;
  std::vector<Vec2> out(points.size());
  for (int i = 0; i < n; ++i) {
    // closed: a full window around the loop; open: the window shrinks symmetrically at the ends
    int w = half_window;
    if (!closed) w = std::min({w, i, n - 1 - i});
    Vec2 sum = Vec2::Zero();
    for (int k = -w; k <= w; ++k) sum += points[static_cast<size_t>(((i + k) % n + n) % n)];
    out[static_cast<size_t>(i)] = sum / (2 * w + 1);
  }
  return out;
}

double three_point_curvature(const Vec2& a, const Vec2& b, const Vec2& c) {
  const double ab = (b - a).norm(), bc = (c - b).norm(), ca = (a - c).norm();
  const double denom = ab * bc * ca;
  if (denom <= 1e-12) return 0.0;
  return 2.0 * core::cross(b - a, c - a) / denom;
}

std::vector<double> curvatures(const std::vector<Vec2>& points, bool closed, int stride) {
  const int n = static_cast<int>(points.size());
  std::vector<double> k(points.size(), 0.0);
  if (n < 3) return k;
  stride = std::max(1, std::min(stride, (n - 1) / 2));

  // the circle through the neighbours stride away; open ends copy the nearest value
  for (int i = 0; i < n; ++i) {
    int lo = i - stride, hi = i + stride;
    if (closed) {
      lo = (lo % n + n) % n;
      hi = hi % n;
    } else if (lo < 0 || hi >= n) {
      continue;
    }
    k[static_cast<size_t>(i)] =
        three_point_curvature(points[static_cast<size_t>(lo)], points[static_cast<size_t>(i)],
                              points[static_cast<size_t>(hi)]);
  }
  if (!closed) {
    for (int i = 0; i < stride; ++i) {
      k[static_cast<size_t>(i)] = k[static_cast<size_t>(stride)];
      k[static_cast<size_t>(n - 1 - i)] = k[static_cast<size_t>(n - 1 - stride)];
    }
  }
  return k;
}

double curvature_near(const Path& path, const std::vector<double>& s, const std::vector<double>& k,
                      double at, double span_m) {
  if (k.empty()) return 0.0;
  const double lap = path.closed ? s.back() : 0.0;
  double sum = 0.0;
  for (int m = -2; m <= 2; ++m) {
    double q = at + 0.25 * m * span_m;
    q = lap > 0.0 ? std::fmod(std::fmod(q, lap) + lap, lap) : std::clamp(q, 0.0, s.back());
    // the point at or before q
    const auto it = std::upper_bound(s.begin(), s.begin() + static_cast<long>(k.size()), q);
    sum += k[it == s.begin() ? 0 : static_cast<size_t>(it - s.begin()) - 1];
  }
  return sum / 5.0;
}

}  // namespace conesim::control
