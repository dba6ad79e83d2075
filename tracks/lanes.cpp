#include "tracks/lanes.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <string>
#include <utility>

namespace conesim::tracks {

namespace {

constexpr size_t kNone = std::numeric_limits<size_t>::max();

/// Shortest step limit between consecutive boundary cones; real tracks space them up to ~5.3 m
/// and put single gaps of ~7 m in fast sections.
constexpr double kMinStepLimitM = 8.0;
/// The step limit grows with the layout's own spacing: this many median neighbour distances.
constexpr double kStepLimitSpacings = 2.0;
/// Sharpest turn between consecutive boundary segments while chaining a lane.
constexpr double kMaxTurnRad = 80.0 * std::numbers::pi / 180.0;
/// Sharpest turn when extending an open lane with orange cones in line with it.
constexpr double kMaxExtendTurnRad = 25.0 * std::numbers::pi / 180.0;
/// How much a turn costs relative to distance: score = step * (1 + penalty * (1 - cos turn)).
constexpr double kTurnPenalty = 2.0;
/// Extra path length allowed to slot a skipped cone between two chained ones.
constexpr double kMaxInsertDetourM = 2.0;
/// Passes over the skipped cones (a slotted cone can make room for another).
constexpr int kInsertPasses = 3;
/// A lane closes when its ends are this close (or 1.5 median steps, whichever is larger) ...
constexpr double kCloseGapM = 6.0;
/// ... and it is at least this long and has this many cones.
constexpr double kMinClosedLengthM = 30.0;
constexpr size_t kMinClosedCones = 6;
/// A shorter lane closes only when it turns at least this far round (a small test ring), rad.
constexpr double kMinRingTurnRad = 1.5 * std::numbers::pi;
/// Big orange cones closer than this belong to the same gate group.
constexpr double kGateGroupRadiusM = 6.0;

// the vector rotated by -90 degrees: from "towards the left" to "forward"
Vec2 rotate_right(const Vec2& v) {
  return {v.y(), -v.x()};
}

std::vector<Vec2> positions(const Track& track, const std::vector<int>& ids) {
  return track.lane_points(ids);
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

// median distance from each point to its nearest neighbour
double median_neighbour_distance(const std::vector<Vec2>& pts) {
  std::vector<double> nn;
  for (size_t i = 0; i < pts.size(); ++i) {
    double best = std::numeric_limits<double>::infinity();
    for (size_t j = 0; j < pts.size(); ++j)
      if (j != i) best = std::min(best, (pts[i] - pts[j]).norm());
    if (std::isfinite(best)) nn.push_back(best);
  }
  return median(nn);
}

double step_limit(const std::vector<Vec2>& pts) {
  return std::max(kMinStepLimitM, kStepLimitSpacings * median_neighbour_distance(pts));
}

size_t nearest_index(const std::vector<Vec2>& pts, const Vec2& p) {
  size_t best = kNone;
  double best_d2 = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < pts.size(); ++i) {
    const double d2 = (pts[i] - p).squaredNorm();
    if (d2 < best_d2) {
      best_d2 = d2;
      best = i;
    }
  }
  return best;
}

// nearest point to p on the polyline pts (closed: the last point joins the first)
Vec2 nearest_on_polyline(const Vec2& p, const std::vector<Vec2>& pts, bool closed) {
  if (pts.size() == 1) return pts.front();
  Vec2 best = pts.front();
  double best_d2 = std::numeric_limits<double>::infinity();
  const size_t n = pts.size();
  for (size_t i = 0; i < (closed ? n : n - 1); ++i) {
    const Vec2 a = pts[i];
    const Vec2 ab = pts[(i + 1) % n] - a;
    const double len2 = ab.squaredNorm();
    const double t = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
    const Vec2 q = a + t * ab;
    if ((p - q).squaredNorm() < best_d2) {
      best_d2 = (p - q).squaredNorm();
      best = q;
    }
  }
  return best;
}

struct WalkLimits {
  double max_step_m;
  double max_turn_rad;
};

// greedily chains unused points from `from`, preferring short steps that keep the heading
std::vector<size_t> walk(const std::vector<Vec2>& pts, std::vector<bool>& used, Vec2 from, Vec2 dir,
                         const WalkLimits& limits) {
  std::vector<size_t> chain;
  const double min_cos = std::cos(limits.max_turn_rad);
  if (dir.norm() < 1e-12) return chain;
  dir.normalize();
  while (true) {
    // score every reachable candidate ahead
    size_t best = kNone;
    double best_score = std::numeric_limits<double>::infinity();
    for (size_t j = 0; j < pts.size(); ++j) {
      if (used[j]) continue;
      const Vec2 v = pts[j] - from;
      const double d = v.norm();
      if (d < 1e-9 || d > limits.max_step_m) continue;
      const double c = v.dot(dir) / d;
      if (c < min_cos) continue;
      const double score = d * (1.0 + kTurnPenalty * (1.0 - c));
      if (score < best_score) {
        best_score = score;
        best = j;
      }
    }
    if (best == kNone) break;

    // step to it and carry its heading on
    used[best] = true;
    chain.push_back(best);
    dir = (pts[best] - from).normalized();
    from = pts[best];
  }
  return chain;
}

// closure test on positions in lane order
bool closes(const std::vector<Vec2>& pts) {
  if (pts.size() < kMinClosedCones) return false;
  double length = 0.0;
  std::vector<double> steps;
  for (size_t i = 0; i + 1 < pts.size(); ++i) {
    steps.push_back((pts[i + 1] - pts[i]).norm());
    length += steps.back();
  }
  const double gap = (pts.back() - pts.front()).norm();
  if (gap > std::max(kCloseGapM, 1.5 * median(steps))) return false;

  // long enough to be a circuit, or a small ring that turns all the way round (a team's test
  // circle): a short open lane does neither
  double turned = 0.0;
  for (size_t i = 0; i + 2 < pts.size(); ++i) {
    const Vec2 a = pts[i + 1] - pts[i], b = pts[i + 2] - pts[i + 1];
    turned += std::atan2(core::cross(a, b), a.dot(b));
  }
  return length >= kMinClosedLengthM || std::abs(turned) > kMinRingTurnRad;
}

// slots cones the walk stepped over between two chained neighbours when the detour is small;
// a few passes (a slotted cone can make room for another), each linear in the lane length
void insert_skipped(const std::vector<Vec2>& pts, std::vector<bool>& used,
                    std::vector<size_t>& order) {
  for (int pass = 0; pass < kInsertPasses && order.size() >= 2; ++pass) {
    std::vector<Vec2> chain;
    for (size_t k : order) chain.push_back(pts[k]);
    const bool closed = closes(chain);
    bool inserted = false;
    for (size_t i = 0; i < pts.size(); ++i) {
      if (used[i]) continue;
      // the segment whose detour through this cone is shortest
      size_t best_k = kNone;
      double best_detour = kMaxInsertDetourM;
      const size_t segments = closed ? order.size() : order.size() - 1;
      for (size_t k = 0; k < segments; ++k) {
        const Vec2& a = pts[order[k]];
        const Vec2& b = pts[order[(k + 1) % order.size()]];
        const double detour = (a - pts[i]).norm() + (pts[i] - b).norm() - (a - b).norm();
        if (detour < best_detour) {
          best_detour = detour;
          best_k = k;
        }
      }
      if (best_k == kNone) continue;
      order.insert(order.begin() + static_cast<std::ptrdiff_t>(best_k + 1), i);
      used[i] = true;
      inserted = true;
    }
    if (!inserted) break;
  }
}

// extends an open lane at both ends with orange cones that continue its line
void extend_with_orange(const Track& track, std::vector<int>& lane,
                        const std::vector<int>& pool_ids, std::vector<bool>& pool_used) {
  if (lane.size() < 2) return;
  const std::vector<Vec2> pool = positions(track, pool_ids);
  const std::vector<Vec2> lane_pts = positions(track, lane);
  const WalkLimits limits{step_limit(lane_pts), kMaxExtendTurnRad};

  // forward from the last cone
  const size_t n = lane_pts.size();
  for (size_t k : walk(pool, pool_used, lane_pts[n - 1], lane_pts[n - 1] - lane_pts[n - 2], limits))
    lane.push_back(pool_ids[k]);

  // backward from the first cone
  std::vector<int> before;
  for (size_t k : walk(pool, pool_used, lane_pts[0], lane_pts[0] - lane_pts[1], limits))
    before.push_back(pool_ids[k]);
  lane.insert(lane.begin(), before.rbegin(), before.rend());
}

// extends both open lanes with the orange cones of the pool; each cone may continue only the
// lane it stands nearer to, so that a lane walking on through a start gate does not take the
// gate's cone on the other side of the track
void extend_lanes_with_orange(const Track& track, std::vector<int>& left, std::vector<int>& right,
                              const std::vector<int>& pool) {
  std::vector<bool> left_used(pool.size(), false), right_used(pool.size(), false);
  const std::vector<Vec2> left_pts = positions(track, left);
  const std::vector<Vec2> right_pts = positions(track, right);
  if (!left_pts.empty() && !right_pts.empty()) {
    for (size_t k = 0; k < pool.size(); ++k) {
      const Vec2 p = track.cone(pool[k]).position;
      const bool nearer_left = (nearest_on_polyline(p, left_pts, false) - p).norm() <=
                               (nearest_on_polyline(p, right_pts, false) - p).norm();
      (nearer_left ? right_used : left_used)[k] = true;
    }
  }
  extend_with_orange(track, left, pool, left_used);
  extend_with_orange(track, right, pool, right_used);
}

std::vector<int> ids_of(const Track& track, ConeClass cls) {
  std::vector<int> ids;
  for (const Cone& c : track.cones)
    if (c.cls == cls) ids.push_back(c.id);
  return ids;
}

// nearest cone of a class to p, if there is one
std::optional<Vec2> nearest_of(const Track& track, ConeClass cls, const Vec2& p) {
  std::optional<Vec2> best;
  for (const Cone& c : track.cones)
    if (c.cls == cls && (!best || (c.position - p).norm() < (*best - p).norm())) best = c.position;
  return best;
}

// direction of travel of a lane at its cone nearest p (next minus previous cone)
std::optional<Vec2> lane_direction_near(const std::vector<Vec2>& pts, bool closed, const Vec2& p) {
  if (pts.size() < 2) return std::nullopt;
  const size_t i = nearest_index(pts, p);
  const size_t n = pts.size();
  const size_t prev = closed ? (i + n - 1) % n : (i == 0 ? 0 : i - 1);
  const size_t next = closed ? (i + 1) % n : std::min(i + 1, n - 1);
  const Vec2 d = pts[next] - pts[prev];
  if (d.norm() < 1e-9) return std::nullopt;
  return d.normalized();
}

void rotate_to_nearest(std::vector<int>& lane, const std::vector<Vec2>& pts, const Vec2& p) {
  if (lane.empty()) return;
  const size_t i = nearest_index(pts, p);
  std::rotate(lane.begin(), lane.begin() + static_cast<std::ptrdiff_t>(i), lane.end());
}

std::string format_pose(const Pose2& pose) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%.2f, %.2f, yaw %.3f rad)", pose.x, pose.y, pose.yaw);
  return buf;
}

}  // namespace

