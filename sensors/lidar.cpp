#include "sensors/lidar.hpp"

#include <embree3/rtcore.h>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <unordered_map>

#include "sensors/scenery_mesh.hpp"

namespace conesim::sensors {

namespace {

constexpr int kClassCount = 5;
// the ground quad reaches this far beyond the cones and the start, on top of the max range
constexpr double kGroundMarginM = 20.0;
// rays are cut this far above the tallest cone
constexpr double kTopSlackM = 0.01;
// columns whose nearby cones are sought together (about 6 degrees of a VLP-16 sweep)
constexpr int kChunkColumns = 32;
// a cone's footprint is widened by this before a ray is judged to pass clear of it: far more
// than the rounding of the single-precision tests, far less than the gap between cones
constexpr float kFootprintSlackM = 0.01f;

// one part of a beam's spot: where it ended, what it met and the energy it brings back (the
// intensity before noise; 0 when it met nothing)
struct Echo {
  float range = 0.f;
  int label = 0;
  float energy = 0.f;
};

// the return of a beam whose spot is cast as three equal parts: parts whose ranges lie closer
// than merge_m form one echo at their energy-weighted range, labelled by its strongest part; the
// strongest echo is the return, with a third of each part's energy. False when nothing came back.
bool strongest_echo(std::array<Echo, 3> parts, float merge_m, Echo& out) {
  std::sort(parts.begin(), parts.end(),
            [](const Echo& a, const Echo& b) { return a.range < b.range; });
  bool found = false;
  out.energy = 0.f;
  for (size_t i = 0; i < parts.size();) {
    if (!(parts[i].energy > 0.f)) {
      ++i;
      continue;
    }
    // the echo that starts at part i
    float energy = 0.f, weighted = 0.f, strongest = 0.f, last = parts[i].range;
    int label = parts[i].label;
    size_t j = i;
    for (; j < parts.size() && (!(parts[j].energy > 0.f) || parts[j].range - last < merge_m); ++j) {
      if (!(parts[j].energy > 0.f)) continue;
      energy += parts[j].energy;
      weighted += parts[j].energy * parts[j].range;
      last = parts[j].range;
      if (parts[j].energy > strongest) {
        strongest = parts[j].energy;
        label = parts[j].label;
      }
    }
    if (energy / 3.f > out.energy) {
      out = {weighted / energy, label, energy / 3.f};
      found = true;
    }
    i = j;
  }
  return found;
}

int class_index(core::ConeClass c) {
  return static_cast<int>(c);
}

// fills a new triangle geometry with vertices and indices and commits it
RTCGeometry make_triangle_geometry(RTCDevice device, const std::vector<Eigen::Vector3f>& vertices,
                                   const std::vector<std::array<uint32_t, 3>>& triangles) {
  RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(
      geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), vertices.size()));
  for (size_t i = 0; i < vertices.size(); ++i) {
    v[3 * i + 0] = vertices[i].x();
    v[3 * i + 1] = vertices[i].y();
    v[3 * i + 2] = vertices[i].z();
  }
  auto* idx = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(
      geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t), triangles.size()));
  for (size_t i = 0; i < triangles.size(); ++i)
    std::copy(triangles[i].begin(), triangles[i].end(), idx + 3 * i);
  rtcCommitGeometry(geom);
  return geom;
}

// what the ray loops need of the scene: the max range, the height of the tallest cone, the ground
// rectangle and the ground's intensity before the incidence and the range fall-off
struct RayBounds {
  float max_range = 0.f, top_z = 0.f;
  // the plane below which there is no ground (z = 0 for the flat ground)
  float floor_z = 0.f;
  float lo_x = 0.f, lo_y = 0.f, hi_x = 0.f, hi_y = 0.f;
  float falloff = 0.f, ground_scale = 0.f;
};

// the label of a ray that meets nothing
constexpr int kNoReturn = std::numeric_limits<int>::min();
// how far past the ground a ray that meets it runs (besides 1e-4 of its range)
constexpr float kGroundSlackM = 1e-3f;

// count rays from origin, one per channel: their directions, how far each can find anything, and
// where each meets the ground plane (kNoReturn where it does not). One branch-free pass over
// arrays that do not overlap, so that the compiler casts several rays at a time
void cast_rays(int count, const float* __restrict cos_elevation,
               const float* __restrict sin_elevation, const Eigen::Vector3f& origin,
               const Eigen::Vector3f& heading, const Eigen::Vector3f& up, const RayBounds& bounds,
               float* __restrict dir_x, float* __restrict dir_y, float* __restrict dir_z,
               float* __restrict length, float* __restrict range, float* __restrict intensity,
               int* __restrict label) {
  const float ox = origin.x(), oy = origin.y(), oz = origin.z();
  const float hx = heading.x(), hy = heading.y(), hz = heading.z();
  const float ux = up.x(), uy = up.y(), uz = up.z();
  const float max_range = bounds.max_range, top_z = bounds.top_z, floor_z = bounds.floor_z;
  const float lo_x = bounds.lo_x, lo_y = bounds.lo_y, hi_x = bounds.hi_x, hi_y = bounds.hi_y;
  const float falloff = bounds.falloff, ground_scale = bounds.ground_scale;
  const bool above_all = oz >= top_z;
  for (int ch = 0; ch < count; ++ch) {
    // the beam's direction: its elevation between the heading and the up axis
    const float dx = cos_elevation[ch] * hx + sin_elevation[ch] * ux;
    const float dy = cos_elevation[ch] * hy + sin_elevation[ch] * uy;
    const float dz = cos_elevation[ch] * hz + sin_elevation[ch] * uz;
    dir_x[ch] = dx;
    dir_y[ch] = dy;
    dir_z[ch] = dz;

    // how far it can find anything: down to just past the ground plane (the floor under a
    // ground that is not flat), or up to where it climbs above the tallest cone (0 when it
    // starts above everything and does not descend)
    const float t = (floor_z - oz) / dz;
    const float down = t * 1.0001f + kGroundSlackM;
    const float climb = (top_z - oz) / dz;
    const float rising = climb < max_range ? climb : max_range;
    const float falling = down < max_range ? down : max_range;
    const float level = above_all ? 0.f : (dz > 0.f ? rising : max_range);
    length[ch] = dz < 0.f ? falling : level;

    // the ground plane, if the ray crosses it ahead within the max range and over the ground
    // rectangle, with the intensity of the ground there
    const float x = ox + t * dx, y = oy + t * dy;
    const bool hit =
        (t >= 0.f) & (t <= max_range) & (x >= lo_x) & (x <= hi_x) & (y >= lo_y) & (y <= hi_y);
    label[ch] = hit ? core::PointCloudLabels::kGroundLabel : kNoReturn;
    range[ch] = t;
    intensity[ch] = ground_scale * std::abs(dz) / (1.f + t * t * falloff);
  }
}

// for count rays from one origin at height oz, whether each passes far from a cone: its track on
// the ground, up to its length, passes farther than radius from the point (cx, cy) relative to
// the origin, or the ray stays above the cone's top over the whole stretch where it does not (a
// lower bound of its height there: at the track's nearest point, less its drop over twice the
// radius; drop[ch] is the ray's fall per metre across the ground). The first test of whether a
// ray passes near a cone, for a column's rays at once; most rays over a low object (a grass
// strip, a lying cone) pass here.
void far_from(int count, float cx, float cy, float radius, float oz, float top,
              const float* __restrict dir_x, const float* __restrict dir_y,
              const float* __restrict dir_z, const float* __restrict drop,
              const float* __restrict length, int* __restrict far) {
  // (a tenth of a millimetre for single precision's rounding)
  const float reach_down = 2.f * radius, above = top + 1e-4f;
  for (int ch = 0; ch < count; ++ch) {
    const float dx = dir_x[ch], dy = dir_y[ch];
    const float squared = dx * dx + dy * dy;
    const float closest = (cx * dx + cy * dy) / squared;
    const float t = std::min(std::max(closest, 0.f), length[ch]);
    const float ex = cx - t * dx, ey = cy - t * dy;
    far[ch] = (ex * ex + ey * ey > radius * radius) |
              (oz + dir_z[ch] * t - reach_down * drop[ch] > above);
  }
}

// draws normal samples from the block the sampler has ready, so that a hot loop keeps its place
// in registers instead of the sampler's memory (which the loop's stores might alias); the same
// samples in the same order as drawing them one by one, once finish() has handed back the count
class NormalDraws {
 public:
  explicit NormalDraws(core::ZigguratNormals& normal) : normal_(normal) {}

  // the next sample
  float operator()() {
    if (drawn_ == ready_) [[unlikely]] {
      normal_.take(drawn_);
      samples_ = normal_.ready(ready_);
      drawn_ = 0;
    }
    return samples_[drawn_++];
  }

  // the sampler takes the samples drawn
  void finish() {
    normal_.take(drawn_);
    drawn_ = ready_ = 0;
  }

 private:
  core::ZigguratNormals& normal_;
  const float* samples_ = nullptr;
  int ready_ = 0, drawn_ = 0;
};

// A horizontal fan of rays, as seen from above: every ray starts within `spread` of the origin,
// runs at most `reach` and heads within the angle atan(tan_half_angle) of the unit axis
// (wide: any heading). may_meet() is conservative: false only when no ray comes within r of c.
struct Fan {
  float origin_x = 0.f, origin_y = 0.f;
  float axis_x = 1.f, axis_y = 0.f;
  float reach = 0.f;
  float spread = 0.f;
  float tan_half_angle = 0.f;
  bool wide = false;

