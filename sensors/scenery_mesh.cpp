#include "sensors/scenery_mesh.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>

namespace conesim::sensors {

namespace {

using Shape = tracks::ScenePrimitive::Shape;

// appends a quad (a, b, c, d counter-clockwise) as two triangles
void quad(SceneryMesh& m, uint32_t a, uint32_t b, uint32_t c, uint32_t d, float reflectivity) {
  m.triangles.push_back({a, b, c});
  m.triangles.push_back({a, c, d});
  m.reflectivity.push_back(reflectivity);
  m.reflectivity.push_back(reflectivity);
}

}  // namespace

SceneryMesh build_scenery_mesh(const tracks::SceneryObject& object, int sides) {
  SceneryMesh m;
  // object frame -> the frame at the object's place, turned by its heading
  const Eigen::Matrix3d turn =
      object.tilt *
      Eigen::AngleAxisd(object.pose.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  for (const tracks::ScenePrimitive& p : object.parts) {
    const auto place = [&](const Eigen::Vector3d& local) {
      return (turn * (p.centre + p.rotation * local)).cast<float>().eval();
    };
    const auto first = static_cast<uint32_t>(m.vertices.size());
    const auto r = static_cast<float>(p.reflectivity);
    if (p.shape == Shape::kBox) {
      for (int i = 0; i < 8; ++i)
        m.vertices.push_back(
            place({i & 1 ? p.size.x() : -p.size.x(), i & 2 ? p.size.y() : -p.size.y(),
                   i & 4 ? p.size.z() : -p.size.z()}));
      // the six faces (corner i has x from bit 0, y from bit 1, z from bit 2)
      constexpr std::array<std::array<uint32_t, 4>, 6> kFaces = {
          {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}}};
      for (const auto& f : kFaces)
        quad(m, first + f[0], first + f[1], first + f[2], first + f[3], r);
      continue;
    }
    // a cylinder or a frustum about the local z axis: a ring at each end, and the end discs
    const double r0 = p.size.x(), r1 = p.shape == Shape::kCylinder ? p.size.x() : p.size.y();
    for (int end = 0; end < 2; ++end)
      for (int k = 0; k < sides; ++k) {
        const double a = 2.0 * std::numbers::pi * k / sides;
        const double radius = end == 0 ? r0 : r1;
        m.vertices.push_back(place(
            {radius * std::cos(a), radius * std::sin(a), end == 0 ? -p.size.z() : p.size.z()}));
      }
    const auto n = static_cast<uint32_t>(sides);
    for (uint32_t k = 0; k < n; ++k) {
      const uint32_t next = (k + 1) % n;
      quad(m, first + k, first + next, first + n + next, first + n + k, r);
    }
    // the end discs as fans round each ring's first vertex
    for (uint32_t end = 0; end < 2; ++end)
      for (uint32_t k = 1; k + 1 < n; ++k) {
        m.triangles.push_back({first + end * n, first + end * n + k, first + end * n + k + 1});
        m.reflectivity.push_back(r);
      }
  }
  return m;
}

}  // namespace conesim::sensors
