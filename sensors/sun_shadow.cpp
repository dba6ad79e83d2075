#include "sensors/sun_shadow.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>

namespace conesim::sensors {
namespace {

// points on a round outline (a circle's shadow is drawn as this many-sided polygon)
constexpr int kOutlineSides = 16;

// two unit vectors at right angles to unit `a` and to each other
void perpendiculars(const Eigen::Vector3d& a, Eigen::Vector3d& u, Eigen::Vector3d& v) {
  u = (std::abs(a.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY())
          .cross(a)
          .normalized();
  v = a.cross(u);
}

// the circle round `centre` spanned by u and v (each scaled by the circle's radius)
void circle(const Eigen::Vector3d& centre, const Eigen::Vector3d& u, const Eigen::Vector3d& v,
            std::vector<Eigen::Vector3d>& out) {
  for (int k = 0; k < kOutlineSides; ++k) {
    const double a = 2.0 * std::numbers::pi * k / kOutlineSides;
    out.push_back(centre + std::cos(a) * u + std::sin(a) * v);
  }
}

double cross2(const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return (a - o).x() * (b - o).y() - (a - o).y() * (b - o).x();
}

}  // namespace

void shadow_caster_points(const mjvGeom& g, const mjModel* model, const Eigen::Vector3d& light,
                          std::vector<Eigen::Vector3d>& out) {
  const Eigen::Vector3d pos(g.pos[0], g.pos[1], g.pos[2]);
  Eigen::Matrix3d axes;  // columns: the geom's axes in the world
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) axes(r, c) = g.mat[3 * r + c];
  const Eigen::Vector3d size(g.size[0], g.size[1], g.size[2]);
  Eigen::Vector3d u, v;
  switch (g.type) {
    case mjGEOM_BOX:
      for (int i = 0; i < 8; ++i)
        out.push_back(pos + axes * Eigen::Vector3d(i & 1 ? size.x() : -size.x(),
                                                   i & 2 ? size.y() : -size.y(),
                                                   i & 4 ? size.z() : -size.z()));
      return;
    case mjGEOM_CYLINDER:
      // radius, half length along the local z axis
      for (const double end : {-size.y(), size.y()})
        circle(pos + end * axes.col(2), size.x() * axes.col(0), size.x() * axes.col(1), out);
      return;
    case mjGEOM_SPHERE:
    case mjGEOM_CAPSULE:
      // each end sphere shows the light the great circle across it
      perpendiculars(light, u, v);
      for (const double end : g.type == mjGEOM_SPHERE ? std::vector<double>{0.0}
                                                      : std::vector<double>{-size.y(), size.y()})
        circle(pos + end * axes.col(2), size.x() * u, size.x() * v, out);
      return;
    case mjGEOM_ELLIPSOID: {
      // the unit sphere's great circle across the light's direction in the sphere's frame,
      // mapped onto the ellipsoid
      const Eigen::Matrix3d to_world = axes * size.asDiagonal();
      perpendiculars((to_world.inverse() * light).normalized(), u, v);
      circle(pos, to_world * u, to_world * v, out);
      return;
    }
    case mjGEOM_MESH: {
      if (!model || g.dataid < 0 || g.dataid >= model->nmesh) return;
      const int first = model->mesh_vertadr[g.dataid], n = model->mesh_vertnum[g.dataid];
      for (int i = first; i < first + n; ++i)
        out.push_back(pos + axes * Eigen::Vector3d(model->mesh_vert[3 * i],
                                                   model->mesh_vert[3 * i + 1],
                                                   model->mesh_vert[3 * i + 2]));
      return;
    }
    default:
      return;
  }
}

std::vector<Eigen::Vector3d> cast_shadow(const std::vector<Eigen::Vector3d>& points,
                                         const Eigen::Vector3d& light,
                                         const Eigen::Vector3d& on_ground,
                                         const Eigen::Vector3d& normal) {
  const double dn = light.dot(normal);
  if (!(dn < -0.05) || points.size() < 3) return {};
  // p -> p - ((p - q).n / d.n) d, in coordinates along two axes of the plane
  Eigen::Vector3d e1, e2;
  perpendiculars(normal, e1, e2);
  std::vector<Eigen::Vector2d> flat;
  flat.reserve(points.size());
  for (const Eigen::Vector3d& p : points) {
    const Eigen::Vector3d s = p - ((p - on_ground).dot(normal) / dn) * light - on_ground;
    flat.emplace_back(s.dot(e1), s.dot(e2));
  }
  // the convex hull (Andrew's monotone chain), counter-clockwise about e1 x e2 = normal
  std::sort(flat.begin(), flat.end(), [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  });
  std::vector<Eigen::Vector2d> hull(2 * flat.size());
  size_t k = 0;
  for (size_t i = 0; i < flat.size(); ++i) {
    while (k >= 2 && cross2(hull[k - 2], hull[k - 1], flat[i]) <= 0.0) --k;
    hull[k++] = flat[i];
  }
  for (size_t i = flat.size() - 1, lower = k + 1; i-- > 0;) {
    while (k >= lower && cross2(hull[k - 2], hull[k - 1], flat[i]) <= 0.0) --k;
    hull[k++] = flat[i];
  }
  hull.resize(k > 0 ? k - 1 : 0);
  if (hull.size() < 3) return {};
  std::vector<Eigen::Vector3d> outline;
  outline.reserve(hull.size());
  for (const Eigen::Vector2d& h : hull) outline.push_back(on_ground + h.x() * e1 + h.y() * e2);
  return outline;
}

}  // namespace conesim::sensors
