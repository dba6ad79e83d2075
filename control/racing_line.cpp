#include "control/racing_line.hpp"

#include <Eigen/Sparse>
#include <algorithm>
#include <cmath>
#include <limits>

namespace conesim::control {

namespace {

using core::MapCone;

// a small weight on the offset itself, so that the least-curvature problem has one solution on
// straights (any parallel shift is as straight)
constexpr double kOffsetWeight = 1e-4;
// weight that pins an offset at its bound in the active-set solve
constexpr double kPinWeight = 1e8;
// where the room runs out (the lane narrower than the car and its margins, or the footprint check
// narrowed the bounds until they crossed) an offset is drawn to the middle of the crossed bounds
// by this weight only (per m^2, against the squared second differences), so that the least
// curvature smooths a run of such points. Pinned hard, the middles of neighbouring points, which
// depend on how far each narrowing went, zig-zagged: kinks of 1.3 /m (four times the steering's
// reach) in the line on EUFS small_track_2 planned from GraphSLAM's map. Measured on 40 generated
// hard-profile trackdrives driven from GraphSLAM (seed 5000 on): 16 hit a cone pinned hard, 9, 8
// and 9 at weights 1, 0.3 and 0.1; ground truth clean on all of them either way
constexpr double kSoftPinWeight = 0.3;
// an open corridor starts where the car is: its first this many points hold offset 0 exactly
constexpr size_t kOpenStartPoints = 2;

// whether point i is one of an open corridor's held start points
bool held_start(const Corridor& c, size_t i) {
  return !c.closed && i < kOpenStartPoints;
}
// the active-set loop gives up after this many solves (it keeps the last feasible line)
constexpr int kMaxActiveSetRounds = 60;
// the footprint check narrows the corridor and plans again at most this many times (each
// narrowing is the shortfall only, and the line follows a narrowed bound part of the way: past a
// cone standing in the lane, tests/data/replay/cone_in_the_lane.csv, 10 rounds left the widest
// line 0.05 m into it)
constexpr int kMaxFootprintRounds = 30;
// with a curvature target: the line is planned again at most this many times with its
// curvature weighed more where it was tighter than the target, each time by the squared ratio
// over the target times this gain
constexpr int kMaxReweighRounds = 8;
constexpr double kReweighGain = 2.0;
constexpr double kMaxWeight = 16.0;
// a turn whose peak stays above the target by more than this factor after the rounds goes back
// to its least-curvature shape
constexpr double kTargetSlack = 1.05;
// a turn where the corridor narrowed to less room than this for the line (beside the car and its
// margins) somewhere is not reweighed, metres
constexpr double kMinRoomM = 0.3;
// a narrowing is spread over this many points either side of where the footprint came too
// close, tapered linearly. Where several points of a stretch come too close to the same cone,
// each point's narrowing is the largest any of them asks there, not their sum: summed, the
// overlapping tapers cut the room by several times the shortfall (FSE24: a line 0.35 s slower
// over the lap than one without the footprint check, 0.03 s with the largest)
constexpr int kNarrowHalfWindow = 6;
// the margin changes between the tight-turn margin and the margin over this length, metres
constexpr double kMarginRampM = 10.0;
// a boundary cone this close to the reference line bounds the line's offset on its side, metres
constexpr double kSideReachM = 4.0;
// cones further than this from the rear axle cannot touch the footprint, metres
constexpr double kFootprintReachM = 4.0;

// distance from p to a polyline (closed: with the closing segment); infinity when empty
double distance_to_polyline(const Vec2& p, const std::vector<Vec2>& line, bool closed) {
  if (line.empty()) return std::numeric_limits<double>::infinity();
  if (line.size() == 1) return (p - line.front()).norm();
  double best = std::numeric_limits<double>::infinity();
  const size_t n = line.size();
  for (size_t i = 0; i + 1 < n + (closed ? 1 : 0); ++i)
    best = std::min(best, core::distance_to_segment(p, line[i], line[(i + 1) % n]));
  return best;
}

// distance from p to the rectangle [x0, x1] x [-hw, hw]
double distance_to_box(const Vec2& p, double x0, double x1, double hw) {
  const double dx = std::max({x0 - p.x(), 0.0, p.x() - x1});
  const double dy = std::max(std::abs(p.y()) - hw, 0.0);
  return std::hypot(dx, dy);
}

// index of a neighbour `k` steps from i (wrapping when closed, clamped when open)
size_t neighbour(size_t i, int k, size_t n, bool closed) {
  const long j = static_cast<long>(i) + k;
  if (closed)
    return static_cast<size_t>(((j % static_cast<long>(n)) + static_cast<long>(n)) %
                               static_cast<long>(n));
  return static_cast<size_t>(std::clamp(j, 0L, static_cast<long>(n) - 1));
}

// the offsets of least squared second difference within [lo, hi], each point's squared second
// difference times its weight (active-set solve of the box-constrained least squares problem;
// pinned offsets are held by a stiff penalty)
//
// `active` (n entries or empty) starts the active set: the footprint check's rounds and the
// reweighing change the bounds and weights a little, and the set of the solve before needs a
// round or two where a cold start takes dozens. It holds the set reached on return.
std::vector<double> least_curvature_offsets(const Corridor& c, const std::vector<double>& lo,
                                            const std::vector<double>& hi,
                                            const std::vector<double>& weight,
                                            std::vector<int>& active) {
  const size_t n = c.centre.size();
  // the second differences as A alpha + b: two rows (x, y) per interior point
  std::vector<Eigen::Triplet<double>> triplets;
  std::vector<double> b;
  size_t row = 0;
  const size_t first = c.closed ? 0 : 1, last = c.closed ? n : n - 1;
  for (size_t i = first; i < last; ++i) {
    const size_t im = neighbour(i, -1, n, c.closed), ip = neighbour(i, 1, n, c.closed);
    const Vec2 d0 = c.centre[im] - 2.0 * c.centre[i] + c.centre[ip];
    const double w = std::sqrt(weight[i]);
    for (int axis = 0; axis < 2; ++axis) {
      triplets.emplace_back(row, im, w * c.normal[im][axis]);
      triplets.emplace_back(row, i, -2.0 * w * c.normal[i][axis]);
      triplets.emplace_back(row, ip, w * c.normal[ip][axis]);
      b.push_back(w * d0[axis]);
      ++row;
    }
  }
  Eigen::SparseMatrix<double> a(static_cast<long>(row), static_cast<long>(n));
  a.setFromTriplets(triplets.begin(), triplets.end());
  const Eigen::Map<const Eigen::VectorXd> bv(b.data(), static_cast<long>(b.size()));
  Eigen::SparseMatrix<double> h = a.transpose() * a;
  for (size_t i = 0; i < n; ++i)
    h.coeffRef(static_cast<long>(i), static_cast<long>(i)) += kOffsetWeight;
  const Eigen::VectorXd g = a.transpose() * bv;

  // active set: -1 pinned at lo, +1 at hi, 0 free; offsets with no room are drawn mid-way (2)
  active.resize(n, 0);
  std::vector<double> pin(n, 0.0);
  for (size_t i = 0; i < n; ++i) {
    if (lo[i] >= hi[i])
      active[i] = 2, pin[i] = 0.5 * (lo[i] + hi[i]);
    else if (active[i] == 2)
      active[i] = 0;
  }
  Eigen::VectorXd x = Eigen::VectorXd::Zero(static_cast<long>(n));
  // the pins change only the diagonal: one ordering serves every solve
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver;
  solver.analyzePattern(h);
  for (int round = 0; round < kMaxActiveSetRounds; ++round) {
    // solve with the active offsets pinned
    Eigen::SparseMatrix<double> hp = h;
    Eigen::VectorXd rhs = -g;
    for (size_t i = 0; i < n; ++i) {
      if (active[i] == 0) continue;
      const double target = active[i] == -1 ? lo[i] : active[i] == 1 ? hi[i] : pin[i];
      // an open corridor's start (where the car is) stays pinned hard
      const bool soft = active[i] == 2 && !held_start(c, i);
      const double w = soft ? kSoftPinWeight : kPinWeight;
      hp.coeffRef(static_cast<long>(i), static_cast<long>(i)) += w;
      rhs[static_cast<long>(i)] += w * target;
    }
    solver.factorize(hp);
    if (solver.info() != Eigen::Success) break;
    x = solver.solve(rhs);

    // free offsets past a bound join the active set
    bool changed = false;
    for (size_t i = 0; i < n; ++i) {
      if (active[i] != 0) continue;
      if (x[static_cast<long>(i)] < lo[i] - 1e-6) active[i] = -1, changed = true;
      if (x[static_cast<long>(i)] > hi[i] + 1e-6) active[i] = 1, changed = true;
    }
    if (changed) continue;

    // pinned offsets whose gradient points into the corridor are released
    const Eigen::VectorXd grad = h * x + g;
    for (size_t i = 0; i < n; ++i) {
      if ((active[i] == -1 && grad[static_cast<long>(i)] < -1e-9) ||
          (active[i] == 1 && grad[static_cast<long>(i)] > 1e-9))
        active[i] = 0, changed = true;
    }
    if (!changed) break;
  }

  // within the bounds whatever the loop reached (where there is no room, where the least
  // curvature drew it)
  std::vector<double> offsets(n);
  for (size_t i = 0; i < n; ++i) {
    const double v = x[static_cast<long>(i)];
    offsets[i] = lo[i] >= hi[i] ? v : std::clamp(v, lo[i], hi[i]);
  }
  return offsets;
}

// the runs of set entries of a mask as (first index, length); on a closed line a run may go
// round the end (then it starts after the last unset entry)
std::vector<std::pair<size_t, size_t>> runs_of(const std::vector<char>& mask, bool closed) {
  const size_t n = mask.size();
  size_t start = 0;
  if (closed)
    while (start < n && mask[start]) ++start;
  if (start == n) start = 0;
  std::vector<std::pair<size_t, size_t>> runs;
  for (size_t m = 0; m < n;) {
    if (!mask[(start + m) % n]) {
      ++m;
      continue;
    }
    size_t length = 0;
    while (m + length < n && mask[(start + m + length) % n]) ++length;
    runs.emplace_back((start + m) % n, length);
    m += length;
  }
  return runs;
}

// heading of the path at point i (chord through the neighbours)
double heading_at(const std::vector<Vec2>& pts, size_t i, bool closed) {
  const size_t n = pts.size();
  const Vec2 d = pts[neighbour(i, 1, n, closed)] - pts[neighbour(i, -1, n, closed)];
  return std::atan2(d.y(), d.x());
}

}  // namespace

Corridor make_corridor(const std::vector<Vec2>& centre, bool closed, const std::vector<Vec2>& left,
                       const std::vector<Vec2>& right, bool boundaries_closed, double max_side_m) {
  Corridor c;
  c.centre = centre;
  c.closed = closed;
  const size_t n = centre.size();
  for (size_t i = 0; i < n; ++i) {
    // the normal from the chord through the neighbours
    Vec2 t = centre[neighbour(i, 1, n, closed)] - centre[neighbour(i, -1, n, closed)];
    t = t.norm() > 1e-9 ? t.normalized() : Vec2::UnitX();
    c.normal.emplace_back(-t.y(), t.x());
    c.left_m.push_back(
        std::min(max_side_m, distance_to_polyline(centre[i], left, boundaries_closed)));
    c.right_m.push_back(
        std::min(max_side_m, distance_to_polyline(centre[i], right, boundaries_closed)));
  }
  return c;
}

double footprint_clearance(const core::Pose2& pose, const std::vector<MapCone>& cones,
                           const Footprint& f, Vec2* at) {
  double best = std::numeric_limits<double>::infinity();
  const double c = std::cos(pose.yaw), s = std::sin(pose.yaw);
  for (const MapCone& cone : cones) {
    const Vec2 rel = cone.position - pose.position();
    if (rel.squaredNorm() > kFootprintReachM * kFootprintReachM) continue;
    const Vec2 local(c * rel.x() + s * rel.y(), -s * rel.x() + c * rel.y());
    const double d = distance_to_box(local, -f.rear_m, f.front_m, f.half_width_m) -
                     0.5 * core::cone_size(cone.cls).base_m;
    if (d < best) {
      best = d;
      if (at) *at = cone.position;
    }
  }
  return best;
}

namespace {

// the least-curvature line through the corridor with the footprint kept margin[i] clear of the
// cones at point i (see plan_racing_line)
RacingLine plan_with_margins(const Corridor& c, const std::vector<MapCone>& cones,
                             const Footprint& f, double curvature_target,
                             const std::vector<double>& margin) {
  RacingLine line;
  const size_t n = c.centre.size();

  // the corridor shrunk by half the car, the margin and a small cone's base radius
  std::vector<double> lo(n), hi(n);
  for (size_t i = 0; i < n; ++i) {
    const double shrink =
        f.half_width_m + margin[i] + 0.5 * core::cone_size(core::ConeClass::kBlue).base_m;
    lo[i] = -(c.right_m[i] - shrink);
    hi[i] = c.left_m[i] - shrink;
  }
  // a boundary cone keeps its side: a blue cone stays left of the line, a yellow one right,
  // also where the boundary polyline the corridor was measured to passes it by, or the
  // reference line runs on its far side (a lane that zig-zags sharply at one cone)
  for (const MapCone& cone : cones) {
    const bool left = cone.cls == core::ConeClass::kBlue;
    if (!left && cone.cls != core::ConeClass::kYellow) continue;
    size_t nearest = 0;
    double nearest_d2 = std::numeric_limits<double>::infinity();
    for (size_t i = 0; i < n; ++i) {
      const double d2 = (cone.position - c.centre[i]).squaredNorm();
      if (d2 < nearest_d2) nearest_d2 = d2, nearest = i;
    }
    if (nearest_d2 > kSideReachM * kSideReachM) continue;
    for (int k = -1; k <= 1; ++k) {
      const size_t j = neighbour(nearest, k, n, c.closed);
      const double cone_shrink =
          f.half_width_m + margin[j] + 0.5 * core::cone_size(cone.cls).base_m;
      if (lo[j] > hi[j]) continue;  // narrower than the car: the line keeps to the middle
      const double offset = c.normal[j].dot(cone.position - c.centre[j]);
      if (left) hi[j] = std::max(lo[j], std::min(hi[j], offset - cone_shrink));
      if (!left) lo[j] = std::min(hi[j], std::max(lo[j], offset + cone_shrink));
    }
  }
  // an open path starts where the car is, heading along the reference line
  for (size_t i = 0; i < n; ++i)
    if (held_start(c, i)) lo[i] = hi[i] = 0.0;

  // plan, check the footprint along the line, narrow the corridor where it comes too close
  std::vector<Vec2> pts(n);
  std::vector<double> offsets;
  std::vector<double> weight(n, 1.0);
  std::vector<int> active;
  const auto plan = [&] {
    for (int round = 0; round < kMaxFootprintRounds; ++round) {
      offsets = least_curvature_offsets(c, lo, hi, weight, active);
      for (size_t i = 0; i < n; ++i) pts[i] = c.centre[i] + offsets[i] * c.normal[i];
      bool narrowed = false;
      std::vector<double> cut_left(n, 0.0), cut_right(n, 0.0);
      line.min_clearance_m = std::numeric_limits<double>::infinity();
      for (size_t i = 0; i < n; ++i) {
        const core::Pose2 pose{pts[i].x(), pts[i].y(), heading_at(pts, i, c.closed)};
        Vec2 at = Vec2::Zero();
        const double clearance = footprint_clearance(pose, cones, f, &at);
        if (clearance < line.min_clearance_m) {
          line.min_clearance_m = clearance;
          line.min_clearance_at = at;
        }
        if (clearance >= margin[i]) continue;
        // the cone's side of the reference line loses room near this point
        const bool cone_left = c.normal[i].dot(at - c.centre[i]) > 0.0;
        const double cut = margin[i] - clearance;
        // tapered either side, so that the line bends smoothly round the cone rather than
        // following a step of the bound
        for (int k = -kNarrowHalfWindow; k <= kNarrowHalfWindow; ++k) {
          const size_t j = neighbour(i, k, n, c.closed);
          if (held_start(c, j)) continue;
          if (lo[j] >= hi[j]) continue;  // no room left to give
          const double share = 1.0 - static_cast<double>(std::abs(k)) / (kNarrowHalfWindow + 1);
          std::vector<double>& cuts = cone_left ? cut_left : cut_right;
          cuts[j] = std::max(cuts[j], cut * share);
          narrowed = true;
        }
      }
      for (size_t j = 0; j < n; ++j) {
        hi[j] -= cut_left[j];
        lo[j] += cut_right[j];
      }
      if (!narrowed) break;
    }
  };
  const std::vector<double> lo_start = lo, hi_start = hi;
  plan();

  // with a curvature target: the turns tighter than it (and a few points either side) weigh
  // their curvature more, round after round, while the line is still tighter there
  if (curvature_target > 0.0) {
    const std::vector<double> k0 = curvatures(pts, c.closed);
    std::vector<char> tight(n, 0);
    for (size_t i = 0; i < n; ++i)
      if (std::abs(k0[i]) > curvature_target)
        for (int k = -kNarrowHalfWindow; k <= kNarrowHalfWindow; ++k)
          tight[neighbour(i, k, n, c.closed)] = 1;
    // (a turn where the corridor leaves the line little room is left as it is: weighed, the
    // line there pulls away from the middle it is drawn to where there is no room)
    std::vector<std::pair<size_t, size_t>> runs = runs_of(tight, c.closed);
    std::erase_if(runs, [&](const std::pair<size_t, size_t>& run) {
      for (size_t q = 0; q < run.second; ++q) {
        const size_t j = (run.first + q) % n;
        if (hi[j] - lo[j] < kMinRoomM) {
          for (size_t r = 0; r < run.second; ++r) tight[(run.first + r) % n] = 0;
          return true;
        }
      }
      return false;
    });
    const std::vector<Vec2> first_pts = pts;
    const std::vector<double> first_offsets = offsets;
    const double first_clearance = line.min_clearance_m;
    const Vec2 first_at = line.min_clearance_at;
    bool reweighed = false;
    for (int round = 0; round < kMaxReweighRounds && !runs.empty(); ++round) {
      const std::vector<double> k = curvatures(pts, c.closed);
      bool over = false;
      for (size_t i = 0; i < n; ++i) {
        const double excess = std::abs(k[i]) / curvature_target;
        if (!tight[i] || excess <= 1.0) continue;
        weight[i] = std::min(kMaxWeight, weight[i] * excess * excess * kReweighGain);
        over = true;
      }
      if (!over) break;
      plan();
      reweighed = true;
    }
    // a turn the weights could not bring under the target (a minimum hairpin, which needs
    // full lock whatever the line) keeps its least-curvature shape: spreading its curvature
    // gains nothing where the car turns at the tight-turn speed anyway
    if (reweighed) {
      const std::vector<double> k = curvatures(pts, c.closed);
      bool kept_any = false;
      for (const auto& [first, length] : runs) {
        double peak = 0.0;
        for (size_t q = 0; q < length; ++q) peak = std::max(peak, std::abs(k[(first + q) % n]));
        if (peak > kTargetSlack * curvature_target)
          for (size_t q = 0; q < length; ++q) weight[(first + q) % n] = 1.0;
        else
          kept_any = true;
      }
      // planned again from the corridor as it was before any narrowing, with the weights of the
      // turns that came under the target only; none: the first line. A line that brings the
      // footprint closer to a cone than the first did is not kept either
      if (kept_any) {
        lo = lo_start;
        hi = hi_start;
        plan();
      }
      const double least_margin = *std::min_element(margin.begin(), margin.end());
      if (!kept_any || line.min_clearance_m < std::min(least_margin, first_clearance) - 1e-3) {
        pts = first_pts;
        offsets = first_offsets;
        line.min_clearance_m = first_clearance;
        line.min_clearance_at = first_at;
      }
    }
  }

  // the figures of the result
  line.path = Path{pts, c.closed};
  line.offset_m = offsets;
  const std::vector<double> k = curvatures(pts, c.closed);
  line.min_width_m = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < n; ++i) {
    if (std::abs(k[i]) > line.max_curvature) {
      line.max_curvature = std::abs(k[i]);
      line.max_curvature_at = pts[i];
    }
    if (c.left_m[i] + c.right_m[i] < line.min_width_m) {
      line.min_width_m = c.left_m[i] + c.right_m[i];
      line.min_width_at = c.centre[i];
    }
  }
  return line;
}

// point by point, the tight-turn margin from `before_m` ahead of a point of `line` tighter than
// the footprint's tight curvature to `after_m` past it, the margin elsewhere, and in between a
// linear change over kMarginRampM (a step would kink a line that runs along the bound there)
std::vector<double> margins_along(const Path& line, const Footprint& f) {
  const size_t n = line.points.size();
  std::vector<double> margin(n, f.margin_m);
  const std::vector<double> k = curvatures(line.points, line.closed);
  std::vector<double> s = line.arc_lengths();
  const double lap = line.closed ? s.back() : 0.0;
  s.resize(n);
  for (size_t j = 0; j < n; ++j) {
    if (std::abs(k[j]) < f.tight_curvature) continue;
    for (size_t i = 0; i < n; ++i) {
      double ahead = s[j] - s[i];  // how far the tight point lies ahead of point i
      if (lap > 0.0) ahead = std::remainder(ahead, lap);
      const double outside = std::max(ahead - f.tight_before_m, -ahead - f.tight_after_m);
      const double share = std::clamp(1.0 - outside / kMarginRampM, 0.0, 1.0);
      margin[i] = std::max(margin[i], f.margin_m + share * (f.tight_margin_m - f.margin_m));
    }
  }
  return margin;
}

}  // namespace

