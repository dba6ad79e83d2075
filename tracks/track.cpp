#include "tracks/track.hpp"

#include <algorithm>
#include <array>
#include <limits>
#include <stdexcept>
#include <utility>

#include "tracks/spatial_index.hpp"

namespace conesim::tracks {

namespace {

// length along the points (closed: with the segment back to the first)
double polyline_length(const std::vector<Vec2>& pts, bool closed) {
  double length = 0.0;
  for (size_t i = 0; i + 1 < pts.size(); ++i) length += (pts[i + 1] - pts[i]).norm();
  if (closed && pts.size() > 1) length += (pts.front() - pts.back()).norm();
  return length;
}

// points every spacing_m along the polyline (closed: around the loop, without repeating start)
std::vector<Vec2> resample(const std::vector<Vec2>& pts, bool closed, double spacing_m) {
  std::vector<Vec2> path = pts;
  if (closed && pts.size() > 1) path.push_back(pts.front());
  std::vector<Vec2> out;
  if (path.empty()) return out;
  out.push_back(path.front());
  double carry = 0.0;  // distance travelled since the last output point
  for (size_t i = 0; i + 1 < path.size(); ++i) {
    const Vec2 a = path[i];
    const Vec2 d = path[i + 1] - a;
    const double len = d.norm();
    if (len <= 0.0) continue;
    double s = spacing_m - carry;
    while (s <= len + 1e-12) {
      out.push_back(a + d * (s / len));
      s += spacing_m;
    }
    carry = len - (s - spacing_m);
  }
  if (closed) {
    // drop a last point that nearly coincides with the start
    if (out.size() > 2 && (out.back() - out.front()).norm() < 0.5 * spacing_m) out.pop_back();
  } else if ((out.back() - path.back()).norm() > 1e-6) {
    out.push_back(path.back());
  }
  return out;
}

}  // namespace

const Cone& Track::cone(int id) const {
  // the ids are the places in `cones` (the readers' and the generator's tracks)
  if (id >= 0 && static_cast<size_t>(id) < cones.size() && cones[static_cast<size_t>(id)].id == id)
    return cones[static_cast<size_t>(id)];
  for (const Cone& c : cones)
    if (c.id == id) return c;
  throw std::out_of_range("track " + name + " has no cone with id " + std::to_string(id));
}

uint64_t Track::file_id(int id) const {
  const auto it = file_ids.find(id);
  return it != file_ids.end() ? it->second : static_cast<uint64_t>(id);
}

std::vector<Vec2> Track::lane_points(const std::vector<int>& lane) const {
  std::vector<Vec2> pts;
  pts.reserve(lane.size());
  for (int id : lane) pts.push_back(cone(id).position);
  return pts;
}

int Track::count(ConeClass c) const {
  return static_cast<int>(
      std::count_if(cones.begin(), cones.end(), [c](const Cone& k) { return k.cls == c; }));
}

int Track::next_id() const {
  int next = 0;
  for (const Cone& c : cones) next = std::max(next, c.id + 1);
  return next;
}

std::vector<Vec2> derive_centre_line(const Track& track, double spacing_m) {
  const std::vector<Vec2> left = track.lane_points(track.left_lane);
  const std::vector<Vec2> right = track.lane_points(track.right_lane);
  if (left.empty() || right.empty()) return {};
  if (polyline_length(left, track.closed) > kMaxCentreLineM) return {};

  // sample the left boundary densely and pair each sample with the nearest right-boundary point
  const std::vector<Vec2> left_dense = resample(left, track.closed, 0.5);
  const PolylineIndex right_index(right, track.closed);
  std::vector<Vec2> mid;
  mid.reserve(left_dense.size());
  for (const Vec2& p : left_dense) mid.push_back(0.5 * (p + right_index.nearest(p).point));

  // open layouts: extend to the ends of the right lane too, so the line spans both lanes
  if (!track.closed) {
    const PolylineIndex left_index(left, false);
    const Vec2 first = 0.5 * (right.front() + left_index.nearest(right.front()).point);
    const Vec2 last = 0.5 * (right.back() + left_index.nearest(right.back()).point);
    const Vec2 dir = mid.size() > 1 ? Vec2(mid.back() - mid.front()) : Vec2(1.0, 0.0);
    if ((first - mid.front()).dot(dir) < 0.0) mid.insert(mid.begin(), first);
    if ((last - mid.back()).dot(dir) > 0.0) mid.push_back(last);
  }

  // smooth the bunching of the inner side of tight turns, then resample evenly
  if (mid.size() >= 5) {
    std::vector<Vec2> smooth = mid;
    const size_t n = mid.size();
    for (size_t i = 0; i < n; ++i) {
      if (!track.closed && (i < 2 || i + 2 >= n)) continue;
      Vec2 sum = Vec2::Zero();
      for (int k = -2; k <= 2; ++k) sum += mid[(i + n + k) % n];
      smooth[i] = sum / 5.0;
    }
    mid = std::move(smooth);
  }
  if (polyline_length(mid, track.closed) > kMaxCentreLineM) return {};
  return resample(mid, track.closed, spacing_m);
}

}  // namespace conesim::tracks