  bool may_meet(float cx, float cy, float r) const {
    // the disk widened by the spread of the origins, against a sector from the mean origin
    const float wx = cx - origin_x, wy = cy - origin_y;
    const float rr = r + spread;
    if (wide) return wx * wx + wy * wy <= (reach + rr) * (reach + rr);
    // along the axis the sector covers [0, reach]; across it, |across| <= along tan(half)
    const float along = wx * axis_x + wy * axis_y;
    if (along < -rr || along > reach + rr) return false;
    const float across = std::abs(wx * axis_y - wy * axis_x);
    return across <= rr + (along + rr) * tan_half_angle;
  }
};

// a cone a column's rays may pass near: its centre from the column's origin, the radius of its
// footprint with the slack, and its top
struct NearCone {
  float x, y, radius, top_m;
  // index into the cones of the scene
  int index;
  // how far the footprint was widened beyond the mesh's own (the slack and half the spot)
  float widening;
};

// A scenery object's outline seen from above, a rectangle about its heading that holds every
// vertex of its mesh: far tighter than the disk of its footprint for a long, thin object (a grass
// edge's 4 m x 1 m strip covers 4 m^2, its disk 13 m^2), so that the rays over the disk but
// beside the object are not traced through its mesh.
struct Outline {
  bool used = false;
  // its centre from the object's place, its axes (u along the heading, w across) and half sizes
  float cx = 0.f, cy = 0.f, ux = 1.f, uy = 0.f, half_u = 0.f, half_w = 0.f;

  // narrows [enter, leave] of a ray's track t (dx, dy) from the sensor, the object's place at
  // (px, py) from the sensor, to the stretch over the outline widened by `widening`; false when
  // none is left
  bool narrow(float px, float py, float dx, float dy, float widening, float& enter,
              float& leave) const {
    const float rx = px + cx, ry = py + cy;
    const auto slab = [&](float ax, float ay, float half) {
      const float rate = dx * ax + dy * ay, at = rx * ax + ry * ay;
      const float h = half + widening;
      if (rate == 0.f) return std::abs(at) <= h;
      const float t0 = (at - h) / rate, t1 = (at + h) / rate;
      enter = std::max(enter, std::min(t0, t1));
      leave = std::min(leave, std::max(t0, t1));
      return enter <= leave;
    };
    return slab(ux, uy, half_u) && slab(-uy, ux, half_w);
  }
};

// the outline of a scenery object's mesh (its vertices about the object's place) about its
// heading (a tenth of a millimetre more each way for single precision's rounding)
Outline outline_of(const SceneryMesh& mesh, float yaw) {
  Outline o;
  if (mesh.vertices.empty()) return o;
  o.used = true;
  o.ux = std::cos(yaw);
  o.uy = std::sin(yaw);
  constexpr float inf = std::numeric_limits<float>::infinity();
  float lo_u = inf, hi_u = -inf, lo_w = inf, hi_w = -inf;
  for (const Eigen::Vector3f& v : mesh.vertices) {
    const float u = v.x() * o.ux + v.y() * o.uy, w = v.y() * o.ux - v.x() * o.uy;
    lo_u = std::min(lo_u, u);
    hi_u = std::max(hi_u, u);
    lo_w = std::min(lo_w, w);
    hi_w = std::max(hi_w, w);
  }
  constexpr float kRoundingM = 1e-4f;
  o.half_u = 0.5f * (hi_u - lo_u) + kRoundingM;
  o.half_w = 0.5f * (hi_w - lo_w) + kRoundingM;
  const float mid_u = 0.5f * (lo_u + hi_u), mid_w = 0.5f * (lo_w + hi_w);
  o.cx = mid_u * o.ux - mid_w * o.uy;
  o.cy = mid_u * o.uy + mid_w * o.ux;
  return o;
}

// tangent of the angle between a horizontal direction and a unit axis (wide past 60 degrees)
bool tan_angle_to(float dx, float dy, float axis_x, float axis_y, float& tan_angle) {
  const float along = dx * axis_x + dy * axis_y;
  const float across = std::abs(dx * axis_y - dy * axis_x);
  if (!(along > 0.5f * std::sqrt(dx * dx + dy * dy))) return false;
  tan_angle = across / along;
  return true;
}

}  // namespace

namespace {

// the cells of a grid of nx x ny unit cells that a ray's track (u0 + t du, v0 + t dv) crosses
// between t_enter and t_leave, in order: visit(i, j, ta, tb) for each cell and the stretch of the
// ray over it, until a visit returns true (then true)
template <class Visit>
bool march(float u0, float v0, float du, float dv, float t_enter, float t_leave, int nx, int ny,
           Visit&& visit) {
  // the stretch over the grid
  const auto clip = [&t_enter, &t_leave](float p0, float dp, float hi) {
    if (dp == 0.f) {
      if (p0 < 0.f || p0 > hi) t_leave = -1.f;
      return;
    }
    const float a = (0.f - p0) / dp, b = (hi - p0) / dp;
    t_enter = std::max(t_enter, std::min(a, b));
    t_leave = std::min(t_leave, std::max(a, b));
  };
  clip(u0, du, static_cast<float>(nx));
  clip(v0, dv, static_cast<float>(ny));
  if (!(t_enter <= t_leave)) return false;

  // the first cell and the steps to the next column and row of cells
  const float start = t_enter + 1e-5f * (t_leave - t_enter);
  int i = std::clamp(static_cast<int>(std::floor(u0 + start * du)), 0, nx - 1);
  int j = std::clamp(static_cast<int>(std::floor(v0 + start * dv)), 0, ny - 1);
  const int step_i = du > 0.f ? 1 : -1, step_j = dv > 0.f ? 1 : -1;
  const float inf = std::numeric_limits<float>::infinity();
  float t_next_i = du != 0.f ? (static_cast<float>(step_i > 0 ? i + 1 : i) - u0) / du : inf;
  float t_next_j = dv != 0.f ? (static_cast<float>(step_j > 0 ? j + 1 : j) - v0) / dv : inf;
  const float delta_i = du != 0.f ? std::abs(1.f / du) : inf;
  const float delta_j = dv != 0.f ? std::abs(1.f / dv) : inf;
  float ta = t_enter;
  for (;;) {
    const float tb = std::min({t_next_i, t_next_j, t_leave});
    if (visit(i, j, ta, tb)) return true;
    if (tb >= t_leave) return false;
    ta = tb;
    if (t_next_i <= t_next_j) {
      i += step_i;
      t_next_i += delta_i;
    } else {
      j += step_j;
      t_next_j += delta_j;
    }
    if (i < 0 || i >= nx || j < 0 || j >= ny) return false;
  }
}

// the highest ground in each block of kGroundBlock x kGroundBlock cells of the grid, as a height
// above the grade's plane (a bump's height, not the grade's rise over the block), so that a ray
// passes over a block it stays above without visiting its cells
constexpr int kGroundBlock = 8;
// a block whose vertices all lie this close to one plane is met as that plane (far below the
// range noise of any LiDAR, and a fraction of what single precision keeps of a venue's heights)
constexpr double kPlanarBlockM = 5e-5;
struct GroundBlocks {
  int nx = 0, ny = 0;
  std::vector<float> max_above;
  // for each block, the plane z = z0 + sx x + sy y it lies in, when it does (planar: most of a
  // venue between its bumps, on a grade or a crown's flanks)
  struct Plane {
    bool planar = false;
    float z0 = 0.f, sx = 0.f, sy = 0.f;
  };
  std::vector<Plane> planes;
  // for each cell of the grid, how many cells away (Chebyshev, at most 255) the nearest cell
  // lies that is not on the grade's plane, or the grid's edge: a ray whose whole stretch through
  // the ground's band lies within that many cells less one of where it meets the grade's plane
  // meets the ground there (the fast path of most rays on a grade with bumps)
  // (stored in tiles of 8 x 8 cells, a cache line each, since a ray's steps and the rays of
  // neighbouring columns look up cells near each other)
  std::vector<uint8_t> clear_cells;
  int tiles_x = 0;
  static std::vector<uint8_t> clearance(const tracks::GroundGrid& g);
  uint8_t clear_at(int i, int j) const {
    return clear_cells[(static_cast<size_t>(j >> 3) * tiles_x + static_cast<size_t>(i >> 3)) * 64 +
                       static_cast<size_t>((j & 7) * 8 + (i & 7))];
  }

