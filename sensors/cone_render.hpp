#pragma once
// Draws the track's cones into a MuJoCo abstract scene: each cone is one textured mesh geom
// (vehicle_models/cone_meshes.hpp) painted in its FSG colours. Cones are not in the physics
// model (docs/architecture.md), so they are appended after mjv_updateScene, every frame.

#include <mujoco/mujoco.h>

#include <Eigen/Core>
#include <array>
#include <functional>
#include <unordered_map>
#include <vector>

#include "core/cone.hpp"
#include "tracks/ground.hpp"
#include "tracks/scenery.hpp"
#include "tracks/track.hpp"

namespace conesim::sensors {

/// The scene geoms appended here say what they draw in their objid (objtype mjOBJ_UNKNOWN): a
/// cone's geom carries the cone's id (>= 0), a scenery object's solids kSceneryObjidBase minus
/// the object's index in the scenery list (the camera's segmentation render reads them).
inline constexpr int kSceneryObjidBase = -100;

/// True for a cone that has been knocked over and must not be drawn.
using IsKnocked = std::function<bool(int cone_id)>;

/// A conservative view volume (a pyramid with its apex at the eye) used to skip cones that no
/// camera of the rig can see.
struct ViewVolume {
  /// Eye position in the world, metres.
  Eigen::Vector3d eye = Eigen::Vector3d::Zero();
  /// Columns: the optical x (right), y (down) and z (forward) axes in the world.
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
  /// Tangents of the half field of view, horizontal and vertical.
  double tan_half_x = 1.0;
  double tan_half_y = 1.0;
  /// Nothing beyond this depth is drawn, metres.
  double far_m = 100.0;

  /// True unless a sphere at `centre` with `radius` lies wholly outside the volume.
  bool may_see(const Eigen::Vector3d& centre, double radius) const;
};

/// Appends cones to a scene. Built once per model and track; append() runs every frame.
class ConeSceneWriter {
 public:
  /// Finds the cone meshes and textures in the model and recovers the frame MuJoCo stored each
  /// mesh in (the compiler moves a mesh to its inertial frame). Throws std::runtime_error when
  /// the model lacks the assets of vehicle_models::cone_assets(). Each cone stands on the
  /// ground (its base at the ground's height under its centre).
  ConeSceneWriter(const mjModel* model, const std::vector<tracks::Cone>& cones,
                  const tracks::GroundModel& ground = {});

  /// Number of scene geoms that all cones together need (one per cone).
  int geom_count() const { return static_cast<int>(cones_.size()); }

  /// Appends every cone that is not knocked over and that the view volume may contain. Returns
  /// the number of cones that did not fit in the scene (zero when maxgeom is large enough).
  int append(mjvScene* scene, const IsKnocked& is_knocked, const ViewVolume& view) const;

  /// A box in the track frame (axes along the track's), by its centre and half sizes.
  struct Box {
    Eigen::Vector3d centre, half;
  };
  /// What stands in for a cone that append() drew (the geom's objid is its id) when it casts a
  /// shadow: its base plate, and its body as a box of its mean width. Empty for a geom that is
  /// none of these cones.
  std::vector<Box> shadow_boxes(const mjvGeom& geom) const;

 private:
  // how a cone class is drawn: its mesh (placed in the cone frame), texture and bounding sphere
  struct ConeModel {
    int mesh_id = -1;
    int texture_id = -1;
    Eigen::Vector3d mesh_position = Eigen::Vector3d::Zero();
    Eigen::Matrix3d mesh_rotation = Eigen::Matrix3d::Identity();
    double centre_height_m = 0.0;
    double bounding_radius_m = 0.0;
  };

  std::vector<tracks::Cone> cones_;
  // index into cones_ by cone id
  std::unordered_map<int, size_t> index_;
  // the ground's height under each cone, in cones_ order
  std::vector<double> base_z_;
  std::array<ConeModel, 5> models_;
};

/// Number of scene geoms the scenery objects need (one per solid).
int scenery_geom_count(const std::vector<tracks::SceneryObject>& scenery);

/// Appends the solids of every scenery object the view volume may contain, as plain coloured
/// boxes and cylinders (a frustum as the cylinder of its mean radius). They are drawn only: the
/// physics model never holds them; each stands on the ground at its place. Returns the number of
/// solids that did not fit in the scene.
int append_scenery(mjvScene* scene, const std::vector<tracks::SceneryObject>& scenery,
                   const ViewVolume& view, const tracks::GroundModel& ground = {});

}  // namespace conesim::sensors
