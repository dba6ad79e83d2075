#pragma once
// Triangle meshes of the scenery objects (tracks/scenery.hpp) for the LiDAR's Embree scene.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <vector>

#include "tracks/scenery.hpp"

namespace conesim::sensors {

/// An object's solids as triangles, turned by the object's heading and placed relative to its
/// position (x, y) on the ground, with each triangle's reflectivity.
struct SceneryMesh {
  std::vector<Eigen::Vector3f> vertices;
  std::vector<std::array<uint32_t, 3>> triangles;
  std::vector<float> reflectivity;
};

/// Tessellates an object; round solids get `sides` sides (vertices on the exact radius).
SceneryMesh build_scenery_mesh(const tracks::SceneryObject& object, int sides);

}  // namespace conesim::sensors