std::vector<int> order_lane(const Track& track, const std::vector<int>& cone_ids,
                            std::vector<int>* left_out) {
  // distinct ids and their positions
  std::vector<int> ids;
  for (int id : cone_ids)
    if (std::find(ids.begin(), ids.end(), id) == ids.end()) ids.push_back(id);
  if (left_out) left_out->clear();
  if (ids.empty()) return {};
  const std::vector<Vec2> pts = positions(track, ids);

  // walk forward from the cone nearest the start, then backward from it for cones behind
  std::vector<bool> used(pts.size(), false);
  const WalkLimits limits{step_limit(pts), kMaxTurnRad};
  const size_t first = nearest_index(pts, track.start.position());
  used[first] = true;
  const std::vector<size_t> ahead = walk(pts, used, pts[first], track.start.heading(), limits);
  const std::vector<size_t> behind = walk(pts, used, pts[first], -track.start.heading(), limits);
  std::vector<size_t> order(behind.rbegin(), behind.rend());
  order.push_back(first);
  order.insert(order.end(), ahead.begin(), ahead.end());

  // slot in cones the greedy walk stepped over
  insert_skipped(pts, used, order);

  // map back to ids; what is still unused could not be chained
  std::vector<int> lane;
  for (size_t k : order) lane.push_back(ids[k]);
  if (left_out)
    for (size_t i = 0; i < ids.size(); ++i)
      if (!used[i]) left_out->push_back(ids[i]);
  return lane;
}

