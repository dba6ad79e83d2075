#include "sensors/cone_render.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

#include "core/cone_geometry.hpp"
#include "vehicle_models/cone_meshes.hpp"

namespace conesim::sensors {

namespace {

// largest distance between a vertex as authored and as MuJoCo stored it, after the fit
constexpr double kMeshFitToleranceM = 1e-4;

// appends a geom that is drawn only (no object of the model behind it), lit with `shine` as
// its specular and shininess, tagged with what it draws (kSceneryObjidBase), and returns it
mjvGeom* append_static_geom(mjvScene* scene, int type, const mjtNum size[3], const mjtNum pos[3],
                            const mjtNum mat[9], const float rgba[4], float shine, int tag) {
  mjvGeom* g = scene->geoms + scene->ngeom;
  mjv_initGeom(g, type, size, pos, mat, rgba);
  g->category = mjCAT_STATIC;
  g->objtype = mjOBJ_UNKNOWN;
  g->objid = tag;
  g->segid = scene->ngeom;
  g->specular = shine;
  g->shininess = shine;
  g->reflectance = 0.0f;
  ++scene->ngeom;
  return g;
}

// the rigid transform that maps the mesh as MuJoCo stores it onto the mesh as authored
Eigen::Isometry3d stored_to_authored(const mjModel* m, int mesh_id,
                                     const vehicle_models::TriangleMesh& authored) {
  const int n = m->mesh_vertnum[mesh_id];
  if (n != authored.vertex_count())
    throw std::runtime_error("cone mesh " + std::to_string(mesh_id) + " has " + std::to_string(n) +
                             " vertices in the model, expected " +
                             std::to_string(authored.vertex_count()));
  Eigen::Matrix3Xd stored(3, n), original(3, n);
  const float* v = m->mesh_vert + 3 * m->mesh_vertadr[mesh_id];
  for (int i = 0; i < n; ++i) {
    stored.col(i) << v[3 * i], v[3 * i + 1], v[3 * i + 2];
    original.col(i) << authored.vertices[3 * i], authored.vertices[3 * i + 1],
        authored.vertices[3 * i + 2];
  }
  const Eigen::Isometry3d t(Eigen::umeyama(stored, original, false));
  const double error = ((t * stored) - original).colwise().norm().maxCoeff();
  if (error > kMeshFitToleranceM)
    throw std::runtime_error("cone mesh " + std::to_string(mesh_id) +
                             " does not match its authored shape");
  return t;
}

// id of a named asset; throws with a hint when the model was not built with the cone assets
int require_asset(const mjModel* m, int type, const std::string& name) {
  const int id = mj_name2id(m, type, name.c_str());
  if (id < 0)
    throw std::runtime_error("MuJoCo model has no cone asset " + name +
                             " (build it with vehicle_models::build_mjcf)");
  return id;
}

}  // namespace

bool ViewVolume::may_see(const Eigen::Vector3d& centre, double radius) const {
  // the sphere in the optical frame: behind the eye or beyond far is out
  const Eigen::Vector3d p = axes.transpose() * (centre - eye);
  if (p.z() < -radius || p.z() > far_m + radius) return false;

  // distance to each side plane of the pyramid (normals pointing out)
  const auto outside = [&](double lateral, double tan_half) {
    return (std::abs(lateral) - tan_half * p.z()) / std::sqrt(1.0 + tan_half * tan_half) > radius;
  };
  return !outside(p.x(), tan_half_x) && !outside(p.y(), tan_half_y);
}

ConeSceneWriter::ConeSceneWriter(const mjModel* model, const std::vector<tracks::Cone>& cones,
                                 const tracks::GroundModel& ground)
    : cones_(cones) {
  for (const tracks::Cone& cone : cones_) {
    index_[cone.id] = base_z_.size();
    base_z_.push_back(ground.height(cone.position.x(), cone.position.y()));
  }
  for (int c = 0; c < static_cast<int>(models_.size()); ++c) {
    const auto cls = static_cast<core::ConeClass>(c);
    const core::ConeGeometry shape = core::cone_geometry(cls);
    const bool big = cls == core::ConeClass::kOrangeBig;
    ConeModel& cone = models_[c];

    // the mesh of the cone's size, placed where the authored mesh was; the class's texture
    cone.mesh_id = require_asset(model, mjOBJ_MESH, vehicle_models::cone_mesh_name(big));
    cone.texture_id = require_asset(model, mjOBJ_TEXTURE, vehicle_models::cone_texture_name(cls));
    const Eigen::Isometry3d frame =
        stored_to_authored(model, cone.mesh_id, vehicle_models::cone_mesh(shape));
    cone.mesh_position = frame.translation();
    cone.mesh_rotation = frame.linear();

    // bounding sphere about the middle of the cone
    cone.centre_height_m = 0.5 * shape.height_m;
    cone.bounding_radius_m =
        std::hypot(0.5 * shape.height_m, 0.5 * std::numbers::sqrt2 * shape.base_width_m);
  }
}

int ConeSceneWriter::append(mjvScene* scene, const IsKnocked& is_knocked,
                            const ViewVolume& view) const {
  constexpr float kWhite[4] = {1.f, 1.f, 1.f, 1.f};  // the texture carries the colour
  int dropped = 0;
  for (size_t k = 0; k < cones_.size(); ++k) {
    // skip knocked cones and those no camera can see
    const tracks::Cone& cone = cones_[k];
    const ConeModel& model = models_[static_cast<size_t>(cone.cls)];
    const Eigen::Vector3d base(cone.position.x(), cone.position.y(), base_z_[k]);
    if (is_knocked && is_knocked(cone.id)) continue;
    if (!view.may_see(base + Eigen::Vector3d(0.0, 0.0, model.centre_height_m),
                      model.bounding_radius_m))
      continue;
    if (scene->ngeom >= scene->maxgeom) {
      ++dropped;
      continue;
    }

    // one textured mesh geom, upright at the cone's base, plate edges along the track axes
    mjtNum size[3] = {1.0, 1.0, 1.0}, pos[3], mat[9];
    for (int i = 0; i < 3; ++i) {
      pos[i] = base[i] + model.mesh_position[i];
      for (int j = 0; j < 3; ++j) mat[3 * i + j] = model.mesh_rotation(i, j);
    }
    mjvGeom* g = append_static_geom(scene, mjGEOM_MESH, size, pos, mat, kWhite, 0.2f, cone.id);
    // MuJoCo 2.2 numbers mesh display lists in pairs (mesh, convex hull): 2 x mesh id
    g->dataid = 2 * model.mesh_id;
    g->texid = model.texture_id;
    g->texcoord = 1;
  }
  return dropped;
}

std::vector<ConeSceneWriter::Box> ConeSceneWriter::shadow_boxes(const mjvGeom& geom) const {
  if (geom.objtype != mjOBJ_UNKNOWN || geom.type != mjGEOM_MESH) return {};
  const auto it = index_.find(geom.objid);
  if (it == index_.end()) return {};
  const tracks::Cone& cone = cones_[it->second];
  const core::ConeGeometry shape = core::cone_geometry(cone.cls);
  // the body's mean radius is about 0.27 of the base's width for both sizes of cone
  constexpr double kPlateM = 0.01, kBodyShare = 0.27;
  const Eigen::Vector3d base(cone.position.x(), cone.position.y(), base_z_[it->second]);
  const double w = 0.5 * shape.base_width_m, h = shape.height_m;
  return {{base + Eigen::Vector3d(0.0, 0.0, 0.5 * kPlateM), {w, w, 0.5 * kPlateM}},
          {base + Eigen::Vector3d(0.0, 0.0, 0.5 * h),
           {kBodyShare * shape.base_width_m, kBodyShare * shape.base_width_m, 0.5 * h}}};
}

int scenery_geom_count(const std::vector<tracks::SceneryObject>& scenery) {
  int n = 0;
  for (const tracks::SceneryObject& o : scenery) n += static_cast<int>(o.parts.size());
  return n;
}

int append_scenery(mjvScene* scene, const std::vector<tracks::SceneryObject>& scenery,
                   const ViewVolume& view, const tracks::GroundModel& ground) {
  int dropped = 0;
  for (size_t index = 0; index < scenery.size(); ++index) {
    const tracks::SceneryObject& object = scenery[index];
    const Eigen::Vector3d base(object.pose.x, object.pose.y,
                               ground.height(object.pose.x, object.pose.y));
    const double half_height = 0.5 * object.height_m;
    if (!view.may_see(base + Eigen::Vector3d(0.0, 0.0, half_height),
                      std::hypot(object.radius_m, half_height)))
      continue;
    const Eigen::Matrix3d turn =
        object.tilt *
        Eigen::AngleAxisd(object.pose.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    for (const tracks::ScenePrimitive& p : object.parts) {
      if (scene->ngeom >= scene->maxgeom) {
        ++dropped;
        continue;
      }
      const Eigen::Vector3d centre = base + turn * p.centre;
      const Eigen::Matrix3d axes = turn * p.rotation;
      mjtNum size[3], pos[3], mat[9];
      for (int i = 0; i < 3; ++i) {
        pos[i] = centre[i];
        for (int j = 0; j < 3; ++j) mat[3 * i + j] = axes(i, j);
      }
      int type = mjGEOM_BOX;
      if (p.shape == tracks::ScenePrimitive::Shape::kBox) {
        for (int i = 0; i < 3; ++i) size[i] = p.size[i];
      } else {
        // MuJoCo's cylinder: radius, half length along its z axis
        type = mjGEOM_CYLINDER;
        const bool frustum = p.shape == tracks::ScenePrimitive::Shape::kFrustum;
        size[0] = frustum ? 0.5 * (p.size.x() + p.size.y()) : p.size.x();
        size[1] = p.size.z();
        size[2] = 0.0;
      }
      append_static_geom(scene, type, size, pos, mat, p.rgba.data(), 0.1f,
                         kSceneryObjidBase - static_cast<int>(index));
    }
  }
  return dropped;
}

}  // namespace conesim::sensors
