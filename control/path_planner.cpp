#include "control/path_planner.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace conesim::control {

namespace {

using core::ConeClass;
using core::MapCone;
using core::Pose2;

// window of chain segments searched ahead of the last one used by the walk
constexpr size_t kWalkWindowSegments = 4;
// the first cone of a chain is searched beside the car within this longitudinal window, metres
constexpr double kStartBehindM = 6.0;
constexpr double kStartAheadM = 15.0;
// links shorter than this join two detections of one cone, metres
constexpr double kMinLinkM = 0.5;
// the turn a chain is expected to keep from one link to the next is capped at this, radians
constexpr double kMaxPredictedTurnRad = 0.6;
// links costing within this share of the cheapest are told apart by the link after each, when
// the last link turned by this much or more (radians): the guess that the turn goes on is tried
constexpr double kAmbiguousLinkShare = 0.25;
constexpr double kTurnGuessRad = 0.1;
// the link into a chain's first cone, which gives the boundary's direction there, is at most
// this long, metres (cones stand up to 5 m apart along a boundary)
constexpr double kMaxBackLinkM = 5.5;
// a closed chain needs this many cones before it may return to its first one
constexpr size_t kMinClosedChainCones = 8;
// a link never passes a cone of its own boundary this close to it on the track's side, metres
// (less than the narrowest lane, 3 m, so that the other boundary's cones are never that close)
constexpr double kMaxPassedInsideM = 2.4;
// ... when it lies at least this share of the link's length along it and this far from the
// link's end, metres
constexpr double kMinPassedAlongShare = 0.5;
constexpr double kMinPassedGapM = 1.0;
// a walk may run straight before the first cone of a boundary for this long, metres
constexpr double kMaxWalkBeforeChainsM = 12.0;
// chains are rebuilt at most this many times after dropping cones that sit on the other side
constexpr int kMaxChainRounds = 3;
// each walk step advances at least this share of a step along the walk direction
constexpr double kMinStepShare = 0.5;
// a circuit walk may stop at the start once it has gone this far, metres
constexpr double kMinCircuitM = 50.0;
constexpr double kPi = std::numbers::pi;
// a link of a closed boundary this many times longer than both its neighbours spans a gap
constexpr double kGapLinkShare = 1.4;

// extra cost of a cone in a chain of `side_class`; negative when it may not be used
double class_penalty(ConeClass cls, ConeClass side_class, const PlannerParams& params) {
  if (cls == side_class) return 0.0;
  if (cls == ConeClass::kOrangeSmall || cls == ConeClass::kOrangeBig || cls == ConeClass::kUnknown)
    return params.off_class_penalty_m;
  return -1.0;
}

// the turn from direction a to direction b, radians (positive left)
double turn_between(const Vec2& a, const Vec2& b) {
  return std::atan2(core::cross(a, b), a.dot(b));
}

// the direction a boundary runs at its first cone and the turn it made there, from the two
// cones before it on the boundary (all three of the boundary's own colour, short links apart,
// the nearer one beside the car and behind the first cone); without them the car's heading and
// no turn. Inside a turn the car's heading lags the boundary's: a chain started at a hairpin's
// apex with the car's heading took the inner cones' turn for a bend and linked 8.6 m on to the
// start's big orange cones (hard trackdrive 7069, LiDAR, lap 1: the path looped back on itself
// and the car unwound mid-hairpin), or 3.3 m across to the next lane's cone instead of 4.0 m
// along its own (hard trackdrive 7131, GraphSLAM, lap 1). The turn matters at a hairpin's tip:
// with the direction alone, the tip's next cone looked a 1.4 rad turn and the chain jumped 9.7 m
// to a cone of another part of the track (hard trackdrive 7195)
struct ChainStart {
  Vec2 dir;
  double last_turn = 0.0;
};
ChainStart chain_start(const std::vector<MapCone>& cones, ConeClass side_class, double side,
                       const Pose2& from, const PlannerParams& params,
                       const std::vector<bool>& used, int first) {
  const double hw = params.assumed_half_width_m;
  ChainStart start{from.heading(), 0.0};
  // an orange first cone (a start gate's, a time-keeping one) stands off the boundary's line
  if (cones[static_cast<size_t>(first)].cls != side_class) return start;
  // up to two links back from the first cone, each one behind the cone it leads to
  size_t at = static_cast<size_t>(first);
  Vec2 reference = from.heading();
  for (int back = 0; back < 2; ++back) {
    const double at_x = from.inverse_transform(cones[at].position).x();
    double best = std::numeric_limits<double>::infinity();
    int before = -1;
    for (size_t i = 0; i < cones.size(); ++i) {
      if (used[i] || i == at || cones[i].cls != side_class) continue;
      // the cone before the first is beside the car as the first is; the one before that (round a
      // hairpin's tip, beside nothing) only leads on to it within the turn limit
      const Vec2 local = from.inverse_transform(cones[i].position);
      const double lateral = side * local.y();
      if (back == 0 && (local.x() > at_x - kMinLinkM || lateral < 0.3 || lateral > 2.0 * hw + 0.5))
        continue;
      const Vec2 v = cones[at].position - cones[i].position;
      const double d = v.norm();
      if (d < kMinLinkM || d > kMaxBackLinkM) continue;
      const double turn = turn_between(reference, v);
      if (std::abs(turn) > params.max_link_turn_rad) continue;
      const double cost = d * (1.0 + params.turn_weight * turn * turn);
      if (cost < best) best = cost, before = static_cast<int>(i);
    }
    if (before < 0) break;
    const Vec2 v = (cones[at].position - cones[static_cast<size_t>(before)].position).normalized();
    if (back == 0)
      start.dir = v;
    else
      start.last_turn = turn_between(v, start.dir);
    reference = v;
    at = static_cast<size_t>(before);
  }
  return start;
}

// one boundary chained from the cone beside `from` on side `side` (+1 left, -1 right)
std::vector<Vec2> chain_one(const std::vector<MapCone>& cones, ConeClass side_class, double side,
                            const Pose2& from, const PlannerParams& params, double max_length_m,
                            bool whole_circuit, std::vector<bool>& used, bool& closed,
                            std::vector<int>& ids) {
  closed = false;
  std::vector<Vec2> chain;
  ids.clear();

  // first cone: the one nearest the expected boundary point beside the car
  const double hw = params.assumed_half_width_m;
  int first = -1;
  double best = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < cones.size(); ++i) {
    const double penalty = class_penalty(cones[i].cls, side_class, params);
    if (used[i] || penalty < 0.0) continue;
    const Vec2 local = from.inverse_transform(cones[i].position);
    const double lateral = side * local.y();
    if (local.x() < -kStartBehindM || local.x() > kStartAheadM) continue;
    if (lateral < 0.3 || lateral > 2.0 * hw + 0.5) continue;
    const double cost =
        local.x() * local.x() + 4.0 * (lateral - hw) * (lateral - hw) + penalty * penalty;
    if (cost < best) best = cost, first = static_cast<int>(i);
  }
  if (first < 0) return chain;
  used[static_cast<size_t>(first)] = true;
  chain.push_back(cones[static_cast<size_t>(first)].position);
  ids.push_back(first);

