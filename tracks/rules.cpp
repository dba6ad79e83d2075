#include "tracks/rules.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <numbers>
#include <optional>
#include <span>
#include <tuple>
#include <utility>

#include "tracks/fsg_layouts.hpp"
#include "tracks/spatial_index.hpp"

namespace conesim::tracks {

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kInf = std::numeric_limits<double>::infinity();

// offenders of one rule closer than this along the centre line are one place (more than the
// largest legal cone spacing, so consecutive offending cones of a lane always merge)
constexpr double kMergeGapM = 6.0;
// half the arc length over which a circle is fitted for the local radius of curvature: on the
// centre line (1 m samples whose ripple at the cone spacing a shorter fit would amplify; a circle
// of 20 m radius between cones 3 m apart reads 19.6 m over +-3 m, 19.8 m over +-4 m) and on a
// boundary (its own cones, 1.5-5 m apart)
constexpr double kCentreLineFitHalfWindowM = 4.0;
constexpr double kBoundaryFitHalfWindowM = 3.0;
// half the chord over which a local heading is measured
constexpr double kHeadingHalfChordM = 1.5;
// skidpad ring search: cones within this of a fitted circle belong to it
constexpr double kRingBandM = 0.3;
// skidpad ring search: fewest cones that make a ring, and the largest span of a seed triple
// (two gaps of the outer ring, 2 x 4.2 m)
constexpr int kRingMinCones = 8;
constexpr double kRingSeedSpanM = 10.0;

// printf-style formatting into a string (std::format is not in GCC 12)
template <typename... Args>
std::string format(const char* pattern, Args... args) {
  char buffer[512];
  std::snprintf(buffer, sizeof buffer, pattern, args...);
  return buffer;
}

// a cone's id as its file gave it, for messages
unsigned long long shown_id(const Track& track, int id) {
  return track.file_id(id);
}

Violation make_violation(std::string rule, std::string message, const Vec2& where,
                         bool warning = false) {
  return {std::move(rule), std::move(message), where, warning};
}

// ---------------------------------------------------------------------------------------------
// polylines

// number of segments of a polyline (closed: the last point joins the first)
size_t segment_count(const std::vector<Vec2>& pts, bool closed) {
  if (pts.size() < 2) return 0;
  return closed ? pts.size() : pts.size() - 1;
}

// arc length at each point (open: s[0] = 0, s.back() = length)
std::vector<double> arc_lengths(const std::vector<Vec2>& pts) {
  std::vector<double> s(pts.size(), 0.0);
  for (size_t i = 1; i < pts.size(); ++i) s[i] = s[i - 1] + (pts[i] - pts[i - 1]).norm();
  return s;
}

// nearest point on a polyline and its distance; a single point is its own polyline
struct Nearest {
  Vec2 point = Vec2::Zero();
  double distance = kInf;
  size_t segment = 0;
  double t = 0.0;  // position within the segment, 0..1
};

Nearest nearest_on(const PolylineIndex& index, const Vec2& p) {
  const PolylineIndex::Nearest n = index.nearest(p);
  if (!std::isfinite(n.distance2)) return {};
  return {n.point, std::sqrt(n.distance2), n.segment, n.t};
}

// even-odd test: is p inside the polygon pts
bool inside_polygon(const Vec2& p, const std::vector<Vec2>& pts) {
  bool inside = false;
  for (size_t i = 0, j = pts.size() - 1; i < pts.size(); j = i++) {
    const Vec2& a = pts[i];
    const Vec2& b = pts[j];
    if ((a.y() > p.y()) != (b.y() > p.y()) &&
        p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x())
      inside = !inside;
  }
  return inside;
}

// the crossing point of two segments known to intersect
Vec2 intersection_point(const Vec2& a1, const Vec2& a2, const Vec2& b1, const Vec2& b2) {
  const Vec2 r = a2 - a1;
  const Vec2 q = b2 - b1;
  const double t = core::cross(b1 - a1, q) / core::cross(r, q);
  return a1 + t * r;
}

// p on the segment from s1 towards s2, its end s2 excluded
bool on_segment_from(const Vec2& p, const Vec2& s1, const Vec2& s2) {
  if (p == s1) return true;
  const Vec2 d = s2 - s1;
  const double along = d.dot(p - s1);
  return core::cross(d, p - s1) == 0.0 && along > 0.0 && along < d.squaredNorm();
}

// where two lane segments cross or touch, if they do: a proper crossing, or the start of one
// lying on the other. Each segment counts with its start cone and without its end cone, so
// lanes that cross exactly at a cone are reported once, by the segments leaving it
std::optional<Vec2> segments_meet(const Vec2& a1, const Vec2& a2, const Vec2& b1, const Vec2& b2) {
  if (core::segments_intersect(a1, a2, b1, b2)) return intersection_point(a1, a2, b1, b2);
  if (on_segment_from(a1, b1, b2)) return a1;
  if (on_segment_from(b1, a1, a2)) return b1;
  return std::nullopt;
}

// ---------------------------------------------------------------------------------------------
// the centre line as the checks see it

// the track's centre line, or one derived from the lanes when the track has none
std::vector<Vec2> centre_line_of(const Track& track) {
  return track.centre_line.empty() ? derive_centre_line(track, 1.0) : track.centre_line;
}

// a centre line with arc lengths; closed lines repeat their first point at the end so that
// the closing segment is part of the walk
struct Line {
  std::vector<Vec2> pts;
  std::vector<double> s;
  bool closed = false;
  // the points' segments indexed for nearest-point queries (made by make_line)
  std::shared_ptr<const PolylineIndex> index;
  double length() const { return s.empty() ? 0.0 : s.back(); }
};

Line make_line(std::vector<Vec2> pts, bool closed) {
  Line line;
  line.closed = closed && pts.size() > 2;
  if (line.closed) pts.push_back(pts.front());
  line.s = arc_lengths(pts);
  line.index = std::make_shared<const PolylineIndex>(pts, false);
  line.pts = std::move(pts);
  return line;
}

// the point of the line at arc length s (wrapped on closed lines, clamped on open ones)
Vec2 point_at(const Line& line, double s) {
  const double total = line.length();
  if (line.closed && total > 0.0) s = s - total * std::floor(s / total);
  s = std::clamp(s, 0.0, total);
  const auto it = std::upper_bound(line.s.begin(), line.s.end(), s);
  if (it == line.s.begin()) return line.pts.front();
  if (it == line.s.end()) return line.pts.back();
  const size_t i = static_cast<size_t>(it - line.s.begin());
  const double seg = line.s[i] - line.s[i - 1];
  const double t = seg > 0.0 ? (s - line.s[i - 1]) / seg : 0.0;
  return line.pts[i - 1] + t * (line.pts[i] - line.pts[i - 1]);
}

// arc length of the point of the line nearest to p
double project_on_line(const Line& line, const Vec2& p) {
  const Nearest n = nearest_on(*line.index, p);
  if (line.pts.size() < 2) return 0.0;
  return line.s[n.segment] + n.t * (line.s[n.segment + 1] - line.s[n.segment]);
}

// least-squares circle (algebraic Kasa fit on centred coordinates) through points: centre and
// radius, exact for points on a circle; nullopt when they are (nearly) collinear
std::optional<std::pair<Vec2, double>> fit_circle(std::span<const Vec2> pts) {
  if (pts.size() < 3) return std::nullopt;
  Vec2 mean = Vec2::Zero();
  for (const Vec2& p : pts) mean += p;
  mean /= static_cast<double>(pts.size());
  double suu = 0, suv = 0, svv = 0, suz = 0, svz = 0, sz = 0;
  for (const Vec2& p : pts) {
    const double u = p.x() - mean.x(), v = p.y() - mean.y(), z = u * u + v * v;
    suu += u * u, suv += u * v, svv += v * v, suz += u * z, svz += v * z, sz += z;
  }
  const double det = suu * svv - suv * suv;
  if (det <= 1e-12 * (suu + svv) * (suu + svv)) return std::nullopt;
  const double d = -(svv * suz - suv * svz) / det;
  const double e = -(suu * svz - suv * suz) / det;
  const double f = -sz / static_cast<double>(pts.size());
  const double r2 = 0.25 * (d * d + e * e) - f;
  if (r2 <= 0.0) return std::nullopt;
  return std::pair{mean + Vec2(-0.5 * d, -0.5 * e), std::sqrt(r2)};
}

// signed curvature (left turn positive) of the circle fitted through points in order, the sign
// taken at point `middle`; 0 when they are collinear. An S-bend fools the algebraic fit into a
// small circle around the points' centroid (it is symmetric); a circle narrower than the
// window's chord cannot be an arc through it, and then the circle through the first, middle and
// last point is used instead.
double fit_curvature(const std::vector<Vec2>& pts, size_t middle) {
  const Vec2& a = pts.front();
  const Vec2& b = pts[middle];
  const Vec2& c = pts.back();
  const double sign = core::cross(b - a, c - a) > 0.0 ? 1.0 : -1.0;
  const auto circle = fit_circle(pts);
  if (circle && 2.0 * circle->second >= (c - a).norm()) return sign / circle->second;
  const double denominator = (b - a).norm() * (c - b).norm() * (c - a).norm();
  return denominator > 0.0 ? 2.0 * core::cross(b - a, c - b) / denominator : 0.0;
}

// signed curvature at every point of a polyline (left turn positive), each from a circle fitted
// to the points within +-half_window_m of arc around it, and at least its two
// neighbours; 0 at the ends of an open polyline. Fitting over metres rather than adjacent
// samples keeps the ripple of a derived centre line and the scatter of surveyed cones small.
std::vector<double> polyline_curvatures(const std::vector<Vec2>& pts, bool closed,
                                        double half_window_m) {
  const size_t n = pts.size();
  std::vector<double> kappa(n, 0.0);
  if (n < 3) return kappa;
  for (size_t i = 0; i < n; ++i) {
    if (!closed && (i == 0 || i + 1 == n)) continue;

    // walk out to either side until the window's arc is covered (closed: at most half way)
    std::vector<Vec2> before, after;
    double arc = 0.0;
    for (size_t k = 1; k <= (closed ? (n - 1) / 2 : i); ++k) {
      arc += (pts[(i + n - k + 1) % n] - pts[(i + n - k) % n]).norm();
      if (k > 1 && arc > half_window_m) break;
      before.push_back(pts[(i + n - k) % n]);
    }
    arc = 0.0;
    for (size_t k = 1; k <= (closed ? (n - 1) / 2 : n - 1 - i); ++k) {
      arc += (pts[(i + k) % n] - pts[(i + k - 1) % n]).norm();
      if (k > 1 && arc > half_window_m) break;
      after.push_back(pts[(i + k) % n]);
    }

    // the window in order: before (reversed), the point, after
    std::vector<Vec2> window(before.rbegin(), before.rend());
    window.push_back(pts[i]);
    window.insert(window.end(), after.begin(), after.end());
    kappa[i] = fit_curvature(window, before.size());
  }
  return kappa;
}

// curvature at every point of the line (closing duplicate excluded)
std::vector<double> curvatures(const Line& line) {
  if (!line.closed) return polyline_curvatures(line.pts, false, kCentreLineFitHalfWindowM);
  return polyline_curvatures({line.pts.begin(), line.pts.end() - 1}, true,
                             kCentreLineFitHalfWindowM);
}

// heading at every point (closing duplicate excluded) from a chord of +-kHeadingHalfChordM,
// unwrapped along the line so that differences are total turning angles
std::vector<double> headings(const Line& line) {
  const size_t n = line.closed ? line.pts.size() - 1 : line.pts.size();
  std::vector<double> theta(n, 0.0);
  for (size_t i = 0; i < n; ++i) {
    const Vec2 d = point_at(line, line.s[i] + kHeadingHalfChordM) -
                   point_at(line, line.s[i] - kHeadingHalfChordM);
    theta[i] = std::atan2(d.y(), d.x());
    if (i > 0) theta[i] = theta[i - 1] + core::normalize_angle(theta[i] - theta[i - 1]);
  }
  return theta;
}

// the line rotated to start at point `first` (closed lines only), so that a stretch that
// crosses the start of the loop is walked in one piece
Line rotated(const Line& line, size_t first) {
  if (!line.closed || first == 0) return line;
  std::vector<Vec2> pts(line.pts.begin(), line.pts.end() - 1);
  std::rotate(pts.begin(), pts.begin() + static_cast<std::ptrdiff_t>(first), pts.end());
  return make_line(std::move(pts), true);
}

// ---------------------------------------------------------------------------------------------
// grouping offenders into places

// one point that breaks a rule: where along the centre line, how badly, and where in the plane
struct Offender {
  double s = 0.0;
  double value = 0.0;
  Vec2 where = Vec2::Zero();
};

// groups offenders closer than kMergeGapM along the line (closed: also across the start)
std::vector<std::vector<Offender>> group_offenders(std::vector<Offender> offenders,
                                                   const Line& line) {
  std::vector<std::vector<Offender>> groups;
  std::sort(offenders.begin(), offenders.end(),
            [](const Offender& a, const Offender& b) { return a.s < b.s; });
  for (const Offender& o : offenders) {
    if (groups.empty() || o.s - groups.back().back().s > kMergeGapM) groups.emplace_back();
    groups.back().push_back(o);
  }
  // closed loops: the last group continues into the first across the start
  if (line.closed && groups.size() > 1 &&
      groups.front().front().s + line.length() - groups.back().back().s <= kMergeGapM) {
    groups.back().insert(groups.back().end(), groups.front().begin(), groups.front().end());
    groups.erase(groups.begin());
  }
  return groups;
}

// the offender with the smallest value of a group
const Offender& worst(const std::vector<Offender>& group) {
  return *std::min_element(group.begin(), group.end(),
                           [](const Offender& a, const Offender& b) { return a.value < b.value; });
}

// extent of a group along the line
double group_extent(const std::vector<Offender>& group, const Line& line) {
  double extent = group.back().s - group.front().s;
  if (extent < 0.0) extent += line.length();
  return extent;
}

// ---------------------------------------------------------------------------------------------
// lanes and widths

// the cones of both lanes with their positions
struct Lanes {
  std::vector<Vec2> left, right;
  bool closed = false;
};

Lanes lanes_of(const Track& track) {
  return {track.lane_points(track.left_lane), track.lane_points(track.right_lane), track.closed};
}

// one cone's width sample: its distance to the other boundary
struct WidthSample {
  double width = kInf;
  Vec2 cone = Vec2::Zero();
  Vec2 other = Vec2::Zero();
};

// width samples from every cone of both lanes
std::vector<WidthSample> width_samples(const Lanes& lanes) {
  std::vector<WidthSample> samples;
  if (lanes.left.empty() || lanes.right.empty()) return samples;
  auto sample_lane = [&](const std::vector<Vec2>& lane, const std::vector<Vec2>& other) {
    const PolylineIndex index(other, lanes.closed);
    for (const Vec2& p : lane) {
      const Nearest n = nearest_on(index, p);
      samples.push_back({n.distance, p, n.point});
    }
  };
  sample_lane(lanes.left, lanes.right);
  sample_lane(lanes.right, lanes.left);
  return samples;
}

// largest gap between consecutive cones of a lane (closing gap included when closed)
double max_gap(const std::vector<Vec2>& lane, bool closed) {
  double gap = 0.0;
  for (size_t i = 0; i < segment_count(lane, closed); ++i)
    gap = std::max(gap, (lane[(i + 1) % lane.size()] - lane[i]).norm());
  return gap;
}

// ---------------------------------------------------------------------------------------------
// rules shared by the events

// each lane needs a few cones before anything else can be measured
bool check_lane_sizes(const Track& track, const RuleLimits& limits, std::vector<Violation>& out) {
  bool ok = true;
  for (const auto& [lane, side] :
       {std::pair{&track.left_lane, "left"}, std::pair{&track.right_lane, "right"}}) {
    if (static_cast<int>(lane->size()) >= limits.min_lane_cones) continue;
    ok = false;
    const Vec2 where = lane->empty() ? track.start.position() : track.cone(lane->front()).position;
    out.push_back(make_violation("lane_cones",
                                 format("%s lane has %d cones, at least %d needed", side,
                                        static_cast<int>(lane->size()), limits.min_lane_cones),
                                 where));
  }
  return ok;
}

// min_width: every place where the boundaries come closer than the limit, one entry per place
void check_width(const Lanes& lanes, const Line& line, const RuleLimits& limits,
                 std::vector<Violation>& out) {
  std::vector<Offender> offenders;
  for (const WidthSample& w : width_samples(lanes))
    if (w.width < limits.min_width_m - limits.survey_tolerance_m)
      offenders.push_back({project_on_line(line, w.cone), w.width, 0.5 * (w.cone + w.other)});
  for (const auto& group : group_offenders(std::move(offenders), line)) {
    const Offender& o = worst(group);
    out.push_back(make_violation(
        "min_width",
        format("track is %.2f m wide, at least %.2f m required (narrow over %.1f m, %d cones)",
               o.value, limits.min_width_m, group_extent(group, line),
               static_cast<int>(group.size())),
        o.where));
  }
}

// max_cone_spacing: each gap between consecutive cones of a lane that is too long
void check_spacing(const Track& track, const RuleLimits& limits, std::vector<Violation>& out) {
  for (const auto& [lane, side] :
       {std::pair{&track.left_lane, "left"}, std::pair{&track.right_lane, "right"}}) {
    const std::vector<Vec2> pts = track.lane_points(*lane);
    for (size_t i = 0; i < segment_count(pts, track.closed); ++i) {
      const size_t j = (i + 1) % pts.size();
      const double gap = (pts[j] - pts[i]).norm();
      if (gap <= limits.max_cone_spacing_m + limits.survey_tolerance_m) continue;
      out.push_back(
          make_violation("max_cone_spacing",
                         format("%s cones %llu and %llu are %.2f m apart, at most %.2f m allowed",
                                side, shown_id(track, (*lane)[i]), shown_id(track, (*lane)[j]), gap,
                                limits.max_cone_spacing_m),
                         0.5 * (pts[i] + pts[j])));
    }
  }
}

// start_on_track: the start pose lies between the boundaries; on an open layout it may also
// stand up to two cone spacings before the first cone pair (fssim's acceleration start is 7 m
// before its first lane cones), within the pair's width
void check_start(const Track& track, const Lanes& lanes, const RuleLimits& limits,
                 std::vector<Violation>& out) {
  if (lanes.left.size() < 2 || lanes.right.size() < 2) return;
  const Vec2 p = track.start.position();
  bool on_track = false;
  if (lanes.closed) {
    // between the boundaries: inside exactly one of the two loops
    on_track = inside_polygon(p, lanes.left) != inside_polygon(p, lanes.right);
  } else {
    // inside the outline of left lane and reversed right lane
    std::vector<Vec2> outline = lanes.left;
    outline.insert(outline.end(), lanes.right.rbegin(), lanes.right.rend());
    on_track = inside_polygon(p, outline);
    // or in the entry, just before the first pair
    const Vec2 across = lanes.left.front() - lanes.right.front();
    const double half = 0.5 * across.norm();
    if (!on_track && half > 0.0) {
      const Vec2 lateral = across / (2.0 * half);
      const Vec2 forward(lateral.y(), -lateral.x());
      const Vec2 rel = p - 0.5 * (lanes.left.front() + lanes.right.front());
      const double along = rel.dot(forward);
      on_track = std::abs(rel.dot(lateral)) <= half &&
                 along >= -2.0 * limits.max_cone_spacing_m - 1e-9 && along <= 1e-9;
    }
  }
  if (!on_track)
    out.push_back(make_violation(
        "start_on_track",
        format("start pose (%.2f, %.2f) is not between the boundaries", p.x(), p.y()), p));
}

// boundary_crossing and boundary_self_crossing: no lane segment crosses another
void check_crossings(const Track& track, const Lanes& lanes, std::vector<Violation>& out) {
  const size_t nl = segment_count(lanes.left, lanes.closed);
  const size_t nr = segment_count(lanes.right, lanes.closed);
  auto ids = [&](const std::vector<int>& lane, size_t i) {
    return std::pair{shown_id(track, lane[i]), shown_id(track, lane[(i + 1) % lane.size()])};
  };

  // left against right: each segment against those of the other lane near it (an index of the
  // segments: linear in the cones rather than quadratic)
  const PolylineIndex left_index(lanes.left, lanes.closed), right_index(lanes.right, lanes.closed);
  const auto box_lo = [](const Vec2& a, const Vec2& b) { return Vec2(a.cwiseMin(b)); };
  const auto box_hi = [](const Vec2& a, const Vec2& b) { return Vec2(a.cwiseMax(b)); };
  for (size_t i = 0; i < nl; ++i) {
    const Vec2& a1 = lanes.left[i];
    const Vec2& a2 = lanes.left[(i + 1) % lanes.left.size()];
    for (size_t j : right_index.segments_near(box_lo(a1, a2), box_hi(a1, a2))) {
      if (j >= nr) continue;
      const Vec2& b1 = lanes.right[j];
      const Vec2& b2 = lanes.right[(j + 1) % lanes.right.size()];
      const std::optional<Vec2> at = segments_meet(a1, a2, b1, b2);
      if (!at) continue;
      const auto [l1, l2] = ids(track.left_lane, i);
      const auto [r1, r2] = ids(track.right_lane, j);
      out.push_back(make_violation(
          "boundary_crossing",
          format("left segment %llu-%llu crosses right segment %llu-%llu", l1, l2, r1, r2), *at));
    }
  }

  // each lane against itself, neighbouring segments excepted
  for (const auto& [lane, pts, side] : {std::tuple{&track.left_lane, &lanes.left, "left"},
                                        std::tuple{&track.right_lane, &lanes.right, "right"}}) {
    const size_t n = segment_count(*pts, lanes.closed);
    const PolylineIndex& index = pts == &lanes.left ? left_index : right_index;
    for (size_t i = 0; i < n; ++i) {
      const Vec2& a1 = (*pts)[i];
      const Vec2& a2 = (*pts)[(i + 1) % pts->size()];
      for (size_t j : index.segments_near(box_lo(a1, a2), box_hi(a1, a2))) {
        if (j < i + 2 || j >= n) continue;
        if (lanes.closed && i == 0 && j == n - 1) continue;
        const Vec2& b1 = (*pts)[j];
        const Vec2& b2 = (*pts)[(j + 1) % pts->size()];
        const std::optional<Vec2> at = segments_meet(a1, a2, b1, b2);
        if (!at) continue;
        const auto [a_from, a_to] = ids(*lane, i);
        const auto [b_from, b_to] = ids(*lane, j);
        out.push_back(make_violation("boundary_self_crossing",
                                     format("%s segment %llu-%llu crosses %s segment %llu-%llu",
                                            side, a_from, a_to, side, b_from, b_to),
                                     *at));
      }
    }
  }
}

// max_straight: every stretch longer than the limit whose heading stays within the tolerance
void check_straights(const Line& line_in, const std::vector<double>& kappa,
                     const RuleLimits& limits, std::vector<Violation>& out) {
  // closed loops are walked from their most curved point, which is on no straight
  size_t first = 0;
  if (line_in.closed && !kappa.empty())
    first = static_cast<size_t>(
        std::max_element(kappa.begin(), kappa.end(),
                         [](double a, double b) { return std::abs(a) < std::abs(b); }) -
        kappa.begin());
  const Line line = rotated(line_in, first);
  const std::vector<double> theta = headings(line);
  const double tolerance = limits.straight_heading_tolerance_deg * kPi / 180.0;

  // grow each stretch as far as the heading stays within the tolerance; report the maximal
  // ones that are too long and continue after them
  const size_t n = theta.size();
  size_t i = 0;
  while (i < n) {
    double lo = theta[i], hi = theta[i];
    size_t j = i;
    while (j + 1 < n && std::max(hi, theta[j + 1]) - std::min(lo, theta[j + 1]) <= tolerance) {
      ++j;
      lo = std::min(lo, theta[j]);
      hi = std::max(hi, theta[j]);
    }
    const double length = line.s[j] - line.s[i];
    if (length > limits.max_straight_m + limits.survey_tolerance_m) {
      out.push_back(make_violation(
          "max_straight",
          format("straight of %.1f m, at most %.1f m allowed", length, limits.max_straight_m),
          point_at(line, 0.5 * (line.s[i] + line.s[j]))));
      i = j + 1;
    } else {
      ++i;
    }
  }
}

// max_turn_diameter: stretches turning one way with a radius above the limit everywhere whose
// total turn reaches wide_turn_min_sweep_deg
void check_wide_turns(const Line& line_in, const std::vector<double>& kappa_in,
                      const RuleLimits& limits, std::vector<Violation>& out) {
  const double kappa_limit = 2.0 / limits.max_turn_diameter_m;
  auto in_wide_turn = [&](double k, double sign) {
    return k * sign > 0.0 && std::abs(k) < kappa_limit;
  };

  // closed loops start at a point that belongs to no wide turn (a loop that is one wide turn
  // all round is walked from its start)
  size_t first = 0;
  if (line_in.closed) {
    for (size_t i = 0; i < kappa_in.size(); ++i) {
      const size_t prev = (i + kappa_in.size() - 1) % kappa_in.size();
      const double sign = kappa_in[i] >= 0.0 ? 1.0 : -1.0;
      if (!in_wide_turn(kappa_in[i], sign) || !in_wide_turn(kappa_in[prev], sign)) {
        first = i;
        break;
      }
    }
  }
  const Line line = rotated(line_in, first);
  std::vector<double> kappa(kappa_in.size());
  for (size_t i = 0; i < kappa.size(); ++i) kappa[i] = kappa_in[(i + first) % kappa.size()];
  const std::vector<double> theta = headings(line);
  const double min_sweep = limits.wide_turn_min_sweep_deg * kPi / 180.0;

  // runs of points that all turn the same way with a large radius
  const size_t n = kappa.size();
  size_t i = 0;
  while (i < n) {
    const double sign = kappa[i] >= 0.0 ? 1.0 : -1.0;
    if (!in_wide_turn(kappa[i], sign)) {
      ++i;
      continue;
    }
    size_t j = i;
    while (j + 1 < n && in_wide_turn(kappa[j + 1], sign)) ++j;
    const double sweep = std::abs(theta[j] - theta[i]);
    const double arc = line.s[j] - line.s[i];
    if (sweep >= min_sweep) {
      out.push_back(make_violation(
          "max_turn_diameter",
          format("turn of %.0f deg with mean diameter %.1f m over %.1f m, constant turns at "
                 "most %.1f m across",
                 sweep * 180.0 / kPi, 2.0 * arc / sweep, arc, limits.max_turn_diameter_m),
          point_at(line, 0.5 * (line.s[i] + line.s[j]))));
    }
    i = j + 1;
  }
}

// min_hairpin_diameter: wherever a boundary turns away from the track (the left lane turning
// right, the right lane turning left: the outside of a turn) with a radius below half the limit,
// fitted to the boundary's own cones, and the centre line turns the same way with a radius below
// it too (so that one misplaced cone on a straight is no hairpin); one entry per turn
void check_hairpins(const Line& line, const std::vector<double>& kappa_centre, const Lanes& lanes,
                    const RuleLimits& limits, std::vector<Violation>& out) {
  const double min_outer_r = 0.5 * limits.min_hairpin_outer_diameter_m;
  std::vector<Offender> offenders;
  for (const auto& [lane, outside_sign] :
       {std::pair{&lanes.left, -1.0}, std::pair{&lanes.right, 1.0}}) {
    const std::vector<double> kappa =
        polyline_curvatures(*lane, lanes.closed, kBoundaryFitHalfWindowM);
    for (size_t i = 0; i < kappa.size(); ++i) {
      // the boundary bends away from the track, tightly
      if (kappa[i] * outside_sign <= 0.0) continue;
      const double radius = 1.0 / std::abs(kappa[i]);
      if (radius >= min_outer_r - 0.5 * limits.survey_tolerance_m) continue;

      // and the centre line turns the same way, tightly, next to it
      const Nearest n = nearest_on(*line.index, (*lane)[i]);
      const size_t k = (n.t < 0.5 ? n.segment : n.segment + 1) % kappa_centre.size();
      if (kappa_centre[k] * outside_sign * min_outer_r <= 1.0) continue;
      offenders.push_back({project_on_line(line, (*lane)[i]), radius, (*lane)[i]});
    }
  }
  for (const auto& group : group_offenders(std::move(offenders), line)) {
    const Offender& o = worst(group);
    out.push_back(make_violation(
        "min_hairpin_diameter",
        format("outer boundary of the turn is %.2f m across, at least %.2f m required",
               2.0 * o.value, limits.min_hairpin_outer_diameter_m),
        o.where));
  }
}

// start_finish_cones (warning): big orange cones near the start of a closed circuit
void check_start_finish_cones(const Track& track, const RuleLimits& limits,
                              std::vector<Violation>& out) {
  double nearest = kInf;
  for (const Cone& c : track.cones)
    if (c.cls == ConeClass::kOrangeBig)
      nearest = std::min(nearest, (c.position - track.start.position()).norm());
  if (nearest <= limits.start_finish_search_m) return;
  out.push_back(make_violation(
      "start_finish_cones",
      std::isinf(nearest)
          ? std::string("no big orange cones mark the start/finish line")
          : format("nearest big orange cone is %.1f m from the start, expected within %.1f m",
                   nearest, limits.start_finish_search_m),
      track.start.position(), true));
}

// ---------------------------------------------------------------------------------------------
// skidpad rings

// a circle of cones
struct Ring {
  Vec2 centre = Vec2::Zero();
  double radius = 0.0;
  std::vector<size_t> members;
};

// indices of the points within kRingBandM of a circle
std::vector<size_t> ring_members(const std::vector<Vec2>& pts, const PointIndex& index,
                                 const std::vector<bool>& used, const Vec2& centre, double radius) {
  std::vector<size_t> members;
  index.for_each_within(centre, radius + kRingBandM + 1e-9, [&](size_t i) {
    if (!used[i] && std::abs((pts[i] - centre).norm() - radius) <= kRingBandM) members.push_back(i);
  });
  std::sort(members.begin(), members.end());
  return members;
}

// how many there are (ring_members().size(), without building the list)
size_t count_ring_members(const std::vector<Vec2>& pts, const PointIndex& index,
                          const std::vector<bool>& used, const Vec2& centre, double radius) {
  size_t n = 0;
  index.for_each_within(centre, radius + kRingBandM + 1e-9, [&](size_t i) {
    if (!used[i] && std::abs((pts[i] - centre).norm() - radius) <= kRingBandM) ++n;
  });
  return n;
}

// rings of at least kRingMinCones cones, best first: seed circles through each triple of
// nearby cones, keep the one with most cones, refit it to them, remove them, repeat
std::vector<Ring> find_rings(const std::vector<Vec2>& pts, size_t max_rings) {
  std::vector<Ring> rings;
  std::vector<bool> used(pts.size(), false);
  // the seeds' neighbours and the members from an index (the points within a span of a seed)
  const PointIndex index(pts);
  std::vector<std::vector<size_t>> near_of(pts.size());
  for (size_t a = 0; a < pts.size(); ++a)
    near_of[a] = index.within(pts[a], kRingSeedSpanM * (1.0 + 1e-9));
  while (rings.size() < max_rings) {
    Ring best;
    for (size_t a = 0; a < pts.size(); ++a) {
      if (used[a]) continue;
      const std::vector<size_t>& near = near_of[a];
      for (size_t b : near) {
        if (b <= a || used[b] || (pts[b] - pts[a]).norm() > kRingSeedSpanM) continue;
        for (size_t c : near) {
          if (c <= b) continue;
          if (used[c] || (pts[c] - pts[a]).norm() > kRingSeedSpanM ||
              (pts[c] - pts[b]).norm() > kRingSeedSpanM)
            continue;
          const std::array<Vec2, 3> seed = {pts[a], pts[b], pts[c]};
          const auto circle = fit_circle(seed);
          if (!circle || circle->second > 50.0) continue;
          // counted first: most seeds lose, and listing their members cost an allocation each
          if (count_ring_members(pts, index, used, circle->first, circle->second) <=
              best.members.size())
            continue;
          best = {circle->first, circle->second,
                  ring_members(pts, index, used, circle->first, circle->second)};
        }
      }
    }
    if (static_cast<int>(best.members.size()) < kRingMinCones) break;

    // refit to the members and take the members of the refined circle
    std::vector<Vec2> member_pts;
    for (size_t i : best.members) member_pts.push_back(pts[i]);
    if (const auto refined = fit_circle(member_pts)) {
      std::vector<size_t> members = ring_members(pts, index, used, refined->first, refined->second);
      if (members.size() >= best.members.size()) {
        member_pts.clear();
        for (size_t i : members) member_pts.push_back(pts[i]);
        const auto final_fit = fit_circle(member_pts);
        best = {final_fit ? final_fit->first : refined->first,
                final_fit ? final_fit->second : refined->second, std::move(members)};
      }
    }
    for (size_t i : best.members) used[i] = true;
    rings.push_back(std::move(best));
  }
  return rings;
}

// the positions of the boundary-coloured cones (blue, yellow and unknown)
std::vector<Vec2> ring_candidates(const Track& track) {
  std::vector<Vec2> pts;
  for (const Cone& c : track.cones)
    if (c.cls == ConeClass::kBlue || c.cls == ConeClass::kYellow || c.cls == ConeClass::kUnknown)
      pts.push_back(c.position);
  return pts;
}

// the two skidpad circles: up to four rings grouped by centre
struct SkidpadCircle {
  Vec2 centre = Vec2::Zero();
  std::vector<Ring> rings;  // smallest radius first
};

std::vector<SkidpadCircle> skidpad_circles(const Track& track) {
  std::vector<SkidpadCircle> circles;
  for (Ring& ring : find_rings(ring_candidates(track), 4)) {
    auto same = std::find_if(circles.begin(), circles.end(), [&](const SkidpadCircle& c) {
      return (c.centre - ring.centre).norm() < 1.5;
    });
    if (same == circles.end()) {
      circles.push_back({ring.centre, {}});
      same = circles.end() - 1;
    }
    same->rings.push_back(std::move(ring));
  }
  for (SkidpadCircle& c : circles) {
    std::sort(c.rings.begin(), c.rings.end(),
              [](const Ring& a, const Ring& b) { return a.radius < b.radius; });
    c.centre = c.rings.front().centre;
  }
  return circles;
}

// ---------------------------------------------------------------------------------------------
// the events

void check_circuit(const Track& track, const RuleLimits& limits, std::vector<Violation>& out) {
  if (!check_lane_sizes(track, limits, out)) return;
  const Lanes lanes = lanes_of(track);
  const Line line = make_line(centre_line_of(track), track.closed);

  // lap length along the centre line
  const double length = line.length();
  if (length < limits.min_lap_m - limits.survey_tolerance_m ||
      length > limits.max_lap_m + limits.survey_tolerance_m)
    out.push_back(make_violation(
        "lap_length",
        format("%s is %.1f m long, %.0f-%.0f m allowed", track.closed ? "lap" : "course", length,
               limits.min_lap_m, limits.max_lap_m),
        track.start.position()));

  // boundaries: width, spacing, crossings
  check_width(lanes, line, limits, out);
  check_spacing(track, limits, out);
  check_crossings(track, lanes, out);

  // shape: straights and wide turns of the centre line, hairpins of the outer boundary
  if (line.pts.size() >= 3) {
    const std::vector<double> kappa = curvatures(line);
    check_straights(line, kappa, limits, out);
    check_wide_turns(line, kappa, limits, out);
    check_hairpins(line, kappa, lanes, limits, out);
  }

  // start pose and its marking
  check_start(track, lanes, limits, out);
  if (track.closed) check_start_finish_cones(track, limits, out);
}

void check_skidpad(const Track& track, const RuleLimits& limits, std::vector<Violation>& out) {
  const std::vector<SkidpadCircle> circles = skidpad_circles(track);

  // two circles, each with an inner and an outer ring
  size_t ring_count = 0;
  for (const SkidpadCircle& c : circles) ring_count += c.rings.size();
  if (circles.size() != 2 || ring_count != 4) {
    out.push_back(make_violation(
        "skidpad_circles",
        format("found %d circle centres with %d rings of cones, expected 2 centres with an "
               "inner and an outer ring each",
               static_cast<int>(circles.size()), static_cast<int>(ring_count)),
        track.start.position()));
  }

  // centre distance
  if (circles.size() >= 2) {
    const double distance = (circles[0].centre - circles[1].centre).norm();
    if (std::abs(distance - kSkidpadCentreDistanceM) > limits.skidpad_centre_distance_tolerance_m)
      out.push_back(make_violation(
          "skidpad_centre_distance",
          format("circle centres are %.2f m apart, %.2f +- %.2f m required", distance,
                 kSkidpadCentreDistanceM, limits.skidpad_centre_distance_tolerance_m),
          0.5 * (circles[0].centre + circles[1].centre)));
  }

  // ring radii, cones standing kSkidpadConeOffsetM outside the driving area
  for (const SkidpadCircle& c : circles) {
    if (c.rings.size() != 2) continue;
    for (const auto& [ring, expected, rule] :
         {std::tuple{&c.rings[0], kSkidpadInnerConeRadiusM, "skidpad_inner_radius"},
          std::tuple{&c.rings[1], kSkidpadOuterConeRadiusM, "skidpad_outer_radius"}}) {
      if (std::abs(ring->radius - expected) <= limits.skidpad_radius_tolerance_m) continue;
      out.push_back(
          make_violation(rule,
                         format("cone ring radius %.3f m, %.3f +- %.2f m required", ring->radius,
                                expected, limits.skidpad_radius_tolerance_m),
                         ring->centre));
    }
  }

  // a timing gate on the line between the circles, near where they touch
  if (circles.size() >= 2) {
    const Vec2 middle = 0.5 * (circles[0].centre + circles[1].centre);
    const bool gate = std::any_of(
        track.timing_gates.begin(), track.timing_gates.end(),
        [&](const Gate& g) { return (0.5 * (g.left + g.right) - middle).norm() < 1.0; });
    if (!gate)
      out.push_back(make_violation(
          "timing_gate", "no timing gate at the timing line between the circles", middle));
  } else if (track.timing_gates.empty()) {
    out.push_back(make_violation("timing_gate", "no timing gate", track.start.position()));
  }
}

void check_acceleration(const Track& track, const RuleLimits& limits, std::vector<Violation>& out) {
  if (!check_lane_sizes(track, limits, out)) return;
  const Lanes lanes = lanes_of(track);
  const Line line = make_line(centre_line_of(track), false);

  // start and finish gate 75 m apart
  if (track.timing_gates.size() < 2) {
    out.push_back(make_violation("timing_gates",
                                 format("%d timing gates, a start and a finish gate required",
                                        static_cast<int>(track.timing_gates.size())),
                                 track.start.position()));
  } else {
    const Gate& start_gate = track.timing_gates.front();
    const Gate& finish_gate = track.timing_gates.back();
    const Vec2 a = 0.5 * (start_gate.left + start_gate.right);
    const Vec2 b = 0.5 * (finish_gate.left + finish_gate.right);
    const double length = (b - a).norm();
    if (std::abs(length - kAccelerationLengthM) > limits.acceleration_length_tolerance_m)
      out.push_back(make_violation(
          "acceleration_length",
          format("start and finish gates are %.2f m apart, %.1f +- %.1f m required", length,
                 kAccelerationLengthM, limits.acceleration_length_tolerance_m),
          0.5 * (a + b)));

    // straight between the gates
    const Vec2 dir = length > 0.0 ? Vec2((b - a) / length) : Vec2(1.0, 0.0);
    double deviation = 0.0;
    Vec2 worst_point = a;
    for (const Vec2& p : line.pts) {
      const double along = (p - a).dot(dir);
      if (along < 0.0 || along > length) continue;
      const double off = std::abs(core::cross(dir, p - a));
      if (off > deviation) deviation = off, worst_point = p;
    }
    if (deviation > limits.acceleration_max_deviation_m)
      out.push_back(make_violation(
          "acceleration_straight",
          format("centre line leaves the gate-to-gate line by %.2f m, at most %.2f m allowed",
                 deviation, limits.acceleration_max_deviation_m),
          worst_point));

    // braking zone: orange cones beyond the finish
    int braking_cones = 0;
    for (const Cone& c : track.cones)
      if (c.cls == ConeClass::kOrangeSmall && (c.position - b).dot(dir) > 0.0) ++braking_cones;
    if (braking_cones < 2)
      out.push_back(make_violation(
          "braking_zone",
          format("%d small orange cones beyond the finish, a marked braking zone required",
                 braking_cones),
          b + 5.0 * dir));
  }

  // width and start pose
  check_width(lanes, line, limits, out);
  check_start(track, lanes, limits, out);
}

}  // namespace