bool lane_closes(const Track& track, const std::vector<int>& lane) {
  return closes(positions(track, lane));
}

void rebuild_lanes(Track& track) {
  // chain the blue and the yellow cones separately
  std::vector<int> left_out_blue, left_out_yellow;
  std::vector<int> left = order_lane(track, ids_of(track, ConeClass::kBlue), &left_out_blue);
  std::vector<int> right = order_lane(track, ids_of(track, ConeClass::kYellow), &left_out_yellow);
  if (!left_out_blue.empty())
    track.warnings.push_back(std::to_string(left_out_blue.size()) +
                             " blue cone(s) could not be chained into the left lane");
  if (!left_out_yellow.empty())
    track.warnings.push_back(std::to_string(left_out_yellow.size()) +
                             " yellow cone(s) could not be chained into the right lane");

  // a circuit when both lanes close; open lanes continue through orange cones in line, and
  // lanes whose ends those orange cones join are a circuit too (big orange cones standing in the
  // boundary lines at the start/finish leave a gap of two cone spacings in the coloured lanes)
  auto both_close = [&] {
    return !left.empty() && !right.empty() && lane_closes(track, left) && lane_closes(track, right);
  };
  track.closed = both_close();
  if (!track.closed) {
    std::vector<int> pool = ids_of(track, ConeClass::kOrangeSmall);
    const std::vector<int> big = ids_of(track, ConeClass::kOrangeBig);
    pool.insert(pool.end(), big.begin(), big.end());
    extend_lanes_with_orange(track, left, right, pool);
    track.closed = both_close();
  }
  track.left_lane = std::move(left);
  track.right_lane = std::move(right);

  // blue on the left of travel, closed lanes beginning at the start
  orient_lanes(track);
}