  // links: the cheapest unused cone ahead within the turn limit, until none or long enough;
  // a link is judged against the direction the boundary would take if it kept turning as it
  // did at the last cone (a constant-curvature guess), so that a turn is followed rather than
  // cut short by cones of a nearby part of the track
  auto link_cost = [&](const Vec2& cur, const Vec2& dir, double last_turn, size_t i,
                       bool continuation) {
    const bool closing_allowed = !continuation;
    const bool is_first = closing_allowed && whole_circuit && static_cast<int>(i) == first &&
                          chain.size() >= kMinClosedChainCones;
    constexpr double kNone = std::numeric_limits<double>::infinity();
    if (used[i] && !is_first) return kNone;
    const double penalty = class_penalty(cones[i].cls, side_class, params);
    if (penalty < 0.0) return kNone;
    const Vec2 v = cones[i].position - cur;
    const double d = v.norm();
    if (d < kMinLinkM || d > params.max_link_m) return kNone;
    const double turn = turn_between(dir, v);
    const double max_turn = !whole_circuit && d <= params.short_link_m
                                ? params.max_short_link_turn_rad
                                : params.max_link_turn_rad;
    if (std::abs(turn) > max_turn) return kNone;
    const double bend = turn - std::clamp(last_turn, -kMaxPredictedTurnRad, kMaxPredictedTurnRad);
    return d * (1.0 + params.turn_weight * bend * bend) + (continuation ? 0.0 : penalty);
  };
  // while the chain is turning, a cone nearly as cheap a link as the cheapest, and turning less,
  // is told apart from it by the link that could follow each: where a turn ends, the guess that it
  // goes on favours a cone of the part of the track the turn led past, which the boundary cannot
  // follow on from (hard trackdrive 7125 with the LiDAR, lap 1: at the exit of a minimum hairpin
  // the yellow chain went 3.9 m to the start straight's cones instead of 2.0 m along its own leg,
  // costs 3.9 against 4.2; the path bent 0.5 m towards the inner cones and every full-lock
  // manoeuvre scored a hit at the exit). The link after counts its shape and length only (an
  // off-class cone's penalty is the link's own); a cone with no link after it counts its own link
  // once more.
  auto link_after = [&](const Vec2& cur, const Vec2& dir, size_t i) {
    if (static_cast<int>(i) == first) return 0.0;
    const Vec2 v = cones[i].position - cur;
    const double turn = turn_between(dir, v);
    const bool was_used = used[i];
    used[i] = true;
    double after = std::numeric_limits<double>::infinity();
    for (size_t j = 0; j < cones.size(); ++j)
      after = std::min(after, link_cost(cones[i].position, v.normalized(), turn, j, true));
    used[i] = was_used;
    return std::isfinite(after) ? after : v.norm();
  };
  const ChainStart start = chain_start(cones, side_class, side, from, params, used, first);
  Vec2 dir = start.dir;
  double last_turn = start.last_turn;
  double length = 0.0;
  std::vector<double> costs(cones.size());
  while (length < max_length_m) {
    const Vec2 cur = chain.back();
    int next = -1;
    best = std::numeric_limits<double>::infinity();
    // the first link may also go on straight: the cones before the first one can belong to
    // another part of the track where the boundary starts (hard trackdrive 7109: the yellow
    // cone behind the start's first was 4.6 m over in the lane below, a 1.2 rad turn that sent
    // the chain off the start straight)
    const bool guessed_turn = chain.size() == 1 && last_turn != 0.0;
    for (size_t i = 0; i < cones.size(); ++i) {
      costs[i] = link_cost(cur, dir, last_turn, i, false);
      if (guessed_turn) costs[i] = std::min(costs[i], link_cost(cur, dir, 0.0, i, false));
      if (costs[i] < best) best = costs[i], next = static_cast<int>(i);
    }
    if (next >= 0 && std::abs(last_turn) >= kTurnGuessRad) {
      const double close_enough = best * (1.0 + kAmbiguousLinkShare);
      auto turn_to = [&](size_t i) {
        const Vec2 v = cones[i].position - cur;
        return std::abs(turn_between(dir, v));
      };
      const double cheapest_turn = turn_to(static_cast<size_t>(next));
      double best_continued = std::numeric_limits<double>::infinity();
      for (size_t i = 0; i < cones.size(); ++i) {
        // only a link that turns less than the cheapest may take its place: the look-ahead
        // checks the guess that the turn goes on, not a link that already turned less (EUFS
        // small_track_2: the outer cone of a bend, where the boundary turns by 0.7 rad, lost to
        // the smoother link past it, which ran 1.25 m from an inner cone; the other chain then
        // dropped that cone and the car hit it)
        if (costs[i] > close_enough || turn_to(i) > cheapest_turn + 1e-9) continue;
        const double continued = costs[i] + link_after(cur, dir, i);
        if (continued < best_continued) best_continued = continued, next = static_cast<int>(i);
      }
    }
    // a boundary runs along its innermost cones: a link that would pass one of the chain's own
    // colour on the track's side, nearer than the link's end, goes to that cone instead (hard
    // autocross 7108, ground truth: leaving a right-hand bend, the guess that the bend goes on
    // sent the yellow chain 4.3 m across to the start straight's yellow cones, 2 m beyond its
    // own, instead of 3.8 m along its own boundary, which bent left there, costs 4.4 against
    // 6.0; the path then ran 1 m towards the straight, and the car hit two of its own cones)
    if (next >= 0 && next != first) {
      const Vec2 v = cones[static_cast<size_t>(next)].position - cur;
      const double d = v.norm();
      int inner = -1;
      for (size_t i = 0; i < cones.size(); ++i) {
        if (static_cast<int>(i) == next || cones[i].cls != side_class || !std::isfinite(costs[i]))
          continue;
        const Vec2 a = cones[i].position - cur;
        const double along = a.dot(v) / d;
        const double inside = -side * core::cross(v, a) / d;
        // the cone passed is another cone of the boundary, not a second copy of the link's ends
        // (a SLAM that maps a cone twice, 0.5-0.9 m apart, put copies beside both): well along
        // the link, not a sharp turn back, and apart from the link's end
        if (along < kMinPassedAlongShare * d || along >= d || inside <= 0.0 ||
            inside > kMaxPassedInsideM || a.norm() >= d ||
            std::abs(turn_between(dir, a)) > params.max_link_turn_rad ||
            (cones[i].position - cones[static_cast<size_t>(next)].position).norm() < kMinPassedGapM)
          continue;
        if (inner < 0 || costs[i] < costs[static_cast<size_t>(inner)]) inner = static_cast<int>(i);
      }
      if (inner >= 0) next = inner;
    }
    if (next < 0) break;
    if (next == first) {
      closed = true;
      break;
    }
    const Vec2 v = cones[static_cast<size_t>(next)].position - cur;
    used[static_cast<size_t>(next)] = true;
    chain.push_back(cones[static_cast<size_t>(next)].position);
    ids.push_back(next);
    length += v.norm();
    last_turn = turn_between(dir, v);
    dir = v.normalized();
  }
  return chain;
}