std::string Violation::to_string() const {
  return format("%s at (%.2f, %.2f): %s%s", rule.c_str(), where.x(), where.y(), message.c_str(),
                warning ? " (warning)" : "");
}

bool RuleLimits::is_valid(std::string* error) const {
  auto fail = [error](const char* why) {
    if (error) *error = why;
    return false;
  };
  if (!(min_lap_m > 0.0 && max_lap_m >= min_lap_m))
    return fail("lap limits must be 0 < min <= max");
  if (!(min_width_m > 0.0)) return fail("min_width_m must be positive");
  if (!(max_straight_m > 0.0)) return fail("max_straight_m must be positive");
  if (!(max_turn_diameter_m > 0.0)) return fail("max_turn_diameter_m must be positive");
  if (!(min_hairpin_outer_diameter_m > 0.0))
    return fail("min_hairpin_outer_diameter_m must be positive");
  if (!(max_cone_spacing_m > 0.0)) return fail("max_cone_spacing_m must be positive");
  if (!(slalom_max_spacing_m >= slalom_min_spacing_m))
    return fail("slalom spacing limits must be min <= max");
  if (!(survey_tolerance_m >= 0.0)) return fail("survey_tolerance_m must not be negative");
  if (!(straight_heading_tolerance_deg > 0.0))
    return fail("straight_heading_tolerance_deg must be positive");
  if (!(wide_turn_min_sweep_deg > 0.0)) return fail("wide_turn_min_sweep_deg must be positive");
  if (min_lane_cones < 2) return fail("min_lane_cones must be at least 2");
  return true;
}