void orient_lanes(Track& track) {
  // vote: on which side of the direction of travel does the left lane lie?
  const std::vector<Vec2> left = track.lane_points(track.left_lane);
  const std::vector<Vec2> right = track.lane_points(track.right_lane);
  if (left.size() >= 2 && !right.empty()) {
    int votes = 0;
    const size_t n = left.size();
    for (size_t i = 0; i < n; ++i) {
      const size_t prev = track.closed ? (i + n - 1) % n : (i == 0 ? 0 : i - 1);
      const size_t next = track.closed ? (i + 1) % n : std::min(i + 1, n - 1);
      const Vec2 dir = left[next] - left[prev];
      const double side =
          core::cross(dir, left[i] - nearest_on_polyline(left[i], right, track.closed));
      votes += side > 0.0 ? 1 : (side < 0.0 ? -1 : 0);
    }
    if (votes < 0) {
      std::reverse(track.left_lane.begin(), track.left_lane.end());
      std::reverse(track.right_lane.begin(), track.right_lane.end());
      track.warnings.push_back("lanes reversed so that the left lane is on the left of travel");
    }
  }

  // closed lanes begin at the cone nearest the start pose
  if (track.closed) {
    rotate_to_nearest(track.left_lane, track.lane_points(track.left_lane), track.start.position());
    rotate_to_nearest(track.right_lane, track.lane_points(track.right_lane),
                      track.start.position());
  }
}

Vec2 left_direction_at(const Track& track, const Vec2& p) {
  // from the nearest point of the right lane to the nearest point of the left lane (points
  // of the polylines, not cones: across a gap such as the start/finish gate the nearest cones
  // may stand round the corner on either side)
  const std::vector<Vec2> left = track.lane_points(track.left_lane);
  const std::vector<Vec2> right = track.lane_points(track.right_lane);
  if (!left.empty() && !right.empty()) {
    const Vec2 d =
        nearest_on_polyline(p, left, track.closed) - nearest_on_polyline(p, right, track.closed);
    if (d.norm() > 1e-9) return d.normalized();
  }

  // else from the nearest yellow cone to the nearest blue one
  const std::optional<Vec2> blue = nearest_of(track, ConeClass::kBlue, p);
  const std::optional<Vec2> yellow = nearest_of(track, ConeClass::kYellow, p);
  if (blue && yellow && (*blue - *yellow).norm() > 1e-9) return (*blue - *yellow).normalized();

  // else the start pose's left
  return {-std::sin(track.start.yaw), std::cos(track.start.yaw)};
}