// what the walk finds of one boundary near a point
struct SideHit {
  enum class Kind { kFound, kBefore, kAfter, kFar } kind = Kind::kFar;
  Vec2 point = Vec2::Zero();
  Vec2 tangent = Vec2::UnitX();
};

// the boundary point beside q, searching the chain from segment `index` on (advanced in place)
SideHit find_side(const Path& chain, const Vec2& q, const Vec2& walk_dir, size_t& index,
                  const PlannerParams& params) {
  SideHit hit;
  if (chain.points.empty()) return hit;

  // a single cone: beside q when q is level with it along the walk
  if (chain.points.size() == 1) {
    const double along = (q - chain.points.front()).dot(walk_dir);
    hit.point = chain.points.front();
    hit.tangent = walk_dir;
    if (along < -params.step_m)
      hit.kind = SideHit::Kind::kBefore;
    else if (along > params.step_m)
      hit.kind = SideHit::Kind::kAfter;
    else if ((q - hit.point).norm() <= params.max_side_distance_m)
      hit.kind = SideHit::Kind::kFound;
    return hit;
  }

  // nearest point over a short window of segments, then whether q is off either end
  const PathProjection proj = project_onto(chain, q, index, kWalkWindowSegments);
  index = proj.segment;  // the window only looks ahead, so this never goes back
  hit.point = proj.point;
  hit.tangent = (chain.segment_end(proj.segment) - chain.points[proj.segment]).normalized();
  const size_t last = chain.segment_count() - 1;
  if (!chain.closed && proj.segment == 0 && proj.t <= 0.0 &&
      (q - proj.point).dot(hit.tangent) < 0.0) {
    hit.kind = SideHit::Kind::kBefore;
  } else if (!chain.closed && proj.segment == last && proj.t >= 1.0 &&
             (q - proj.point).dot(hit.tangent) > 0.0) {
    hit.kind = SideHit::Kind::kAfter;
  } else if (proj.distance_m <= params.max_side_distance_m) {
    hit.kind = SideHit::Kind::kFound;
  }
  return hit;
}