  explicit GroundBlocks(const tracks::GroundGrid& g)
      : nx((g.nx - 1 + kGroundBlock - 1) / kGroundBlock),
        ny((g.ny - 1 + kGroundBlock - 1) / kGroundBlock),
        max_above(static_cast<size_t>(nx) * ny, -std::numeric_limits<float>::infinity()),
        clear_cells(clearance(g)),
        tiles_x((std::max(0, g.nx - 1) + 7) / 8) {
    for (int j = 0; j < g.ny; ++j)
      for (int i = 0; i < g.nx; ++i) {
        const double plane =
            g.slope.x() * (g.x0 + i * g.cell_m) + g.slope.y() * (g.y0 + j * g.cell_m) + g.plane_z0;
        const auto above = static_cast<float>(g.z[static_cast<size_t>(j) * g.nx + i] - plane);
        // a vertex on a block's edge belongs to the blocks either side
        for (int bj = std::max(0, (j - 1) / kGroundBlock); bj <= std::min(ny - 1, j / kGroundBlock);
             ++bj)
          for (int bi = std::max(0, (i - 1) / kGroundBlock);
               bi <= std::min(nx - 1, i / kGroundBlock); ++bi) {
            float& m = max_above[static_cast<size_t>(bj) * nx + bi];
            m = std::max(m, above);
          }
      }
    // each block's least-squares plane through its vertices, kept when none strays from it
    planes.resize(max_above.size());
    for (int bj = 0; bj < ny; ++bj)
      for (int bi = 0; bi < nx; ++bi) {
        const int i0 = bi * kGroundBlock, i1 = std::min(g.nx - 1, i0 + kGroundBlock);
        const int j0 = bj * kGroundBlock, j1 = std::min(g.ny - 1, j0 + kGroundBlock);
        // (about the block's corner, in metres)
        Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
        Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
        for (int j = j0; j <= j1; ++j)
          for (int i = i0; i <= i1; ++i) {
            const Eigen::Vector3d row(1.0, (i - i0) * g.cell_m, (j - j0) * g.cell_m);
            normal += row * row.transpose();
            rhs += row * g.at(i, j);
          }
        const Eigen::Vector3d c = normal.ldlt().solve(rhs);
        double stray = 0.0;
        for (int j = j0; j <= j1; ++j)
          for (int i = i0; i <= i1; ++i)
            stray = std::max(stray, std::abs(c[0] + c[1] * (i - i0) * g.cell_m +
                                             c[2] * (j - j0) * g.cell_m - g.at(i, j)));
        if (!(stray <= kPlanarBlockM)) continue;
        const double cx = g.x0 + i0 * g.cell_m, cy = g.y0 + j0 * g.cell_m;
        planes[static_cast<size_t>(bj) * nx + bi] = {
            true, static_cast<float>(c[0] - c[1] * cx - c[2] * cy), static_cast<float>(c[1]),
            static_cast<float>(c[2])};
      }
  }
};

// the cells' clearance of GroundBlocks::clear_cells: 0 for a cell with a vertex off the grade's
// plane, then a two-pass chamfer of the Chebyshev distance (a cell outside the grid counts as
// off the plane)
std::vector<uint8_t> GroundBlocks::clearance(const tracks::GroundGrid& g) {
  const int cx = g.nx - 1, cy = g.ny - 1;
  if (cx <= 0 || cy <= 0) return {};
  std::vector<uint8_t> on_plane(static_cast<size_t>(g.nx) * g.ny);
  for (int j = 0; j < g.ny; ++j)
    for (int i = 0; i < g.nx; ++i) {
      const double plane =
          g.slope.x() * (g.x0 + i * g.cell_m) + g.slope.y() * (g.y0 + j * g.cell_m) + g.plane_z0;
      on_plane[static_cast<size_t>(j) * g.nx + i] = std::abs(g.at(i, j) - plane) <= kPlanarBlockM;
    }
  std::vector<uint8_t> d(static_cast<size_t>(cx) * cy);
  const auto at = [&](int i, int j) -> uint8_t& { return d[static_cast<size_t>(j) * cx + i]; };
  // (a neighbour outside the grid is at distance 0)
  const auto seen = [&](int i, int j) -> int {
    return i < 0 || j < 0 || i >= cx || j >= cy ? 0 : at(i, j);
  };
  for (int j = 0; j < cy; ++j)
    for (int i = 0; i < cx; ++i) {
      const size_t v = static_cast<size_t>(j) * g.nx + i;
      if (!(on_plane[v] && on_plane[v + 1] && on_plane[v + g.nx] && on_plane[v + g.nx + 1])) {
        at(i, j) = 0;
        continue;
      }
      const int best =
          std::min({seen(i - 1, j), seen(i - 1, j - 1), seen(i, j - 1), seen(i + 1, j - 1)});
      at(i, j) = static_cast<uint8_t>(std::min(255, best + 1));
    }
  for (int j = cy - 1; j >= 0; --j)
    for (int i = cx - 1; i >= 0; --i) {
      if (at(i, j) == 0) continue;
      const int best =
          std::min({seen(i + 1, j), seen(i + 1, j + 1), seen(i, j + 1), seen(i - 1, j + 1)}) + 1;
      at(i, j) = static_cast<uint8_t>(std::min<int>(at(i, j), best));
    }
  // in tiles of 8 x 8 (clear_at())
  const int tx = (cx + 7) / 8, ty = (cy + 7) / 8;
  std::vector<uint8_t> tiled(static_cast<size_t>(tx) * ty * 64, 0);
  for (int j = 0; j < cy; ++j)
    for (int i = 0; i < cx; ++i)
      tiled[(static_cast<size_t>(j >> 3) * tx + static_cast<size_t>(i >> 3)) * 64 +
            static_cast<size_t>((j & 7) * 8 + (i & 7))] = at(i, j);
  return tiled;
}

// where a ray from origin along dir first comes down onto the grid's surface between t_enter and
// t_leave (each cell two triangles split along its diagonal from (i, j) to (i + 1, j + 1), as the
// ground model splits it): the blocks its track crosses, in order, and in each block it may reach
// down to, its cells, each one's piece or two of the ray tested against the triangle under it.
// `above` and `climb`: the origin's height above the grade's plane and the ray's rise over it per
// metre. The range and the triangle's upward normal (not unit length); false when it stays above
bool meet_grid(const tracks::GroundGrid& g, const GroundBlocks& blocks,
               const Eigen::Vector3f& origin, const Eigen::Vector3f& dir, float above, float climb,
               float t_enter, float t_leave, float& t_hit, Eigen::Vector3f& normal) {
  // the ray in cell units
  const float cell = static_cast<float>(g.cell_m);
  const float u0 = (origin.x() - static_cast<float>(g.x0)) / cell;
  const float v0 = (origin.y() - static_cast<float>(g.y0)) / cell;
  const float du = dir.x() / cell, dv = dir.y() / cell;

  // one cell: the piece or two of the ray over it, split where it crosses the diagonal, each
  // against the triangle under it (the ray's height above a triangle is linear along it)
  const auto cell_hit = [&](int i, int j, float ta, float tb) {
    const size_t k = static_cast<size_t>(j) * g.nx + i;
    const float z00 = g.z[k], z10 = g.z[k + 1], z01 = g.z[k + g.nx], z11 = g.z[k + g.nx + 1];
    const float lowest_ray = origin.z() + dir.z() * (dir.z() < 0.f ? tb : ta);
    if (lowest_ray > std::max({z00, z10, z01, z11})) return false;
    float cuts[3] = {ta, tb, tb};
    int pieces = 1;
    const float fu0 = u0 - static_cast<float>(i), fv0 = v0 - static_cast<float>(j);
    if (du != dv) {
      const float td = (fv0 - fu0) / (du - dv);
      if (td > ta && td < tb) {
        cuts[1] = td;
        pieces = 2;
      }
    }
    for (int p = 0; p < pieces; ++p) {
      const float pa = cuts[p], pb = cuts[p + 1];
      const float tm = 0.5f * (pa + pb);
      const bool lower = fu0 + tm * du >= fv0 + tm * dv;
      const float su = lower ? z10 - z00 : z11 - z01;
      const float sv = lower ? z11 - z10 : z01 - z00;
      const auto above = [&](float t) {
        return origin.z() + t * dir.z() - (z00 + su * (fu0 + t * du) + sv * (fv0 + t * dv));
      };
      const float ha = above(pa), hb = above(pb);
      if (ha >= 0.f && hb <= 0.f && ha > hb) {
        t_hit = pa + (pb - pa) * ha / (ha - hb);
        normal = Eigen::Vector3f(-su / cell, -sv / cell, 1.f);
        return true;
      }
    }
    return false;
  };

  // the blocks, and the cells of those the ray comes down to
  const float b = static_cast<float>(kGroundBlock);
  return march(u0 / b, v0 / b, du / b, dv / b, t_enter, t_leave, blocks.nx, blocks.ny,
               [&](int bi, int bj, float ta, float tb) {
                 // the ray's lowest over the block, above the grade's plane (a millimetre for
                 // the rounding of single precision)
                 const float lowest = above + climb * (climb < 0.f ? tb : ta);
                 const size_t k = static_cast<size_t>(bj) * blocks.nx + bi;
                 if (lowest > blocks.max_above[k] + 1e-3f) return false;
                 // a planar block: where the ray comes down through its plane, if over it
                 if (const GroundBlocks::Plane& p = blocks.planes[k]; p.planar) {
                   const float h0 = origin.z() - (p.z0 + p.sx * origin.x() + p.sy * origin.y());
                   const float rate = dir.z() - p.sx * dir.x() - p.sy * dir.y();
                   const float ha = h0 + rate * ta, hb = h0 + rate * tb;
                   if (!(ha >= 0.f && hb <= 0.f && ha > hb)) return false;
                   t_hit = ta + (tb - ta) * ha / (ha - hb);
                   normal = Eigen::Vector3f(-p.sx, -p.sy, 1.f);
                   return true;
                 }
                 return march(u0, v0, du, dv, ta, tb, g.nx - 1, g.ny - 1, cell_hit);
               });
}

}  // namespace

// A cone class's true shape (its mesh's facets lie within it) for the test of whether a ray that
// passes over a cone's footprint can meet the mesh at all: the plate out to its corners, and the
// body, whose radius shrinks with height. Heights above the cone's base.
struct ConeBounds {
  float plate_reach = 0.f, plate_top = 0.f;
  float bottom_radius = 0.f, top_radius = 0.f, height = 0.f;