void extend_open_lanes_with_orange(Track& track) {
  if (track.closed) return;
  // the pool: orange cones that neither lane holds yet
  std::vector<int> pool;
  for (const Cone& c : track.cones) {
    if (c.cls != ConeClass::kOrangeSmall) continue;
    const auto in = [&c](const std::vector<int>& lane) {
      return std::find(lane.begin(), lane.end(), c.id) != lane.end();
    };
    if (!in(track.left_lane) && !in(track.right_lane)) pool.push_back(c.id);
  }
  extend_lanes_with_orange(track, track.left_lane, track.right_lane, pool);
}

std::vector<Gate> gates_from_big_orange(const Track& track) {
  // group the big orange cones: connected when closer than kGateGroupRadiusM
  const std::vector<int> ids = ids_of(track, ConeClass::kOrangeBig);
  const std::vector<Vec2> pts = positions(track, ids);
  std::vector<int> group(pts.size(), -1);
  int groups = 0;
  for (size_t seed = 0; seed < pts.size(); ++seed) {
    if (group[seed] >= 0) continue;
    std::vector<size_t> stack{seed};
    group[seed] = groups;
    while (!stack.empty()) {
      const size_t i = stack.back();
      stack.pop_back();
      for (size_t j = 0; j < pts.size(); ++j)
        if (group[j] < 0 && (pts[i] - pts[j]).norm() < kGateGroupRadiusM) {
          group[j] = groups;
          stack.push_back(j);
        }
    }
    ++groups;
  }

  // split each group into its left and right side and join their middles
  std::vector<Gate> gates;
  for (int g = 0; g < groups; ++g) {
    Vec2 centre = Vec2::Zero();
    int n = 0;
    for (size_t i = 0; i < pts.size(); ++i) {
      if (group[i] != g) continue;
      centre += pts[i];
      ++n;
    }
    centre /= n;
    const Vec2 across = left_direction_at(track, centre);
    Vec2 left_sum = Vec2::Zero(), right_sum = Vec2::Zero();
    int n_left = 0, n_right = 0;
    for (size_t i = 0; i < pts.size(); ++i) {
      if (group[i] != g) continue;
      if ((pts[i] - centre).dot(across) > 0.0) {
        left_sum += pts[i];
        ++n_left;
      } else {
        right_sum += pts[i];
        ++n_right;
      }
    }
    if (n_left > 0 && n_right > 0) gates.push_back({left_sum / n_left, right_sum / n_right});
  }
  return gates;
}

void guess_start_pose(Track& track) {
  // position: the start gate, else the centre line, the lanes or the cones
  Vec2 position = Vec2::Zero();
  std::string from;
  const std::vector<Gate> big_orange =
      track.timing_gates.empty() ? gates_from_big_orange(track) : std::vector<Gate>{};
  if (!track.timing_gates.empty()) {
    position = 0.5 * (track.timing_gates.front().left + track.timing_gates.front().right);
    from = "the first timing gate";
  } else if (!big_orange.empty()) {
    position = 0.5 * (big_orange.front().left + big_orange.front().right);
    from = "the big orange gate";
  } else if (!track.centre_line.empty()) {
    position = track.centre_line.front();
    from = "the centre line";
  } else if (!track.left_lane.empty() && !track.right_lane.empty()) {
    position = 0.5 * (track.cone(track.left_lane.front()).position +
                      track.cone(track.right_lane.front()).position);
    from = "the first lane cones";
  } else if (!track.cones.empty()) {
    for (const Cone& c : track.cones) position += c.position;
    position /= static_cast<double>(track.cones.size());
    from = "the middle of the cones";
  } else {
    from = "nothing (no cones)";
  }

  // heading: along the centre line or the lanes, else across the nearest blue/yellow pair
  Vec2 heading = rotate_right(left_direction_at(track, position));
  if (track.centre_line.size() >= 2) {
    const std::optional<Vec2> d = lane_direction_near(track.centre_line, track.closed, position);
    if (d) heading = *d;
  } else if (const std::optional<Vec2> d =
                 lane_direction_near(track.lane_points(track.left_lane), track.closed, position)) {
    heading = *d;
  }

  track.start = {position.x(), position.y(), std::atan2(heading.y(), heading.x())};
  track.warnings.push_back("no start pose given: guessed " + format_pose(track.start) + " from " +
                           from);
}

}  // namespace conesim::tracks