std::vector<SkidpadCircleFit> fit_skidpad_circles(const Track& track) {
  std::vector<SkidpadCircleFit> fits;
  for (const SkidpadCircle& c : skidpad_circles(track)) {
    SkidpadCircleFit fit;
    fit.centre = c.centre;
    fit.inner_radius_m = c.rings.front().radius;
    if (c.rings.size() > 1) fit.outer_radius_m = c.rings.back().radius;
    fit.inner_cones = static_cast<int>(c.rings.front().members.size());
    if (c.rings.size() > 1) fit.outer_cones = static_cast<int>(c.rings.back().members.size());
    fits.push_back(fit);
  }
  return fits;
}

TrackStats compute_stats(const Track& track) {
  TrackStats stats;
  const Lanes lanes = lanes_of(track);
  const Line line = make_line(centre_line_of(track), track.closed);

  // length of the centre line, closing segment included
  stats.length_m = line.length();

  // narrowest place over the cones of both lanes
  const std::vector<WidthSample> widths = width_samples(lanes);
  if (!widths.empty())
    stats.min_width_m = std::min_element(widths.begin(), widths.end(),
                                         [](const WidthSample& a, const WidthSample& b) {
                                           return a.width < b.width;
                                         })
                            ->width;

  // largest gap in either lane
  stats.max_spacing_m =
      std::max(max_gap(lanes.left, track.closed), max_gap(lanes.right, track.closed));

  // tightest radius from circles fitted over +-4 m of centre line
  double max_kappa = 0.0;
  if (line.pts.size() >= 3)
    for (double k : curvatures(line)) max_kappa = std::max(max_kappa, std::abs(k));
  stats.min_radius_m = max_kappa > 0.0 ? 1.0 / max_kappa : kInf;
  return stats;
}

