#include "tracks/lanes.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <optional>
#include <string>
#include <unordered_set>
#include <utility>

#include "tracks/spatial_index.hpp"

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
  const PointIndex index(pts);
  for (size_t i = 0; i < pts.size(); ++i) {
    const size_t j = index.nearest(pts[i], [i](size_t k) { return k != i; });
    if (j != PointIndex::kNone) nn.push_back((pts[i] - pts[j]).norm());
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

// nearest point to p on the indexed polyline
Vec2 nearest_on(const PolylineIndex& index, const Vec2& p) {
  return index.nearest(p).point;
}

struct WalkLimits {
  double max_step_m;
  double max_turn_rad;
};

// greedily chains unused points from `from`, preferring short steps that keep the heading
std::vector<size_t> walk(const std::vector<Vec2>& pts, const PointIndex& index,
                         std::vector<bool>& used, Vec2 from, Vec2 dir, const WalkLimits& limits) {
  std::vector<size_t> chain;
  const double min_cos = std::cos(limits.max_turn_rad);
  if (dir.norm() < 1e-12) return chain;
  dir.normalize();
  while (true) {
    // score every reachable candidate ahead (the index gives those within a step, in order)
    size_t best = kNone;
    double best_score = std::numeric_limits<double>::infinity();
    for (size_t j : index.within(from, limits.max_step_m * (1.0 + 1e-9))) {
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
// a few passes (a slotted cone can make room for another). The chain is a linked list over
// the points, and a cone is tried only against the segments starting near it (a detour under
// kMaxInsertDetourM needs the segment's start within its length plus that of the cone), so a
// pass costs what is near each skipped cone
void insert_skipped(const std::vector<Vec2>& pts, const PointIndex& index, std::vector<bool>& used,
                    std::vector<size_t>& order) {
  for (int pass = 0; pass < kInsertPasses && order.size() >= 2; ++pass) {
    std::vector<Vec2> chain;
    for (size_t k : order) chain.push_back(pts[k]);
    const bool closed = closes(chain);

    // the chain as links with a rank for its order (a slotted cone ranks between its
    // neighbours), and the longest segment
    std::vector<size_t> next(pts.size(), kNone);
    std::vector<double> rank(pts.size(), 0.0);
    double longest_m = 0.0;
    for (size_t k = 0; k < order.size(); ++k) {
      rank[order[k]] = static_cast<double>(k);
      const bool has_next = k + 1 < order.size() || closed;
      if (!has_next) continue;
      next[order[k]] = order[(k + 1) % order.size()];
      longest_m = std::max(longest_m, (pts[next[order[k]]] - pts[order[k]]).norm());
    }
    size_t last = order.back();
    std::vector<bool> chained(pts.size(), false);
    for (size_t k : order) chained[k] = true;

    bool inserted = false;
    for (size_t i = 0; i < pts.size(); ++i) {
      if (used[i]) continue;
      // the segment whose detour through this cone is shortest (ties: the earliest in order)
      size_t best_a = kNone;
      double best_detour = kMaxInsertDetourM;
      double best_rank = 0.0;
      for (size_t a : index.within(pts[i], longest_m + kMaxInsertDetourM + 1e-6)) {
        if (!chained[a] || next[a] == kNone) continue;
        const size_t b = next[a];
        const double detour =
            (pts[a] - pts[i]).norm() + (pts[i] - pts[b]).norm() - (pts[a] - pts[b]).norm();
        if (detour < best_detour ||
            (detour == best_detour && best_a != kNone && rank[a] < best_rank)) {
          best_detour = detour;
          best_a = a;
          best_rank = rank[a];
        }
      }
      if (best_a == kNone) continue;
      const size_t b = next[best_a];
      // the closing segment (last to first) puts the cone at the end
      const bool at_end = best_a == last;
      rank[i] = at_end ? rank[best_a] + 1.0 : 0.5 * (rank[best_a] + rank[b]);
      if (at_end) last = i;
      longest_m = std::max({longest_m, (pts[i] - pts[best_a]).norm(), (pts[b] - pts[i]).norm()});
      next[i] = b;
      next[best_a] = i;
      chained[i] = true;
      used[i] = true;
      inserted = true;
    }
    if (!inserted) break;

    // back to an order: from the first cone along the links
    std::vector<size_t> walked{order.front()};
    for (size_t k = next[order.front()]; k != kNone && k != order.front(); k = next[k])
      walked.push_back(k);
    order = std::move(walked);
  }
}

// extends an open lane at both ends with orange cones that continue its line
void extend_with_orange(const Track& track, std::vector<int>& lane,
                        const std::vector<int>& pool_ids, std::vector<bool>& pool_used) {
  if (lane.size() < 2) return;
  const std::vector<Vec2> pool = positions(track, pool_ids);
  const std::vector<Vec2> lane_pts = positions(track, lane);
  const WalkLimits limits{step_limit(lane_pts), kMaxExtendTurnRad};
  const PointIndex index(pool);

  // forward from the last cone
  const size_t n = lane_pts.size();
  for (size_t k :
       walk(pool, index, pool_used, lane_pts[n - 1], lane_pts[n - 1] - lane_pts[n - 2], limits))
    lane.push_back(pool_ids[k]);

  // backward from the first cone
  std::vector<int> before;
  for (size_t k : walk(pool, index, pool_used, lane_pts[0], lane_pts[0] - lane_pts[1], limits))
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
    const PolylineIndex left_index(left_pts, false), right_index(right_pts, false);
    for (size_t k = 0; k < pool.size(); ++k) {
      const Vec2 p = track.cone(pool[k]).position;
      const bool nearer_left =
          (nearest_on(left_index, p) - p).norm() <= (nearest_on(right_index, p) - p).norm();
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
  std::unordered_set<int> distinct;
  for (int id : cone_ids)
    if (distinct.insert(id).second) ids.push_back(id);
  if (left_out) left_out->clear();
  if (ids.empty()) return {};
  const std::vector<Vec2> pts = positions(track, ids);

  // walk forward from the cone nearest the start, then backward from it for cones behind
  std::vector<bool> used(pts.size(), false);
  const WalkLimits limits{step_limit(pts), kMaxTurnRad};
  const PointIndex index(pts);
  const size_t first = nearest_index(pts, track.start.position());
  used[first] = true;
  const std::vector<size_t> ahead =
      walk(pts, index, used, pts[first], track.start.heading(), limits);
  const std::vector<size_t> behind =
      walk(pts, index, used, pts[first], -track.start.heading(), limits);
  std::vector<size_t> order(behind.rbegin(), behind.rend());
  order.push_back(first);
  order.insert(order.end(), ahead.begin(), ahead.end());

  // slot in cones the greedy walk stepped over
  insert_skipped(pts, index, used, order);

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
    const PolylineIndex right_index(right, track.closed);
    int votes = 0;
    const size_t n = left.size();
    for (size_t i = 0; i < n; ++i) {
      const size_t prev = track.closed ? (i + n - 1) % n : (i == 0 ? 0 : i - 1);
      const size_t next = track.closed ? (i + 1) % n : std::min(i + 1, n - 1);
      const Vec2 dir = left[next] - left[prev];
      const double side = core::cross(dir, left[i] - nearest_on(right_index, left[i]));
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

namespace {

// what left_direction_at looks at, indexed once for many places
class AcrossTrack {
 public:
  explicit AcrossTrack(const Track& track)
      : track_(track),
        left_(track.lane_points(track.left_lane)),
        right_(track.lane_points(track.right_lane)),
        left_index_(left_, track.closed),
        right_index_(right_, track.closed) {
    for (const Cone& c : track.cones) {
      if (c.cls == ConeClass::kBlue) blue_.push_back(c.position);
      if (c.cls == ConeClass::kYellow) yellow_.push_back(c.position);
    }
  }

  Vec2 left_direction_at(const Vec2& p) const {
    // from the nearest point of the right lane to the nearest point of the left lane (points
    // of the polylines, not cones: across a gap such as the start/finish gate the nearest
    // cones may stand round the corner on either side)
    if (!left_.empty() && !right_.empty()) {
      const Vec2 d = nearest_on(left_index_, p) - nearest_on(right_index_, p);
      if (d.norm() > 1e-9) return d.normalized();
    }

    // else from the nearest yellow cone to the nearest blue one
    const std::optional<Vec2> blue = nearest(blue_, blue_index_, p);
    const std::optional<Vec2> yellow = nearest(yellow_, yellow_index_, p);
    if (blue && yellow && (*blue - *yellow).norm() > 1e-9) return (*blue - *yellow).normalized();

    // else the start pose's left
    return {-std::sin(track_.start.yaw), std::cos(track_.start.yaw)};
  }

 private:
  static std::optional<Vec2> nearest(const std::vector<Vec2>& pts, std::optional<PointIndex>& index,
                                     const Vec2& p) {
    if (pts.empty()) return std::nullopt;
    if (!index) index.emplace(pts);
    return pts[index->nearest(p, [](size_t) { return true; })];
  }

  const Track& track_;
  std::vector<Vec2> left_, right_, blue_, yellow_;
  PolylineIndex left_index_, right_index_;
  mutable std::optional<PointIndex> blue_index_, yellow_index_;
};

}  // namespace

Vec2 left_direction_at(const Track& track, const Vec2& p) {
  return AcrossTrack(track).left_direction_at(p);
}

std::vector<Vec2> left_directions_at(const Track& track, const std::vector<Vec2>& places) {
  const AcrossTrack across(track);
  std::vector<Vec2> out;
  out.reserve(places.size());
  for (const Vec2& p : places) out.push_back(across.left_direction_at(p));
  return out;
}

void extend_open_lanes_with_orange(Track& track) {
  if (track.closed) return;
  // the pool: orange cones that neither lane holds yet
  std::vector<int> pool;
  std::unordered_set<int> in_lanes(track.left_lane.begin(), track.left_lane.end());
  in_lanes.insert(track.right_lane.begin(), track.right_lane.end());
  for (const Cone& c : track.cones)
    if (c.cls == ConeClass::kOrangeSmall && in_lanes.count(c.id) == 0) pool.push_back(c.id);
  extend_lanes_with_orange(track, track.left_lane, track.right_lane, pool);
}

std::vector<Gate> gates_from_big_orange(const Track& track) {
  // group the big orange cones: connected when closer than kGateGroupRadiusM
  const std::vector<int> ids = ids_of(track, ConeClass::kOrangeBig);
  const std::vector<Vec2> pts = positions(track, ids);
  std::vector<int> group(pts.size(), -1);
  int groups = 0;
  const PointIndex index(pts);
  for (size_t seed = 0; seed < pts.size(); ++seed) {
    if (group[seed] >= 0) continue;
    std::vector<size_t> stack{seed};
    group[seed] = groups;
    while (!stack.empty()) {
      const size_t i = stack.back();
      stack.pop_back();
      for (size_t j : index.within(pts[i], kGateGroupRadiusM))
        if (group[j] < 0 && (pts[i] - pts[j]).norm() < kGateGroupRadiusM) {
          group[j] = groups;
          stack.push_back(j);
        }
    }
    ++groups;
  }

  // split each group into its left and right side and join their middles
  std::vector<Gate> gates;
  std::vector<std::vector<size_t>> members(static_cast<size_t>(groups));
  for (size_t i = 0; i < pts.size(); ++i) members[static_cast<size_t>(group[i])].push_back(i);
  const AcrossTrack across_track(track);
  for (int g = 0; g < groups; ++g) {
    Vec2 centre = Vec2::Zero();
    int n = 0;
    for (size_t i : members[static_cast<size_t>(g)]) {
      centre += pts[i];
      ++n;
    }
    centre /= n;
    const Vec2 across = across_track.left_direction_at(centre);
    Vec2 left_sum = Vec2::Zero(), right_sum = Vec2::Zero();
    int n_left = 0, n_right = 0;
    for (size_t i : members[static_cast<size_t>(g)]) {
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