  // whether the ray can meet the cone: its track on the ground passes miss_squared (squared)
  // from the axis, nearest at the ray's range `closest`, with `squared` the square of its
  // horizontal part per metre; its height above the base is z0 + dz t, for t up to length; every
  // radius widened by `widening`. Conservative: false only when the ray stays clear of both the
  // plate and the body, with a centimetre of slack in height
  bool may_meet(float miss_squared, float closest, float squared, float z0, float dz, float length,
                float widening) const {
    constexpr auto kSlack = static_cast<float>(kTopSlackM);
    // the lowest the ray comes over the disk of radius r about the axis (false: it misses it)
    const auto lowest_over = [&](float r, float& lowest) {
      if (miss_squared > r * r) return false;
      const float half = std::sqrt((r * r - miss_squared) / squared);
      const float a = std::max(0.f, closest - half), b = std::min(length, closest + half);
      if (!(a <= b)) return false;
      lowest = z0 + dz * (dz > 0.f ? a : b);
      return true;
    };
    float lowest = 0.f;
    if (lowest_over(plate_reach + widening, lowest) && lowest <= plate_top + kSlack) return true;
    // over the body's disk the ray is no lower than `lowest`, where the body is no wider than
    // at that height
    if (!lowest_over(bottom_radius + widening, lowest) || lowest > height + kSlack) return false;
    const float at = std::clamp(lowest - kSlack, plate_top, height);
    const float r = bottom_radius +
                    (top_radius - bottom_radius) * (at - plate_top) / (height - plate_top) +
                    widening;
    return miss_squared <= r * r;
  }
};

// A box of a scenery object, met analytically rather than through Embree (most of the scenery
// is boxes: a grass strip, a barrier, a fence): its centre relative to the object's place, its
// axes as rows and its half sizes; the same six faces as its mesh would have.
struct SolidBox {
  Eigen::Vector3f centre = Eigen::Vector3f::Zero();
  Eigen::Matrix3f axes = Eigen::Matrix3f::Identity();
  Eigen::Vector3f half = Eigen::Vector3f::Zero();
  float reflectivity = 0.f;

  // where a ray from o (relative to the object's place) along the unit d first meets a face at
  // a range in [0, reach): the range and the face's unit normal (from inside the box, the face
  // it leaves by, as a ray meets a mesh from within)
  bool hit(const Eigen::Vector3f& o, const Eigen::Vector3f& d, float reach, float& t,
           Eigen::Vector3f& normal) const {
    const Eigen::Vector3f q = axes * (o - centre), e = axes * d;
    float lo = -std::numeric_limits<float>::infinity(), hi = -lo;
    int lo_axis = 0, hi_axis = 0;
    for (int k = 0; k < 3; ++k) {
      if (e[k] == 0.f) {
        if (std::abs(q[k]) > half[k]) return false;
        continue;
      }
      const float per = 1.f / e[k];
      float a = (-half[k] - q[k]) * per, b = (half[k] - q[k]) * per;
      if (a > b) std::swap(a, b);
      if (a > lo) {
        lo = a;
        lo_axis = k;
      }
      if (b < hi) {
        hi = b;
        hi_axis = k;
      }
    }
    if (!(lo <= hi)) return false;
    const bool outside = lo >= 0.f;
    t = outside ? lo : hi;
    if (!(t >= 0.f && t < reach)) return false;
    normal = axes.row(outside ? lo_axis : hi_axis).transpose();
    return true;
  }
};