// left normal of a unit vector
Vec2 left_normal(const Vec2& t) {
  return {-t.y(), t.x()};
}

}  // namespace

Boundaries chain_boundaries(const std::vector<MapCone>& cones, const Pose2& from,
                            const PlannerParams& params, double max_length_m, bool whole_circuit) {
  Boundaries b;
  std::vector<bool> excluded(cones.size(), false);
  for (int round = 0; round < kMaxChainRounds; ++round) {
    // both chains, left first; a cone goes into one chain at most
    std::vector<bool> used = excluded;
    std::vector<int> left_ids, right_ids;
    b.left = chain_one(cones, ConeClass::kBlue, 1.0, from, params, max_length_m, whole_circuit,
                       used, b.left_closed, left_ids);
    b.right = chain_one(cones, ConeClass::kYellow, -1.0, from, params, max_length_m, whole_circuit,
                        used, b.right_closed, right_ids);

    // a cone lying on the other boundary (a wrong colour, a spurious cone) is dropped, and the
    // chains are built again without it
    bool conflict = false;
    const Path left{b.left, b.left_closed}, right{b.right, b.right_closed};
    auto flag = [&](const std::vector<int>& ids, const Path& other) {
      if (other.points.size() < 2) return;
      const size_t last = other.segment_count() - 1;
      for (const int i : ids) {
        const Vec2& p = cones[static_cast<size_t>(i)].position;
        const PathProjection proj = project_onto(other, p, 0, other.segment_count());
        const bool beside = other.closed || ((proj.segment > 0 || proj.t > 0.0) &&
                                             (proj.segment < last || proj.t < 1.0));
        if (proj.distance_m < params.min_boundary_gap_m ||
            (beside && proj.distance_m > params.max_boundary_gap_m)) {
          excluded[static_cast<size_t>(i)] = true;
          conflict = true;
        }
      }
    };
    flag(left_ids, right);
    flag(right_ids, left);
    if (!conflict) break;
  }
  return b;
}