RacingLine plan_racing_line(const Corridor& c, const std::vector<MapCone>& cones,
                            const Footprint& f, double curvature_target) {
  const size_t n = c.centre.size();
  if (n < 3) return {};
  if (!(f.tight_curvature > 0.0 && f.tight_margin_m > f.margin_m))
    return plan_with_margins(c, cones, f, curvature_target, std::vector<double>(n, f.margin_m));
  // the line with the margin everywhere shows where the turns near full lock are (those that
  // need it with the most room the line is given); then the line again with the tight-turn
  // margin about them. (Found on the line with the larger margin, a turn whose reweighing that
  // margin left too little room for came out tight and kept it: FSS19's second hairpin)
  const RacingLine line =
      plan_with_margins(c, cones, f, curvature_target, std::vector<double>(n, f.margin_m));
  const std::vector<double> margin = margins_along(line.path, f);
  if (std::all_of(margin.begin(), margin.end(), [&](double m) { return m == f.margin_m; }))
    return line;
  return plan_with_margins(c, cones, f, curvature_target, margin);
}

RacingLine plan_racing_line(const std::vector<Vec2>& reference, bool closed,
                            const std::vector<Vec2>& left, const std::vector<Vec2>& right,
                            const std::vector<MapCone>& cones, const Footprint& footprint,
                            int passes, double spacing_m, double curvature_target) {
  std::vector<Vec2> ref = resample(reference, spacing_m, closed);
  RacingLine line;
  double min_width = 0.0;
  Vec2 min_width_at = Vec2::Zero();
  for (int pass = 0; pass < passes; ++pass) {
    const Corridor corridor = make_corridor(ref, closed, left, right, closed);
    line = plan_racing_line(corridor, cones, footprint, curvature_target);
    if (line.path.points.size() < 3) return line;
    if (pass == 0) min_width = line.min_width_m, min_width_at = line.min_width_at;
    ref = resample(line.path.points, spacing_m, closed);
  }
  line.min_width_m = min_width;
  line.min_width_at = min_width_at;
  return line;
}

}  // namespace conesim::control
