#pragma once

#include <mujoco/mujoco.h>

#include <Eigen/Core>
#include <vector>

namespace conesim::sensors {

/// The points whose shadows bound a solid geom's shadow in light travelling along `light` (unit):
/// a box's corners, a cylinder's end rings, the outline a sphere, capsule or ellipsoid shows the
/// light, a mesh's vertices (from `model`, when the geom's mesh is one of its meshes). Appends
/// to `out`; nothing for planes, height fields and decorations.
void shadow_caster_points(const mjvGeom& geom, const mjModel* model, const Eigen::Vector3d& light,
                          std::vector<Eigen::Vector3d>& out);

/// The convex outline of the shadow `points` cast along `light` (unit) on the plane through
/// `on_ground` with unit normal `normal`, counter-clockwise seen from the normal's side; empty
/// when the light runs along the plane or away from its face (light . normal > -0.05) or the
/// shadow has no area.
std::vector<Eigen::Vector3d> cast_shadow(const std::vector<Eigen::Vector3d>& points,
                                         const Eigen::Vector3d& light,
                                         const Eigen::Vector3d& on_ground,
                                         const Eigen::Vector3d& normal);

}  // namespace conesim::sensors