namespace {

// where a cone lies beside a closed reference line with arc lengths s
struct Beside {
  bool near = false;      // within max_side_distance_m
  double offset_m = 0.0;  // positive left
  double s = 0.0;
};

Beside beside(const Path& reference, const std::vector<double>& s, const Vec2& p,
              const PlannerParams& params) {
  Beside b;
  const PathProjection at = project_onto(reference, p, 0, reference.segment_count());
  if (at.distance_m > params.max_side_distance_m) return b;
  const Vec2 tangent = reference.segment_end(at.segment) - reference.points[at.segment];
  b.near = true;
  b.offset_m = (core::cross(tangent, p - at.point) > 0.0 ? 1.0 : -1.0) * at.distance_m;
  b.s = s[at.segment] + at.t * (s[at.segment + 1] - s[at.segment]);
  return b;
}

// a blue cone well right of the line or a yellow one well left of it: further than half the
// narrowest lane (a line that cuts a corner, such as a smoothed lap, passes close to the inner
// cones and may pass them on the wrong side by a little)
bool wrong_side(ConeClass cls, const Beside& b) {
  constexpr double kWrongSideM = 0.75;
  return b.near && ((cls == ConeClass::kBlue && b.offset_m < -kWrongSideM) ||
                    (cls == ConeClass::kYellow && b.offset_m > kWrongSideM));
}

std::vector<double> closed_arc_lengths(const Path& reference) {
  std::vector<double> s(reference.segment_count() + 1, 0.0);
  for (size_t i = 0; i + 1 < s.size(); ++i)
    s[i + 1] = s[i] + (reference.segment_end(i) - reference.points[i]).norm();
  return s;
}

double median(std::vector<double> v) {
  const size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(mid), v.end());
  return v[mid];
}