EventType infer_event(const Track& track) {
  // the layout's own event, then closed circuits
  if (track.event) return *track.event;
  if (track.closed) return EventType::kTrackdrive;

  // skidpad: three or four rings of cones around two centres about 18 m apart
  const std::vector<Vec2> candidates = ring_candidates(track);
  if (candidates.size() >= 2 * kRingMinCones) {
    const std::vector<SkidpadCircle> circles = skidpad_circles(track);
    if (circles.size() == 2 && circles[0].rings.size() + circles[1].rings.size() >= 3) {
      const double d = (circles[0].centre - circles[1].centre).norm();
      if (d > 14.0 && d < 23.0) return EventType::kSkidpad;
    }
  }

  // acceleration: the boundary cones lie along a line, 60-100 m between the gates or, without
  // gates, from the first to the last cone
  if (candidates.size() >= 4) {
    Vec2 mean = Vec2::Zero();
    for (const Vec2& p : candidates) mean += p;
    mean /= static_cast<double>(candidates.size());
    Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
    for (const Vec2& p : candidates) cov += (p - mean) * (p - mean).transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
    const Vec2 axis = eig.eigenvectors().col(1);
    double lo = kInf, hi = -kInf, spread = 0.0;
    for (const Vec2& p : candidates) {
      lo = std::min(lo, (p - mean).dot(axis));
      hi = std::max(hi, (p - mean).dot(axis));
      spread = std::max(spread, std::abs(core::cross(axis, p - mean)));
    }
    double length = hi - lo;
    if (track.timing_gates.size() >= 2) {
      const Gate& a = track.timing_gates.front();
      const Gate& b = track.timing_gates.back();
      length = (0.5 * (b.left + b.right - a.left - a.right)).norm();
    }
    if (spread < 3.0 && length >= 60.0 && length <= 100.0) return EventType::kAcceleration;
  }
  return EventType::kAutocross;
}

std::vector<Violation> check_rules(const Track& track, EventType event, const RuleLimits& limits) {
  std::vector<Violation> out;
  switch (event) {
    case EventType::kSkidpad:
      check_skidpad(track, limits, out);
      break;
    case EventType::kAcceleration:
      check_acceleration(track, limits, out);
      break;
    case EventType::kAutocross:
    case EventType::kTrackdrive:
      check_circuit(track, limits, out);
      break;
  }
  return out;
}

bool is_compliant(const std::vector<Violation>& violations) {
  return std::all_of(violations.begin(), violations.end(),
                     [](const Violation& v) { return v.warning; });
}

}  // namespace conesim::tracks