// the boxes of an object, placed as its mesh places them (turned by its tilt and heading)
std::vector<SolidBox> boxes_of(const tracks::SceneryObject& object) {
  const Eigen::Matrix3d turn =
      object.tilt * Eigen::AngleAxisd(object.pose.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  std::vector<SolidBox> out;
  for (const tracks::ScenePrimitive& p : object.parts) {
    if (p.shape != tracks::ScenePrimitive::Shape::kBox) continue;
    SolidBox b;
    b.centre = (turn * p.centre).cast<float>();
    b.axes = (turn * p.rotation).transpose().cast<float>();
    b.half = p.size.cast<float>();
    b.reflectivity = static_cast<float>(p.reflectivity);
    out.push_back(b);
  }
  return out;
}

struct Lidar::Impl {
  // one beam of a column, in ring order
  struct Channel {
    float cos_elevation;
    float sin_elevation;
  };
  // a cone of the track or a scenery object: its mesh (a cone class's or the object's own, an
  // index into scenes), its place, its footprint and the label its points carry (the cone id,
  // or the object's clutter label)
  struct SceneCone {
    int label = 0;
    int cls = 0;
    float x = 0.f, y = 0.f;
    // every point of the cone lies within this horizontal distance of (x, y), and below top_m
    // (a height in the track frame: the ground under the cone, z, plus the cone's own)
    float footprint_m = 0.f;
    float top_m = 0.f;
    bool present = true;
    float z = 0.f;
    // a scenery object's outline (unused for a cone, whose footprint is round)
    Outline outline;
  };

  LidarConfig config;
  RTCDevice device = nullptr;
  // one scene per cone class, holding its mesh in the cone's own frame, then one per scenery
  // object (its mesh about its place)
  std::vector<RTCScene> class_scenes;
  // the ground's grid when it is not flat (empty: the plane z = 0, met analytically), its
  // grade's plane and the band about that plane that holds the whole grid
  tracks::GroundGrid ground_grid;
  std::optional<GroundBlocks> ground_blocks;
  bool uneven = false;
  float grade_x = 0.f, grade_y = 0.f, grade_z0 = 0.f;
  float band_lo = 0.f, band_hi = 0.f;
  // one over the length of the grade's upward normal (-grade_x, -grade_y, 1), and the grid's
  // cells for trace_ground()'s fast path (their clearance, GroundBlocks::clear_cells)
  float grade_cos_scale = 1.f;
  float cell_x0 = 0.f, cell_y0 = 0.f, per_cell = 1.f, cells_x = 0.f, cells_y = 0.f;
  // the height above the grade's plane that every cone and scenery object stays below
  float stuff_above = 0.f;
  std::vector<Channel> channels;
  // the same, one array per term, for the loops over a column's rays
  std::vector<float> channel_cos, channel_sin;
  std::vector<float> column_cos;
  std::vector<float> column_sin;
  std::vector<core::TimeUs> column_offset_us;
  std::array<float, kSurfaceMaterialCount> reflectivity{};
  // reflectivity of each triangle of each scene's mesh
  std::vector<std::vector<float>> class_reflectivity;
  // each cone class's shape
  std::array<ConeBounds, kClassCount> cone_bounds{};
  // each scene's boxes, met without Embree (a scenery object's; its scene holds the rest of its
  // solids, or is null when it has none)
  std::vector<std::vector<SolidBox>> class_boxes;
  std::vector<SceneCone> cones;
  std::unordered_map<int, int> cone_index;
  // the ground (the plane z = 0 over a rectangle) and the height above which nothing stands,
  // where rays are cut
  RayBounds ray_bounds;
  float inverse_squared_falloff = 0.f;
  // a cone's footprint is widened before a ray is judged to pass clear of it: by the slack, and
  // by half the beam's spot where the ray passes it, this much per metre of horizontal distance
  float spot_slack_per_m = 0.f;
  // the offset of the beam's outer thirds from its axis (tangent of the angle; 0: a thin ray)
  float spot_offset = 0.f;
  // one over the length of a ray turned by the offset: 1 / sqrt(1 + spot_offset^2)
  float spot_scale = 1.f;
  // the squared range of a 10 % diffuse target at normal incidence, over 0.1, for the signal
  // of a return (0: every return is detected)
  float detection_scale = 0.f;
  // the mount as a rotation and a translation
  Eigen::Matrix3d mount_rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d mount_translation = Eigen::Vector3d::Zero();

  ~Impl() {
    for (RTCScene s : class_scenes)
      if (s) rtcReleaseScene(s);
    if (device) rtcReleaseDevice(device);
  }

  // the rays of a chunk of columns and what each met (label kNoReturn: nothing)
  struct ChunkRays {
    std::vector<float> dir_x, dir_y, dir_z, length;
    std::vector<float> range, intensity;
    std::vector<int> label;
    std::array<Eigen::Vector3f, kChunkColumns> origin;
    // the points of the chunk's returns and their labels, before they join the scan
    std::vector<core::LidarPoint> points;
    std::vector<int> point_label;
    // for each cone near a column and each of its rays, whether the ray passes far from it, for
    // each ray whether it passes far from them all, and its fall per metre across the ground
    std::vector<int> far, far_from_all;
    std::vector<float> drop;
    explicit ChunkRays(size_t n)
        : dir_x(n),
          dir_y(n),
          dir_z(n),
          length(n),
          range(n),
          intensity(n),
          label(n),
          points(n),
          point_label(n),
          far_from_all(n),
          drop(n) {}
  };

  void build_beams();
  void build_scene(const tracks::Track& track, const std::vector<tracks::SceneryObject>& scenery,
                   const tracks::GroundModel& ground);
  void build_ground(const tracks::GroundModel& ground);
  static RTCRayHit ray_hit(const Eigen::Vector3f& origin, const Eigen::Vector3f& dir, float tnear,
                           float tfar);
  float trace_ground(ChunkRays& rays, int first, const Eigen::Vector3f& origin,
                     const Eigen::Vector3f& heading, const Eigen::Vector3f& up) const;
  void meet_ground(ChunkRays& rays, int slot, float length, float t, float cos_incidence) const;
  void throw_on_device_error(const char* what) const;
  float intensity_of(float reflectivity_of_surface, float cos_incidence, float range) const;
  float cast_column(ChunkRays& rays, int first, const Eigen::Vector3f& origin,
                    const Eigen::Vector3f& heading, const Eigen::Vector3f& up) const;
  void hit_cone(const SceneCone& cone, const Eigen::Vector3f& origin, const Eigen::Vector3f& dir,
                RTCIntersectContext& context, float& reach, int& label, float& intensity) const;
};

float Lidar::Impl::intensity_of(float reflectivity_of_surface, float cos_incidence,
                                float range) const {
  // the material's reflectivity, times the cosine of incidence and the range fall-off
  return 255.f * reflectivity_of_surface * cos_incidence /
         (1.f + range * range * inverse_squared_falloff);
}

// a column's rays from origin: their directions, how far each can find anything, and where each
// meets the ground plane; returns the longest ray
float Lidar::Impl::cast_column(ChunkRays& rays, int first, const Eigen::Vector3f& origin,
                               const Eigen::Vector3f& heading, const Eigen::Vector3f& up) const {
  const int count = static_cast<int>(channels.size());
  cast_rays(count, channel_cos.data(), channel_sin.data(), origin, heading, up, ray_bounds,
            rays.dir_x.data() + first, rays.dir_y.data() + first, rays.dir_z.data() + first,
            rays.length.data() + first, rays.range.data() + first, rays.intensity.data() + first,
            rays.label.data() + first);

  // the longest ray
  float reach = 0.f;
  for (int slot = first; slot < first + count; ++slot) reach = std::max(reach, rays.length[slot]);
  return reach;
}

// the Embree ray from origin along dir over [tnear, tfar], no hit yet
RTCRayHit Lidar::Impl::ray_hit(const Eigen::Vector3f& origin, const Eigen::Vector3f& dir,
                               float tnear, float tfar) {
  RTCRayHit ray;
  ray.ray.org_x = origin.x();
  ray.ray.org_y = origin.y();
  ray.ray.org_z = origin.z();
  ray.ray.dir_x = dir.x();
  ray.ray.dir_y = dir.y();
  ray.ray.dir_z = dir.z();
  ray.ray.tnear = tnear;
  ray.ray.tfar = tfar;
  ray.ray.time = 0.f;
  ray.ray.mask = 0xFFFFFFFFu;
  ray.ray.id = 0;
  ray.ray.flags = 0;
  ray.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  ray.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  return ray;
}

// the cone's mesh, if the ray from origin along dir (a unit vector) meets it nearer than reach
// (then reach becomes its range, with the cone's label and the hit's intensity before noise):
// the ray moved into the cone's frame, which is the track frame shifted to the cone's place
void Lidar::Impl::hit_cone(const SceneCone& cone, const Eigen::Vector3f& origin,
                           const Eigen::Vector3f& dir, RTCIntersectContext& context, float& reach,
                           int& label, float& intensity) const {
  const Eigen::Vector3f from = origin - Eigen::Vector3f(cone.x, cone.y, cone.z);
  for (const SolidBox& box : class_boxes[cone.cls]) {
    float t = 0.f;
    Eigen::Vector3f normal;
    if (!box.hit(from, dir, reach, t, normal)) continue;
    reach = t;
    label = cone.label;
    intensity = intensity_of(box.reflectivity, std::abs(dir.dot(normal)), t);
  }
  if (!class_scenes[cone.cls]) return;
  RTCRayHit ray = ray_hit(from, dir, 0.f, reach);
  rtcIntersect1(class_scenes[cone.cls], &context, &ray);
  if (ray.hit.geomID == RTC_INVALID_GEOMETRY_ID) return;

  // (the shift leaves the normal as it is)
  const Eigen::Vector3f normal(ray.hit.Ng_x, ray.hit.Ng_y, ray.hit.Ng_z);
  const float cos_incidence = std::abs(dir.dot(normal)) / normal.norm();
  reach = ray.ray.tfar;
  label = cone.label;
  intensity =
      intensity_of(class_reflectivity[cone.cls][ray.hit.primID], cos_incidence, ray.ray.tfar);
}

// a ground that is not flat: a column's rays as cast_column() casts them down to the floor under
// the ground's lowest point, then each ray that can find anything marched over the ground's grid
// instead of meeting the plane z = 0 (label, range and intensity as the plane's) and ended just
// past where it meets it; returns the longest ray
float Lidar::Impl::trace_ground(ChunkRays& rays, int first, const Eigen::Vector3f& origin,
                                const Eigen::Vector3f& heading, const Eigen::Vector3f& up) const {
  cast_column(rays, first, origin, heading, up);
  const int count = static_cast<int>(channels.size());
  // the origin's height above the grade's plane
  const float above = origin.z() - (grade_x * origin.x() + grade_y * origin.y() + grade_z0);
  for (int slot = first; slot < first + count; ++slot) {
    rays.label[slot] = kNoReturn;
    const float length = rays.length[slot];
    if (!(length > 0.f)) continue;

    // the stretch of the ray within the band about the grade's plane that holds the ground:
    // the only place it can meet it (none for most rays that climb away from it)
    const float climb = rays.dir_z[slot] - grade_x * rays.dir_x[slot] - grade_y * rays.dir_y[slot];
    // a ray that climbs away from the grade's plane meets nothing once it is above everything
    // that stands on the ground (on a grade the floor and the top of the whole venue, where
    // cast_column() ends it, lie far below and above the ground near the car)
    if (climb >= 0.f) {
      const float rise = stuff_above - above;
      const float to_top =
          climb > 0.f ? rise / climb * 1.0001f + kGroundSlackM : (rise >= 0.f ? length : 0.f);
      rays.length[slot] = std::clamp(to_top, 0.f, length);
      // (from above the ground's band it never comes down to the ground)
      if (above > band_hi) continue;
    }
    // the fast path: a ray that comes down onto the grade's plane where the ground around is
    // that plane. From where the ray enters the band, it steps over the cells that the clearance
    // of the cell it is over says lie on the plane (GroundBlocks::clear_cells), until it passes
    // the plane (then it met the ground there) or comes near a cell off the plane (then it is
    // marched from there)
    const Eigen::Vector3f dir(rays.dir_x[slot], rays.dir_y[slot], rays.dir_z[slot]);
    float from = 0.f;
    if (climb < 0.f && above > 0.f) {
      const float per_climb = 1.f / climb;
      const float t_plane = -above * per_climb;
      from = std::max(0.f, (band_hi - above) * per_climb);
      // (metres of the ray per cell it runs over, in the larger of the two axes)
      const float per_run = 1.f / (per_cell * std::max(std::abs(dir.x()), std::abs(dir.y())));
      bool met = false;
      while (t_plane <= length) {
        const float u = (origin.x() + from * dir.x() - cell_x0) * per_cell;
        const float v = (origin.y() + from * dir.y() - cell_y0) * per_cell;
        if (!(u >= 0.f && v >= 0.f && u < cells_x && v < cells_y)) break;
        const int clear = ground_blocks->clear_at(static_cast<int>(u), static_cast<int>(v));
        if (clear <= 1) break;
        from += static_cast<float>(clear - 1) * per_run;
        if (from >= t_plane) {
          met = true;
          break;
        }
      }
      if (met) {
        // (the cosine of incidence on the grade's plane: dir . its normal is the climb)
        meet_ground(rays, slot, length, t_plane, -climb * grade_cos_scale);
        continue;
      }
    }
    float enter = 0.f, leave = rays.length[slot];
    if (climb != 0.f) {
      const float to_lo = (band_lo - above) / climb, to_hi = (band_hi - above) / climb;
      enter = std::max(from, std::min(to_lo, to_hi));
      leave = std::min(leave, std::max(to_lo, to_hi));
    } else if (above < band_lo || above > band_hi) {
      continue;
    }
    if (!(enter <= leave)) continue;
    float t = 0.f;
    Eigen::Vector3f normal;
    if (meet_grid(ground_grid, *ground_blocks, origin, dir, above, climb, enter, leave, t, normal))
      meet_ground(rays, slot, length, t, std::abs(dir.dot(normal)) / normal.norm());
  }
  float reach = 0.f;
  for (int slot = first; slot < first + count; ++slot) reach = std::max(reach, rays.length[slot]);
  return reach;
}

// the ray in slot (at most length long) meets the ground at range t with that cosine of incidence
void Lidar::Impl::meet_ground(ChunkRays& rays, int slot, float length, float t,
                              float cos_incidence) const {
  rays.label[slot] = core::PointCloudLabels::kGroundLabel;
  rays.range[slot] = t;
  // nothing beyond the ground is seen: the ray ends just past it, as on the plane
  rays.length[slot] = std::min(length, t * 1.0001f + kGroundSlackM);
  rays.intensity[slot] =
      ray_bounds.ground_scale * cos_incidence / (1.f + t * t * ray_bounds.falloff);
}

// the ground's grid and the band about its grade's plane that holds it
void Lidar::Impl::build_ground(const tracks::GroundModel& ground) {
  const tracks::GroundGrid& g = ground.grid();
  ground_grid = g;
  ground_blocks.emplace(g);
  uneven = true;
  grade_x = static_cast<float>(g.slope.x());
  grade_y = static_cast<float>(g.slope.y());
  grade_z0 = static_cast<float>(g.plane_z0);
  // two millimetres beyond the band: far more than single precision loses at these heights
  band_lo = static_cast<float>(g.residual_min) - 0.002f;
  band_hi = static_cast<float>(g.residual_max) + 0.002f;
  // the fast path's cells
  grade_cos_scale = 1.f / std::sqrt(1.f + grade_x * grade_x + grade_y * grade_y);
  cell_x0 = static_cast<float>(g.x0);
  cell_y0 = static_cast<float>(g.y0);
  per_cell = static_cast<float>(1.0 / g.cell_m);
  cells_x = static_cast<float>(std::max(0, g.nx - 1));
  cells_y = static_cast<float>(std::max(0, g.ny - 1));
}

void Lidar::Impl::build_beams() {
  // channels sorted by elevation: ring 0 is the lowest beam
  std::vector<double> elevations = config.elevations_deg;
  std::sort(elevations.begin(), elevations.end());
  for (double e : elevations) {
    const double rad = e * std::numbers::pi / 180.0;
    channels.push_back({static_cast<float>(std::cos(rad)), static_cast<float>(std::sin(rad))});
    channel_cos.push_back(channels.back().cos_elevation);
    channel_sin.push_back(channels.back().sin_elevation);
  }

  // columns: azimuth and firing time inside the sweep (whole microseconds)
  const double step = 2.0 * std::numbers::pi / config.columns * (config.clockwise ? -1.0 : 1.0);
  const double start = config.start_azimuth_deg * std::numbers::pi / 180.0;
  const core::TimeUs period = config.sweep_period_us();
  for (int c = 0; c < config.columns; ++c) {
    const double azimuth = start + step * c;
    column_cos.push_back(static_cast<float>(std::cos(azimuth)));
    column_sin.push_back(static_cast<float>(std::sin(azimuth)));
    column_offset_us.push_back(period * c / config.columns);
  }

  // the mount and the intensity fall-off
  mount_rotation = config.mount.orientation.normalized().toRotationMatrix();
  mount_translation = config.mount.position;
  inverse_squared_falloff =
      static_cast<float>(1.0 / (config.intensity_falloff_m * config.intensity_falloff_m));

  // the beam's spot and the fading of weak returns
  const double divergence_rad = config.beam_divergence_mrad * 1e-3;
  const double offset = std::tan(divergence_rad / 3.0);
  spot_offset = static_cast<float>(offset);
  spot_scale = static_cast<float>(1.0 / std::sqrt(1.0 + offset * offset));
  // (a ray's range over its horizontal distance is at most 1 / cos of the steepest beam)
  double steepest_deg = 0.0;
  for (double e : config.elevations_deg) steepest_deg = std::max(steepest_deg, std::abs(e));
  spot_slack_per_m = static_cast<float>(std::tan(divergence_rad / 2.0) /
                                        std::cos(steepest_deg * std::numbers::pi / 180.0));
  detection_scale =
      static_cast<float>(config.detection_range_10pct_m * config.detection_range_10pct_m / 0.1);

  // reflectivity per material
  for (int m = 0; m < kSurfaceMaterialCount; ++m)
    reflectivity[m] = static_cast<float>(config.reflectivity.of(static_cast<SurfaceMaterial>(m)));

  // what the ray loops need besides the ground rectangle and the top (build_scene's)
  ray_bounds.max_range = static_cast<float>(config.max_range_m);
  ray_bounds.falloff = inverse_squared_falloff;
  ray_bounds.ground_scale = 255.f * reflectivity[static_cast<int>(SurfaceMaterial::kGround)];
}

void Lidar::Impl::build_scene(const tracks::Track& track,
                              const std::vector<tracks::SceneryObject>& scenery,
                              const tracks::GroundModel& ground) {
  device = rtcNewDevice("threads=1");
  if (!device) throw std::runtime_error("lidar: Embree device could not be created");

  // a ground that is not flat: its mesh, and the floor below its lowest point
  if (!ground.flat()) {
    build_ground(ground);
    ray_bounds.floor_z = static_cast<float>(ground.grid().min_z) - 0.01f;
    ray_bounds.top_z = static_cast<float>(ground.grid().max_z) + 0.01f;
  }

  // ground: a rectangle over the cones and the start pose, reaching the max range beyond them
  Eigen::Vector2d lo(track.start.x, track.start.y), hi = lo;
  for (const tracks::Cone& cone : track.cones) {
    lo = lo.cwiseMin(cone.position);
    hi = hi.cwiseMax(cone.position);
  }
  for (const tracks::SceneryObject& object : scenery) {
    const Eigen::Vector2d reach = Eigen::Vector2d::Constant(object.radius_m);
    lo = lo.cwiseMin(object.pose.position() - reach);
    hi = hi.cwiseMax(object.pose.position() + reach);
  }
  const double margin = config.max_range_m + kGroundMarginM;
  lo.array() -= margin;
  hi.array() += margin;
  ray_bounds.lo_x = static_cast<float>(lo.x());
  ray_bounds.lo_y = static_cast<float>(lo.y());
  ray_bounds.hi_x = static_cast<float>(hi.x());
  ray_bounds.hi_y = static_cast<float>(hi.y());

  // one scene per class, built once at high quality, its materials shared by its cones
  std::array<float, kClassCount> footprint{};
  class_scenes.assign(kClassCount, nullptr);
  class_reflectivity.resize(kClassCount);
  class_boxes.resize(kClassCount);
  for (int k = 0; k < kClassCount; ++k) {
    const ConeShape shape = cone_shape(static_cast<core::ConeClass>(k));
    const ConeMesh mesh = build_cone_mesh(shape, config.cone_mesh_sides);
    for (SurfaceMaterial m : mesh.materials)
      class_reflectivity[k].push_back(reflectivity[static_cast<int>(m)]);
    footprint[k] = static_cast<float>(
        std::max(shape.plate_width_m * std::numbers::sqrt2 / 2.0, shape.body_bottom_radius_m));
    cone_bounds[k] = {
        static_cast<float>(shape.plate_width_m * std::numbers::sqrt2 / 2.0),
        static_cast<float>(shape.plate_height_m), static_cast<float>(shape.body_bottom_radius_m),
        static_cast<float>(shape.body_top_radius_m), static_cast<float>(shape.height_m)};
    class_scenes[k] = rtcNewScene(device);
    rtcSetSceneBuildQuality(class_scenes[k], RTC_BUILD_QUALITY_HIGH);
    RTCGeometry geom = make_triangle_geometry(device, mesh.vertices, mesh.triangles);
    rtcAttachGeometry(class_scenes[k], geom);
    rtcReleaseGeometry(geom);
    rtcCommitScene(class_scenes[k]);
  }

  // every cone: its class and its place
  for (const tracks::Cone& cone : track.cones) {
    const int k = class_index(cone.cls);
    const float x = static_cast<float>(cone.position.x());
    const float y = static_cast<float>(cone.position.y());
    cone_index[cone.id] = static_cast<int>(cones.size());
    const float z = static_cast<float>(ground.height(cone.position.x(), cone.position.y()));
    const float top = static_cast<float>(cone_shape(cone.cls).height_m + kTopSlackM) + z;
    cones.push_back({cone.id, k, x, y, footprint[k], top, true, z, Outline{}});
    ray_bounds.top_z = std::max(ray_bounds.top_z, top);
  }

  // every scenery object: its boxes, and a scene of its own holding the mesh of its other solids
  // about its place, labelled by its class (never a cone id)
  for (const tracks::SceneryObject& object : scenery) {
    const SceneryMesh mesh = build_scenery_mesh(object, config.cone_mesh_sides);
    const int k = static_cast<int>(class_scenes.size());
    float reach = 0.f, top = 0.f;
    for (const Eigen::Vector3f& v : mesh.vertices) {
      reach = std::max(reach, v.head<2>().norm());
      top = std::max(top, v.z());
    }
    class_boxes.push_back(boxes_of(object));
    tracks::SceneryObject round = object;
    std::erase_if(round.parts, [](const tracks::ScenePrimitive& p) {
      return p.shape == tracks::ScenePrimitive::Shape::kBox;
    });
    class_reflectivity.emplace_back();
    class_scenes.push_back(nullptr);
    if (!round.parts.empty()) {
      const SceneryMesh solids = build_scenery_mesh(round, config.cone_mesh_sides);
      for (float r : solids.reflectivity) class_reflectivity.back().push_back(r);
      class_scenes.back() = rtcNewScene(device);
      rtcSetSceneBuildQuality(class_scenes.back(), RTC_BUILD_QUALITY_HIGH);
      RTCGeometry geom = make_triangle_geometry(device, solids.vertices, solids.triangles);
      rtcAttachGeometry(class_scenes.back(), geom);
      rtcReleaseGeometry(geom);
      rtcCommitScene(class_scenes.back());
    }
    const float z = static_cast<float>(ground.height(object.pose.x, object.pose.y));
    cones.push_back({core::clutter_label(object.cls), k, static_cast<float>(object.pose.x),
                     static_cast<float>(object.pose.y), reach,
                     top + static_cast<float>(kTopSlackM) + z, true, z,
                     outline_of(mesh, static_cast<float>(object.pose.yaw))});
    ray_bounds.top_z = std::max(ray_bounds.top_z, top + static_cast<float>(kTopSlackM) + z);
  }
  // on ground that is not flat: the highest any of them reaches above the grade's plane (the
  // plane rises by up to its slope times the footprint's radius across one)
  if (uneven) {
    const float slope = std::hypot(grade_x, grade_y);
    stuff_above = band_hi;
    for (const SceneCone& c : cones)
      stuff_above = std::max(stuff_above, c.top_m - (grade_x * c.x + grade_y * c.y + grade_z0) +
                                              slope * c.footprint_m);
  }
  throw_on_device_error("building the scene");
}

void Lidar::Impl::throw_on_device_error(const char* what) const {
  const RTCError error = rtcGetDeviceError(device);
  if (error != RTC_ERROR_NONE)
    throw std::runtime_error(std::string("lidar: Embree error ") +
                             std::to_string(static_cast<int>(error)) + " while " + what);
}

Lidar::Lidar(const LidarConfig& config, const tracks::Track& track,
             const std::vector<tracks::SceneryObject>& scenery, const tracks::GroundModel& ground)
    : impl_(std::make_unique<Impl>()) {
  if (const std::string error = config.validate(); !error.empty())
    throw std::invalid_argument("lidar: " + error);
  impl_->config = config;
  impl_->build_beams();
  impl_->build_scene(track, scenery, ground);
}

Lidar::~Lidar() = default;
Lidar::Lidar(Lidar&&) noexcept = default;
Lidar& Lidar::operator=(Lidar&&) noexcept = default;

const LidarConfig& Lidar::config() const {
  return impl_->config;
}

void Lidar::set_cone_present(int cone_id, bool present) {
  const auto it = impl_->cone_index.find(cone_id);
  if (it == impl_->cone_index.end())
    throw std::out_of_range("lidar: no cone with id " + std::to_string(cone_id));
  impl_->cones[it->second].present = present;
}

bool Lidar::cone_present(int cone_id) const {
  const auto it = impl_->cone_index.find(cone_id);
  return it != impl_->cone_index.end() && impl_->cones[it->second].present;
}

core::TimeUs Lidar::column_time(core::TimeUs sweep_start, int column) const {
  return sweep_start + impl_->column_offset_us.at(static_cast<size_t>(column));
}

core::TimeUs Lidar::sweep_end(core::TimeUs sweep_start) const {
  return sweep_start + impl_->column_offset_us.back();
}

core::Pose3 Lidar::sensor_pose(const core::Pose3& vehicle_pose) const {
  return vehicle_pose.compose(impl_->config.mount);
}

LidarScan Lidar::sweep(core::TimeUs sweep_start, const PoseHistory& vehicle_poses,
                       core::Rng& rng) const {
  LidarScan scan;
  LidarNoise noise(rng);
  sweep_columns(sweep_start, 0, impl_->config.columns, vehicle_poses, noise, scan);
  return scan;
}

int Lidar::column_block() const {
  return kChunkColumns;
}

void Lidar::sweep_columns(core::TimeUs sweep_start, int column_begin, int column_end,
                          const PoseHistory& vehicle_poses, LidarNoise& noise,
                          LidarScan& scan) const {
  const Impl& im = *impl_;
  const LidarConfig& cfg = im.config;
  const int channel_count = static_cast<int>(im.channels.size());
  const float max_range = static_cast<float>(cfg.max_range_m);
  if (column_begin < 0 || column_end > cfg.columns || column_begin >= column_end)
    throw std::invalid_argument("lidar sweep: no columns [" + std::to_string(column_begin) + ", " +
                                std::to_string(column_end) + ") in a sweep of " +
                                std::to_string(cfg.columns));

  // the poses must span every column's firing time
  const core::TimeUs first = column_time(sweep_start, column_begin);
  const core::TimeUs end = column_time(sweep_start, column_end - 1);
  if (!vehicle_poses.covers(first, end)) {
    std::ostringstream msg;
    msg << "lidar sweep: the columns need poses over [" << first << ", " << end
        << "] us, the history covers ";
    if (vehicle_poses.empty())
      msg << "nothing";
    else
      msg << "[" << vehicle_poses.oldest() << ", " << vehicle_poses.newest() << "] us";
    throw std::invalid_argument(msg.str());
  }

  // the scan, its labels and the sensor poses at the first and last columns; room for a
  // return from every ray, so that the cloud never moves while it grows
  if (column_begin == 0) {
    scan.cloud.stamp = sweep_start;
    scan.cloud.points.reserve(static_cast<size_t>(cfg.columns) * channel_count);
    scan.labels.cone_id.reserve(scan.cloud.points.capacity());
    scan.labels.sensor_pose_start = sensor_pose(vehicle_poses.at(sweep_start));
  }
  if (column_end == cfg.columns) scan.labels.sensor_pose_end = sensor_pose(vehicle_poses.at(end));

  // the cones standing, for the test of which rays pass near one
  std::vector<const Impl::SceneCone*> standing;
  standing.reserve(im.cones.size());
  for (const Impl::SceneCone& cone : im.cones)
    if (cone.present) standing.push_back(&cone);
  std::vector<const Impl::SceneCone*> chunk_cones;
  std::vector<NearCone> column_cones;
  std::vector<int> near_ray;
  // the ground's intensity before the incidence and the range fall-off

  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  Impl::ChunkRays rays(static_cast<size_t>(kChunkColumns) * channel_count);
  std::array<Fan, kChunkColumns> column_fans;
  size_t pose_cursor = 0;
  const float range_sigma = static_cast<float>(cfg.range_noise_sigma_m);
  const float intensity_sigma = static_cast<float>(cfg.intensity_noise_sigma);
  const float min_range = static_cast<float>(cfg.min_range_m);
  const bool dropout = cfg.dropout_probability > 0.0;
  const auto dropout_probability = static_cast<float>(cfg.dropout_probability);
  const float range_growth = static_cast<float>(cfg.range_noise_growth);
  const float echo_merge = static_cast<float>(cfg.echo_merge_m);
  const float detection_scale = im.detection_scale;
  const float falloff = im.inverse_squared_falloff;

  for (int c0 = column_begin; c0 < column_end; c0 += kChunkColumns) {
    const int chunk = std::min(kChunkColumns, column_end - c0);

    // every ray of the chunk's columns from the sensor pose when its column fires, and each
    // column's fan of rays seen from above
    for (int j = 0; j < chunk; ++j) {
      const int c = c0 + j;
      const core::Pose3 vehicle =
          vehicle_poses.at(sweep_start + im.column_offset_us[c], pose_cursor);
      const Eigen::Matrix3d vehicle_rotation = vehicle.orientation.toRotationMatrix();
      const Eigen::Matrix3f rotation = (vehicle_rotation * im.mount_rotation).cast<float>();
      const Eigen::Vector3f origin =
          (vehicle.position + vehicle_rotation * im.mount_translation).cast<float>();
      // the column's horizontal heading and the sensor's up axis, in the track frame
      const Eigen::Vector3f heading =
          im.column_cos[c] * rotation.col(0) + im.column_sin[c] * rotation.col(1);
      const Eigen::Vector3f up = rotation.col(2);
      rays.origin[j] = origin;
      Fan& fan = column_fans[j];
      fan.origin_x = origin.x();
      fan.origin_y = origin.y();
      fan.reach = im.uneven ? im.trace_ground(rays, j * channel_count, origin, heading, up)
                            : im.cast_column(rays, j * channel_count, origin, heading, up);

      // headings of the beams turn monotonically with elevation: the lowest and the highest
      // bound the column's fan
      const float norm = std::sqrt(heading.x() * heading.x() + heading.y() * heading.y());
      fan.wide = !(norm > 0.5f);
      if (!fan.wide) {
        fan.axis_x = heading.x() / norm;
        fan.axis_y = heading.y() / norm;
        float tan_low = 0.f, tan_high = 0.f;
        const int low = j * channel_count, high = low + channel_count - 1;
        fan.wide =
            !tan_angle_to(rays.dir_x[low], rays.dir_y[low], fan.axis_x, fan.axis_y, tan_low) ||
            !tan_angle_to(rays.dir_x[high], rays.dir_y[high], fan.axis_x, fan.axis_y, tan_high);
        fan.tan_half_angle = std::max(tan_low, tan_high);
      }
    }

    // the chunk's fan: all its columns' rays, from their mean origin and mean heading
    Fan chunk_fan;
    float sum_x = 0.f, sum_y = 0.f, axis_x = 0.f, axis_y = 0.f;
    for (int j = 0; j < chunk; ++j) {
      sum_x += column_fans[j].origin_x;
      sum_y += column_fans[j].origin_y;
      axis_x += column_fans[j].axis_x;
      axis_y += column_fans[j].axis_y;
      chunk_fan.reach = std::max(chunk_fan.reach, column_fans[j].reach);
      chunk_fan.wide = chunk_fan.wide || column_fans[j].wide;
    }
    chunk_fan.origin_x = sum_x / static_cast<float>(chunk);
    chunk_fan.origin_y = sum_y / static_cast<float>(chunk);
    const float axis_norm = std::sqrt(axis_x * axis_x + axis_y * axis_y);
    chunk_fan.wide = chunk_fan.wide || !(axis_norm > 0.5f * static_cast<float>(chunk));
    if (!chunk_fan.wide) {
      chunk_fan.axis_x = axis_x / axis_norm;
      chunk_fan.axis_y = axis_y / axis_norm;
    }
    for (int j = 0; j < chunk; ++j) {
      const float ox = column_fans[j].origin_x - chunk_fan.origin_x;
      const float oy = column_fans[j].origin_y - chunk_fan.origin_y;
      chunk_fan.spread = std::max(chunk_fan.spread, std::sqrt(ox * ox + oy * oy));
    }
    // its half angle: each column's own plus the turn of its axis from the chunk's
    float cos_half = 1.f;
    for (int j = 0; j < chunk && !chunk_fan.wide; ++j) {
      const Fan& f = column_fans[j];
      const float cos_turn = f.axis_x * chunk_fan.axis_x + f.axis_y * chunk_fan.axis_y;
      const float sin_turn = std::abs(f.axis_x * chunk_fan.axis_y - f.axis_y * chunk_fan.axis_x);
      const float cos_own = 1.f / std::sqrt(1.f + f.tan_half_angle * f.tan_half_angle);
      const float sin_own = f.tan_half_angle * cos_own;
      cos_half = std::min(cos_half, cos_turn * cos_own - sin_turn * sin_own);
    }
    if (!(cos_half > 0.5f)) chunk_fan.wide = true;
    if (!chunk_fan.wide) chunk_fan.tan_half_angle = std::sqrt(1.f - cos_half * cos_half) / cos_half;

    // the cones the chunk's rays may pass near
    chunk_cones.clear();
    // (the footprint widened by the slack and half the spot: from the chunk's mean origin, the
    // columns' origins lie within its spread)
    const auto widened = [&](const Impl::SceneCone& cone, float from_x, float from_y,
                             float spread) {
      float r = cone.footprint_m + kFootprintSlackM;
      if (im.spot_slack_per_m > 0.f)
        r += im.spot_slack_per_m * (std::sqrt((cone.x - from_x) * (cone.x - from_x) +
                                              (cone.y - from_y) * (cone.y - from_y)) +
                                    spread + cone.footprint_m);
      return r;
    };
    for (const Impl::SceneCone* cone : standing)
      if (chunk_fan.may_meet(
              cone->x, cone->y,
              widened(*cone, chunk_fan.origin_x, chunk_fan.origin_y, chunk_fan.spread)))
        chunk_cones.push_back(cone);

    // each ray: the ground plane, and the meshes of the cones its column's fan may meet that
    // the ray itself passes near (all of them when the sensor is not above the ground)
    for (int j = 0; j < chunk; ++j) {
      const Eigen::Vector3f& origin = rays.origin[j];
      const int first = j * channel_count, last = first + channel_count;
      const bool anywhere = !(origin.z() > im.ray_bounds.floor_z);
      column_cones.clear();
      for (const Impl::SceneCone* cone : chunk_cones) {
        const float radius = widened(*cone, origin.x(), origin.y(), 0.f);
        if (column_fans[j].may_meet(cone->x, cone->y, radius))
          column_cones.push_back({cone->x - origin.x(), cone->y - origin.y(), radius, cone->top_m,
                                  static_cast<int>(cone - im.cones.data()),
                                  radius - cone->footprint_m});
      }

      // a column clear of every cone (most of them) meets only the ground, as cast already
      if (column_cones.empty() && !anywhere) continue;

      // which rays pass far from each cone, for all the column's rays at once (from under the
      // ground every ray is near them all)
      const size_t cone_count = column_cones.size();
      if (rays.far.size() < cone_count * channel_count) rays.far.resize(cone_count * channel_count);
      if (!anywhere) {
        for (int ch = 0; ch < channel_count; ++ch) {
          const float dx = rays.dir_x[first + ch], dy = rays.dir_y[first + ch];
          rays.drop[ch] = std::abs(rays.dir_z[first + ch]) / std::sqrt(dx * dx + dy * dy);
        }
        for (size_t k = 0; k < cone_count; ++k)
          far_from(channel_count, column_cones[k].x, column_cones[k].y, column_cones[k].radius,
                   origin.z(), column_cones[k].top_m, rays.dir_x.data() + first,
                   rays.dir_y.data() + first, rays.dir_z.data() + first, rays.drop.data(),
                   rays.length.data() + first, rays.far.data() + k * channel_count);
        // the rays far from them all (most) skip the cones one by one
        std::fill(rays.far_from_all.begin(), rays.far_from_all.begin() + channel_count, 1);
        for (size_t k = 0; k < cone_count; ++k)
          for (int ch = 0; ch < channel_count; ++ch)
            rays.far_from_all[ch] &= rays.far[k * channel_count + ch];
      }

      for (int slot = first; slot < last; ++slot) {
        // a ray that ends where it starts meets nothing
        const float length = rays.length[slot];
        if (!(length > 0.f)) {
          rays.label[slot] = kNoReturn;
          continue;
        }

        // the ground (as cast), then every cone the ray passes near, through its mesh: near when
        // the ray's track on the ground enters the cone's footprint and the ray is below the cone's
        // top somewhere over it (a steep ray, or one from under the ground, is near them all)
        const float dx = rays.dir_x[slot], dy = rays.dir_y[slot], dz = rays.dir_z[slot];
        const float squared = dx * dx + dy * dy;
        const bool near_all = anywhere || !(squared > 1e-6f);
        if (!near_all && rays.far_from_all[slot - first]) continue;
        // what the ray met before the cones (the ground, or nothing)
        const int behind_label = rays.label[slot];
        const float behind_range = behind_label == kNoReturn ? length : rays.range[slot];
        const float behind_energy = behind_label == kNoReturn ? 0.f : rays.intensity[slot];
        float reach = behind_range;
        bool traced = false;
        // the cones this ray passes near (so do its spot's outer thirds: the footprints are
        // widened by half the spot)
        near_ray.clear();
        for (size_t k = 0; k < cone_count; ++k) {
          const NearCone& cone = column_cones[k];
          if (!near_all) {
            if (rays.far[k * channel_count + (slot - first)]) continue;
            const float closest = (cone.x * dx + cone.y * dy) / squared;
            // the stretch of the ray over the footprint, and its lowest point there
            const float miss_squared =
                std::max(0.f, cone.x * cone.x + cone.y * cone.y - closest * closest * squared);
            const float half =
                std::sqrt(std::max(0.f, cone.radius * cone.radius - miss_squared) / squared);
            float enter = std::max(0.f, closest - half);
            float leave = std::min(length, closest + half);
            // (an object's outline, tighter than its disk, widened as the disk was)
            const Outline& outline = im.cones[cone.index].outline;
            if (outline.used &&
                !outline.narrow(cone.x, cone.y, dx, dy, cone.widening, enter, leave))
              continue;
            if (origin.z() + dz * (dz > 0.f ? enter : leave) > cone.top_m) continue;
            // (a cone: its plate and body, tighter than its footprint)
            const Impl::SceneCone& scene_cone = im.cones[cone.index];
            if (scene_cone.cls < kClassCount &&
                !im.cone_bounds[scene_cone.cls].may_meet(miss_squared, closest, squared,
                                                         origin.z() - scene_cone.z, dz, length,
                                                         cone.widening))
              continue;
          }
          im.hit_cone(im.cones[cone.index], origin, Eigen::Vector3f(dx, dy, dz), context, reach,
                      rays.label[slot], rays.intensity[slot]);
          near_ray.push_back(cone.index);
          traced = true;
        }
        if (traced) rays.range[slot] = reach;
        scan.stats.traced += traced;

        // a spot with a width near a cone: its outer thirds, beside the ray across the scan,
        // meet the cones (or what the ray met behind them), and the strongest echo is the return
        if (traced && im.spot_offset > 0.f && squared > 1e-6f) {
          std::array<Echo, 3> parts;
          parts[0] = {rays.range[slot], rays.label[slot],
                      rays.label[slot] == kNoReturn ? 0.f : rays.intensity[slot]};
          const float across = im.spot_offset / std::sqrt(squared);
          for (int side = 0; side < 2; ++side) {
            const float shift = side == 0 ? -across : across;
            // (the shift is across the ray's horizontal part: the length is the same for all)
            const Eigen::Vector3f dir =
                Eigen::Vector3f(dx - shift * dy, dy + shift * dx, dz) * im.spot_scale;
            Echo& part = parts[1 + side];
            part = {behind_range, behind_label, behind_energy};
            float part_reach = behind_range;
            for (int index : near_ray)
              im.hit_cone(im.cones[index], origin, dir, context, part_reach, part.label,
                          part.energy);
            part.range = part_reach;
          }
          Echo echo;
          if (strongest_echo(parts, echo_merge, echo)) {
            rays.range[slot] = echo.range;
            rays.label[slot] = echo.label;
            rays.intensity[slot] = echo.energy;
          } else {
            rays.label[slot] = kNoReturn;
          }
        }
      }
    }

    // the chunk's rays and returns
    const int chunk_rays = chunk * channel_count;
    int returns = 0;
    for (int slot = 0; slot < chunk_rays; ++slot) returns += rays.label[slot] != kNoReturn;
    scan.stats.rays += chunk_rays;
    scan.stats.hits += returns;

    // each return becomes a point, in firing order, unless a fault or the range window takes it
    int64_t dropped = 0, faded = 0, out_of_range = 0;
    NormalDraws draw(noise.normal);
    core::LidarPoint* point = rays.points.data();
    int* point_label = rays.point_label.data();
    for (int j = 0; j < chunk; ++j) {
      const int c = c0 + j;
      const float time_offset_s = static_cast<float>(core::to_seconds(im.column_offset_us[c]));
      const float column_cos = im.column_cos[c], column_sin = im.column_sin[c];
      const int first = j * channel_count;
      for (int ch = 0; ch < channel_count; ++ch) {
        const int label = rays.label[first + ch];
        if (label == kNoReturn) continue;

        // a return, unless the dropout takes it
        if (dropout && noise.uniform() < dropout_probability) {
          ++dropped;
          continue;
        }

        // a weak return fades: the probability of detecting it rises with its signal (the
        // surface's reflectivity times the cosine of incidence over the squared range) as
        // q^4 / (1 + q^4), q its signal over that of a 10 % target at detection_range_10pct_m
        const float range = rays.range[first + ch];
        if (detection_scale > 0.f) {
          const float reflected =
              rays.intensity[first + ch] / 255.f * (1.f + range * range * falloff);
          const float q = reflected * detection_scale / std::max(range * range, 1e-6f);
          const float q4 = (q * q) * (q * q);
          // (beyond q = 32 the return is lost with a probability under 1e-6: no draw)
          if (q < 32.f && noise.uniform() * (1.f + q4) > q4) {
            ++faded;
            continue;
          }
        }

        // range noise, growing with range; a noisy range outside the sensor's window is no return
        const float sigma = range_sigma + range_growth * range;
        const float measured = sigma > 0.f ? range + sigma * draw() : range;
        if (measured < min_range || measured > max_range) {
          ++out_of_range;
          continue;
        }
        float intensity = rays.intensity[first + ch];
        if (intensity_sigma > 0.f) intensity += intensity_sigma * draw();

        // the point in the sensor frame of its column
        const float horizontal = im.channel_cos[ch] * measured;
        *point++ = {horizontal * column_cos,       horizontal * column_sin,
                    im.channel_sin[ch] * measured, std::clamp(intensity, 0.f, 255.f),
                    static_cast<uint16_t>(ch),     time_offset_s};
        *point_label++ = label;
      }
    }
    draw.finish();
    scan.stats.dropped += dropped;
    scan.stats.faded += faded;
    scan.stats.out_of_range += out_of_range;

    // the chunk's points join the scan
    const size_t kept = static_cast<size_t>(point - rays.points.data());
    scan.cloud.points.insert(scan.cloud.points.end(), rays.points.begin(),
                             rays.points.begin() + kept);
    scan.labels.cone_id.insert(scan.labels.cone_id.end(), rays.point_label.begin(),
                               rays.point_label.begin() + kept);
  }
}

}  // namespace conesim::sensors