// where each cone lies beside a closed reference line (arc lengths s), and whether it is a blue
// or yellow cone of a wrong colour for its place: well on the wrong side of the line
// (wrong_side), or nearer, across the lane, to the cones of the other colour beside it than to
// those of its own. A line the car drove passes close to the cones on either side where it cuts
// a corner or weaves through a slalom, so the side alone misses a cone of the lane's far side
// seen in the wrong colour (hard trackdrive 7023 with the LiDAR: a yellow cone mapped as blue
// stood 1.0 m in from the yellow cones and 0.67 m right of lap 1's line; kept as a blue cone,
// which the racing line keeps on its left, it put the line through that cone and the next)
struct Placed {
  Beside at;
  bool wrong = false;
};
std::vector<Placed> placed_beside(const Path& reference, const std::vector<double>& s,
                                  const std::vector<MapCone>& cones, const PlannerParams& params) {
  // the cones beside one within this arc length of it give their colour's place across the lane
  constexpr double kColourReachM = 6.0;
  const double lap_m = s.back();
  std::vector<Placed> out(cones.size());
  std::vector<bool> side_wrong(cones.size());
  for (size_t i = 0; i < cones.size(); ++i) {
    out[i].at = beside(reference, s, cones[i].position, params);
    out[i].wrong = side_wrong[i] = wrong_side(cones[i].cls, out[i].at);
  }
  for (size_t i = 0; i < cones.size(); ++i) {
    const ConeClass cls = cones[i].cls;
    if (!out[i].at.near || out[i].wrong || (cls != ConeClass::kBlue && cls != ConeClass::kYellow))
      continue;
    std::vector<double> own, other;
    for (size_t j = 0; j < cones.size(); ++j) {
      if (j == i || !out[j].at.near || side_wrong[j]) continue;
      const double ds = std::abs(std::remainder(out[j].at.s - out[i].at.s, lap_m));
      if (ds > kColourReachM) continue;
      if (cones[j].cls == cls)
        own.push_back(out[j].at.offset_m);
      else if (cones[j].cls == ConeClass::kBlue || cones[j].cls == ConeClass::kYellow)
        other.push_back(out[j].at.offset_m);
    }
    if (own.empty() || other.empty()) continue;
    const double offset = out[i].at.offset_m;
    out[i].wrong = std::abs(offset - median(other)) < std::abs(offset - median(own));
  }
  return out;
}

}  // namespace

Boundaries boundaries_along(const Path& reference, const std::vector<MapCone>& cones,
                            const PlannerParams& params) {
  Boundaries b;
  if (!reference.closed || reference.points.size() < 3) return b;
  const std::vector<double> s = closed_arc_lengths(reference);
  const double lap_m = s.back();

  struct Along {
    double s;
    Vec2 p;
  };
  std::vector<Along> left, right;
  const std::vector<Placed> placed = placed_beside(reference, s, cones, params);
  for (size_t i = 0; i < cones.size(); ++i) {
    const MapCone& c = cones[i];
    const Beside& at = placed[i].at;
    if (c.cls == ConeClass::kUnknown || !at.near || placed[i].wrong) continue;
    const bool on_left =
        c.cls == ConeClass::kBlue || (c.cls != ConeClass::kYellow && at.offset_m > 0.0);
    (on_left ? left : right).push_back({at.s, c.position});
  }
  auto order = [&](std::vector<Along>& side, std::vector<Vec2>& chain, bool& closed) {
    std::sort(side.begin(), side.end(), [](const Along& a, const Along& c) { return a.s < c.s; });
    double widest = 0.0;
    for (size_t i = 0; i < side.size(); ++i) {
      const double next = i + 1 < side.size() ? side[i + 1].s : side.front().s + lap_m;
      widest = std::max(widest, next - side[i].s);
      chain.push_back(side[i].p);
    }
    closed = side.size() >= kMinClosedChainCones && widest <= 2.0 * params.max_link_m;
  };
  order(left, b.left, b.left_closed);
  order(right, b.right, b.right_closed);
  return b;
}

namespace {

// the point a fraction t along the arc from a to b of the circle through a, b and c (the chord
// when the three are nearly in line)
Vec2 on_arc(const Vec2& a, const Vec2& b, const Vec2& c, double t) {
  const Vec2 chord = (1.0 - t) * a + t * b;
  const double d = 2.0 * core::cross(b - a, c - a);
  if (std::abs(d) < 1e-9 * (b - a).squaredNorm() * (c - a).norm()) return chord;
  // the circle's centre relative to a
  const Vec2 ab = b - a, ac = c - a;
  const Vec2 o = a + Vec2(ac.y() * ab.squaredNorm() - ab.y() * ac.squaredNorm(),
                          ab.x() * ac.squaredNorm() - ac.x() * ab.squaredNorm()) /
                         d;
  const double r = (a - o).norm();
  const double a0 = std::atan2(a.y() - o.y(), a.x() - o.x());
  const double sweep = std::remainder(std::atan2(b.y() - o.y(), b.x() - o.x()) - a0, 2.0 * kPi);
  const double angle = a0 + t * sweep;
  return o + r * Vec2(std::cos(angle), std::sin(angle));
}

// a closed chain with points added where one link is much longer than both its neighbours (a
// cone or more missing from an even spacing): on the circle through the link's ends and the cone
// before it, on the one through them and the cone after it, or on the chord, whichever reaches
// furthest into the track (`track_side` +1: the track lies left of the chain's direction, -1:
// right), so that a missing cone on a curve's inside is assumed where it may stand; the added
// points also go to `added`
std::vector<Vec2> filled(const std::vector<Vec2>& chain, double track_side,
                         std::vector<Vec2>& added) {
  const size_t n = chain.size();
  if (n < 4) return chain;
  auto at = [&](size_t i) -> const Vec2& { return chain[i % n]; };
  std::vector<Vec2> out;
  for (size_t i = 0; i < n; ++i) {
    out.push_back(at(i));
    const Vec2 &p0 = at(i + n - 1), &p1 = at(i), &p2 = at(i + 1), &p3 = at(i + 2);
    const double link = (p2 - p1).norm();
    const double neighbours = std::max((p1 - p0).norm(), (p3 - p2).norm());
    if (neighbours <= 0.0 || link <= kGapLinkShare * neighbours) continue;
    const Vec2 along = (p2 - p1) / link;
    const int pieces = std::max(2, static_cast<int>(std::lround(link / neighbours)));
    for (int j = 1; j < pieces; ++j) {
      const double t = static_cast<double>(j) / pieces;
      const Vec2 chord = (1.0 - t) * p1 + t * p2;
      Vec2 best = chord;
      for (const Vec2& q : {on_arc(p1, p2, p0, t), on_arc(p1, p2, p3, t)})
        if (track_side * core::cross(along, q - chord) >
            track_side * core::cross(along, best - chord))
          best = q;
      out.push_back(best);
      added.push_back(best);
    }
  }
  return out;
}

}  // namespace

Boundaries with_gaps_filled(const Boundaries& b, std::vector<MapCone>& cones) {
  Boundaries out = b;
  std::vector<Vec2> added;
  if (b.left_closed) {
    out.left = filled(b.left, -1.0, added);
    for (const Vec2& p : added) cones.push_back({-1, ConeClass::kBlue, p, Eigen::Matrix2d::Zero()});
  }
  added.clear();
  if (b.right_closed) {
    out.right = filled(b.right, 1.0, added);
    for (const Vec2& p : added)
      cones.push_back({-1, ConeClass::kYellow, p, Eigen::Matrix2d::Zero()});
  }
  return out;
}

std::vector<MapCone> with_sides_kept(const Path& reference, std::vector<MapCone> cones,
                                     const PlannerParams& params) {
  if (!reference.closed || reference.points.size() < 3) return cones;
  const std::vector<Placed> placed =
      placed_beside(reference, closed_arc_lengths(reference), cones, params);
  for (size_t i = 0; i < cones.size(); ++i)
    if (placed[i].wrong) cones[i].cls = ConeClass::kUnknown;
  return cones;
}

std::vector<Vec2> walk_centre_line(const Boundaries& boundaries, const Pose2& from,
                                   const PlannerParams& params, double max_length_m,
                                   bool whole_circuit) {
  const Path left{boundaries.left, whole_circuit && boundaries.left.size() > 2};
  const Path right{boundaries.right, whole_circuit && boundaries.right.size() > 2};
  // a closed chain starts its search on the closing segment, which may span the start
  size_t li = left.closed ? left.segment_count() - 1 : 0;
  size_t ri = right.closed ? right.segment_count() - 1 : 0;

  std::vector<Vec2> line{from.position()};
  Vec2 dir = from.heading();
  const double hw = params.assumed_half_width_m;
  double walked = 0.0;
  while (walked < max_length_m) {
    // the two boundaries beside the next step
    const Vec2& p = line.back();
    const Vec2 q = p + params.step_m * dir;
    const SideHit l = find_side(left, q, dir, li, params);
    const SideHit r = find_side(right, q, dir, ri, params);
    const bool has_l = l.kind == SideHit::Kind::kFound, has_r = r.kind == SideHit::Kind::kFound;
    const double width = (l.point - r.point).norm();

    // centre: midpoint of both, or the one side offset inwards, or straight on before the
    // chains begin; nothing beside and nothing ahead ends the walk
    Vec2 c;
    if (has_l && has_r && width > hw && width < 2.0 * params.max_side_distance_m) {
      c = 0.5 * (l.point + r.point);
    } else if (has_l && (!has_r || (q - l.point).norm() <= (q - r.point).norm())) {
      c = l.point - hw * left_normal(l.tangent);
    } else if (has_r) {
      c = r.point + hw * left_normal(r.tangent);
    } else if ((l.kind == SideHit::Kind::kBefore || r.kind == SideHit::Kind::kBefore) &&
               walked < kMaxWalkBeforeChainsM) {
      c = q;
    } else {
      break;
    }

    // keep moving forward: a centre too little ahead keeps its lateral place but is moved on
    const double ahead = (c - p).dot(dir);
    if (ahead < kMinStepShare * params.step_m) c += (kMinStepShare * params.step_m - ahead) * dir;
    const Vec2 next_dir = (c - p).normalized();

    // a circuit stops when it comes back across the start line
    if (whole_circuit && walked > kMinCircuitM) {
      const Vec2 h = from.heading();
      const Vec2 s = from.position();
      if ((p - s).dot(h) < 0.0 && (c - s).dot(h) >= 0.0 && (c - s).norm() < 2.0 * hw + 2.0)
        return line;
    }
    walked += (c - p).norm();
    line.push_back(c);
    dir = next_dir;
  }
  if (whole_circuit) return {};
  return line;
}

Path plan_local_path(const std::vector<MapCone>& cones, const Pose2& pose,
                     const PlannerParams& params, double horizon_m) {
  // boundaries a little longer than the horizon, so that the walk has cones at its end
  const Boundaries b = chain_boundaries(cones, pose, params, horizon_m + 5.0, false);
  if (b.left.empty() && b.right.empty()) return {};
  std::vector<Vec2> line = walk_centre_line(b, pose, params, horizon_m, false);
  if (line.size() < 3) return {};
  return {smooth(line, params.smooth_half_window, false), false};
}

std::optional<Path> plan_circuit(const std::vector<MapCone>& map, const Pose2& start,
                                 const PlannerParams& params, double spacing_m) {
  // both boundaries must close into loops
  constexpr double kMaxCircuitM = 3000.0;
  const Boundaries b = chain_boundaries(map, start, params, kMaxCircuitM, true);
  if (!b.left_closed || !b.right_closed) return std::nullopt;

  // walk once round, then resample and smooth as a loop
  std::vector<Vec2> line = walk_centre_line(b, start, params, kMaxCircuitM, true);
  if (line.size() < 20) return std::nullopt;
  line = resample(line, spacing_m, true);
  line = smooth(line, params.smooth_half_window, true);
  return Path{resample(line, spacing_m, true), true};
}

}  // namespace conesim::control
