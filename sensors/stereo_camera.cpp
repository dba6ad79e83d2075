#include "sensors/stereo_camera.hpp"

#include <GL/gl.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace conesim::sensors {

namespace {

constexpr double kDegToRad = std::numbers::pi / 180.0;
// scene geoms for the car and MuJoCo's own decorations, beyond the cones
constexpr int kSpareGeoms = 200;
// the asphalt's mean colour (the MJCF's asphalt texture) and the sky's, as the MJCF's skybox
constexpr float kAsphalt[4] = {0.30f, 0.30f, 0.32f, 1.0f};
constexpr double kSkyZenith[3] = {0.55, 0.70, 0.90};
constexpr double kSkyHorizon[3] = {0.85, 0.90, 0.95};
// elevation (sine) above which the sky has its zenith colour
constexpr double kSkyGradientSine = 0.5;
// half size of the ground square in far distances: the far plane, not the square's edge, then
// bounds the ground for fields of view up to 150 degrees (1 / cos 75 deg = 3.9)
constexpr double kGroundHalfSizeInFar = 4.0;

// vehicle frame from the optical frame of a camera pitched down by pitch_rad
Eigen::Quaterniond vehicle_from_optical(double pitch_rad) {
  Eigen::Matrix3d level;
  level.col(0) << 0.0, -1.0, 0.0;  // optical x: right
  level.col(1) << 0.0, 0.0, -1.0;  // optical y: down
  level.col(2) << 1.0, 0.0, 0.0;   // optical z: forward
  return Eigen::Quaterniond(Eigen::AngleAxisd(pitch_rad, Eigen::Vector3d::UnitY()) * level);
}

// half height of the near-plane window for a configuration, as the float MuJoCo uses
float frustum_half_height(const StereoCameraConfig& c) {
  const double tan_half_x = std::tan(0.5 * c.horizontal_fov_deg * kDegToRad);
  return static_cast<float>(c.near_m * tan_half_x * c.height_px / c.width_px);
}

}  // namespace

std::string StereoCameraConfig::validate() const {
  if (width_px < 16 || width_px > 4096) return "width_px: must be 16-4096";
  if (height_px < 16 || height_px > 4096) return "height_px: must be 16-4096";
  if (!(horizontal_fov_deg >= 10.0 && horizontal_fov_deg <= 150.0))
    return "horizontal_fov_deg: must be 10-150";
  if (!(baseline_m > 0.0 && baseline_m <= 2.0)) return "baseline_m: must be in (0, 2]";
  if (!std::isfinite(mount_x_m)) return "mount_x_m: must be finite";
  if (!std::isfinite(mount_y_m)) return "mount_y_m: must be finite";
  if (!(mount_z_m > 0.0 && mount_z_m < 5.0)) return "mount_z_m: must be in (0, 5)";
  if (!(std::abs(pitch_down_deg) <= 60.0)) return "pitch_down_deg: must be within +-60";
  if (!(near_m >= 0.01 && near_m <= 10.0)) return "near_m: must be 0.01-10";
  if (!(far_m > 10.0 * near_m && far_m <= 2000.0))
    return "far_m: must exceed 10 x near_m and be at most 2000";
  if (!(light_ambient >= 0.0 && light_ambient <= 1.0)) return "light_ambient: must be 0-1";
  if (!(light_diffuse >= 0.0 && light_diffuse <= 1.0)) return "light_diffuse: must be 0-1";
  return response.validate();
}

core::CameraIntrinsics stereo_intrinsics(const StereoCameraConfig& c) {
  // MuJoCo sets the frustum half width to match the viewport aspect, so fx = fy
  const double half_height = frustum_half_height(c);
  const double near = static_cast<float>(c.near_m);
  core::CameraIntrinsics k;
  k.width_px = c.width_px;
  k.height_px = c.height_px;
  k.fy = 0.5 * c.height_px * near / half_height;
  k.fx = k.fy;
  k.cx = 0.5 * c.width_px - 0.5;
  k.cy = 0.5 * c.height_px - 0.5;
  return k;
}

core::Pose3 stereo_camera_in_vehicle(const StereoCameraConfig& c, bool left) {
  // the optical centres sit half a baseline either side of the mount, along the vehicle y axis
  const double side = (left ? 0.5 : -0.5) * c.baseline_m;
  return {{c.mount_x_m, c.mount_y_m + side, c.mount_z_m},
          vehicle_from_optical(c.pitch_down_deg * kDegToRad)};
}

StereoCamera::StereoCamera(const StereoCameraConfig& config, const mjModel* model,
                           const tracks::Track& track,
                           const std::vector<tracks::SceneryObject>& scenery,
                           const tracks::GroundModel& ground)
    : config_(config),
      model_(model),
      scenery_(scenery),
      ground_(ground),
      response_filter_(config.response, config.noise_seed) {
  // check the configuration against itself and the model's offscreen buffer
  if (const std::string error = config.validate(); !error.empty())
    throw std::invalid_argument("stereo camera: " + error);
  if (config.width_px > model->vis.global.offwidth)
    throw std::invalid_argument("stereo camera: width_px: exceeds the model's offscreen width " +
                                std::to_string(model->vis.global.offwidth));
  if (config.height_px > model->vis.global.offheight)
    throw std::invalid_argument("stereo camera: height_px: exceeds the model's offscreen height " +
                                std::to_string(model->vis.global.offheight));

  // calibration, fixed for the camera's life
  intrinsics_ = stereo_intrinsics(config);
  left_in_vehicle_ = stereo_camera_in_vehicle(config, true);
  right_in_vehicle_ = stereo_camera_in_vehicle(config, false);
  frustum_half_height_ = frustum_half_height(config);

  // GL: one OSMesa context per camera, MuJoCo's render context drawing off-screen
  gl_ = std::make_unique<OsMesaContext>(config.width_px, config.height_px);
  mjr_defaultContext(&context_);
  mjr_makeContext(model, &context_, mjFONTSCALE_50);
  mjr_setBuffer(mjFB_OFFSCREEN, &context_);
  if (context_.currentBuffer != mjFB_OFFSCREEN) {
    mjr_freeContext(&context_);
    throw std::runtime_error("stereo camera: MuJoCo has no offscreen buffer under OSMesa");
  }

  // the abstract scene: the car's world plus room for every cone's geoms
  cones_ = std::make_unique<ConeSceneWriter>(model, track.cones, ground);
  mjv_defaultScene(&scene_);
  mjv_makeScene(model, &scene_,
                model->ngeom + kSpareGeoms + cones_->geom_count() + scenery_geom_count(scenery));
  scene_.flags[mjRND_SHADOW] = 0;
  scene_.flags[mjRND_REFLECTION] = 0;
  // the sky is painted after reading back (llvmpipe's cube-mapped skybox costs 3 ms a frame)
  scene_.flags[mjRND_SKYBOX] = 0;

  // what MuJoCo adds itself: geoms only, no sites, frames or labels
  mjv_defaultOption(&option_);
  for (int g = 0; g < mjNGROUP; ++g) option_.sitegroup[g] = 0;
  mjv_defaultPerturb(&perturb_);
  mjv_defaultCamera(&free_camera_);
  free_camera_.type = mjCAMERA_FREE;

  // scratch state, so that the caller's mjData stays untouched
  scratch_ = mj_makeData(model);
  rgba_scratch_.resize(4 * static_cast<size_t>(config.width_px) * config.height_px);
  depth_scratch_.resize(static_cast<size_t>(config.width_px) * config.height_px);

  // ray lengths for painting the sky by elevation
  inverse_ray_length_.resize(depth_scratch_.size());
  for (int r = 0; r < config.height_px; ++r)
    for (int c = 0; c < config.width_px; ++c) {
      const double x = (c - intrinsics_.cx) / intrinsics_.fx;
      const double y = (r - intrinsics_.cy) / intrinsics_.fy;
      inverse_ray_length_[static_cast<size_t>(r) * config.width_px + c] =
          static_cast<float>(1.0 / std::sqrt(1.0 + x * x + y * y));
    }
}

StereoCamera::~StereoCamera() {
  // MuJoCo frees GL objects of the current context: ours (if that fails, GL leaks, nothing worse)
  gl_->try_make_current();
  mjr_freeContext(&context_);
  mjv_freeScene(&scene_);
  mj_deleteData(scratch_);
}

void StereoCamera::render(const mjData* data, const core::Pose3& vehicle_in_track,
                          core::TimeUs stamp, const IsKnocked& is_knocked, bool with_depth,
                          core::StereoFrame& frame, core::StereoLabels& labels) {
  gl_->make_current();

  // pose the car: copy its configuration and recompute positions in the scratch data
  mju_copy(scratch_->qpos, data->qpos, model_->nq);
  mj_kinematics(model_, scratch_);
  mj_camlight(model_, scratch_);

  // the car's world, then the cones that either camera may see
  mjv_updateScene(model_, scratch_, &option_, &perturb_, &free_camera_, mjCAT_ALL, &scene_);
  labels.left_in_track = vehicle_in_track.compose(left_in_vehicle_);
  labels.right_in_track = vehicle_in_track.compose(right_in_vehicle_);
  dropped_geoms_ += cones_->append(&scene_, is_knocked, rig_view(labels.left_in_track));
  dropped_geoms_ += append_scenery(&scene_, scenery_, rig_view(labels.left_in_track), ground_);
  simplify_ground(0.5 * (labels.left_in_track.position + labels.right_in_track.position));

  // one pass per eye; depth only for the left one and only on request
  render_eye(labels.left_in_track, frame.left, with_depth ? &frame.left_depth_m : nullptr);
  render_eye(labels.right_in_track, frame.right, nullptr);
  // the sensor's response, its noise drawn afresh for each frame and eye
  response_filter_.apply(frame.left, 2 * static_cast<uint64_t>(stamp));
  response_filter_.apply(frame.right, 2 * static_cast<uint64_t>(stamp) + 1);
  if (!with_depth) frame.left_depth_m.clear();
  last_left_in_track_ = labels.left_in_track;
  rendered_ = true;

  // calibration travels with the frame
  frame.stamp = stamp;
  frame.intrinsics = intrinsics_;
  frame.left_in_vehicle = left_in_vehicle_;
  frame.right_in_vehicle = right_in_vehicle_;
  frame.baseline_m = config_.baseline_m;
}

void StereoCamera::render_segmentation(SegmentationImage& out) {
  if (!rendered_) throw std::logic_error("stereo camera: render_segmentation before render");
  gl_->make_current();
  const int w = config_.width_px, h = config_.height_px;

  // what each scene geom shows, and its segmentation id: MuJoCo paints a geom in the colour
  // segid + 1 (red the low byte) with lighting, textures and blending off
  const int ground_geom = mj_name2id(model_, mjOBJ_GEOM, "ground");
  std::vector<int32_t> shows(static_cast<size_t>(scene_.ngeom));
  std::vector<int> saved_segid(static_cast<size_t>(scene_.ngeom));
  for (int i = 0; i < scene_.ngeom; ++i) {
    mjvGeom& g = scene_.geoms[i];
    if (g.objtype == mjOBJ_GEOM)
      shows[static_cast<size_t>(i)] =
          g.objid == ground_geom ? SegmentationImage::kGround : SegmentationImage::kCar;
    else if (g.objtype == mjOBJ_UNKNOWN && (g.objid >= 0 || g.objid <= kSceneryObjidBase))
      shows[static_cast<size_t>(i)] = g.objid;
    else
      shows[static_cast<size_t>(i)] = SegmentationImage::kNothing;
    saved_segid[static_cast<size_t>(i)] = g.segid;
    g.segid = i;
  }
  const mjtByte saved_segment = scene_.flags[mjRND_SEGMENT];
  const mjtByte saved_idcolor = scene_.flags[mjRND_IDCOLOR];
  scene_.flags[mjRND_SEGMENT] = 1;
  scene_.flags[mjRND_IDCOLOR] = 1;

  // the left eye, as render() drew it
  aim(last_left_in_track_);
  const mjrRect viewport{0, 0, w, h};
  mjr_render(viewport, &scene_, &context_);
  glReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, rgba_scratch_.data());
  scene_.flags[mjRND_SEGMENT] = saved_segment;
  scene_.flags[mjRND_IDCOLOR] = saved_idcolor;
  for (int i = 0; i < scene_.ngeom; ++i) scene_.geoms[i].segid = saved_segid[static_cast<size_t>(i)];

  // decode, flipping rows to top to bottom; colour 0 (the cleared background) is the sky
  out.width_px = w;
  out.height_px = h;
  out.object.resize(static_cast<size_t>(w) * h);
  for (int r = 0; r < h; ++r) {
    const uint8_t* src = rgba_scratch_.data() + 4 * static_cast<size_t>(h - 1 - r) * w;
    int32_t* dst = out.object.data() + static_cast<size_t>(r) * w;
    for (int c = 0; c < w; ++c, src += 4) {
      const int id = (src[0] | (src[1] << 8) | (src[2] << 16)) - 1;
      dst[c] = id >= 0 && id < scene_.ngeom ? shows[static_cast<size_t>(id)]
                                            : SegmentationImage::kNothing;
    }
  }
}

ViewVolume StereoCamera::rig_view(const core::Pose3& left_in_track) const {
  // one pyramid holding both cameras' ones: its apex sits behind the midpoint of the optical
  // centres, far enough back that its sides pass through both centres
  ViewVolume v;
  v.axes = left_in_track.orientation.toRotationMatrix();
  v.tan_half_x = std::tan(0.5 * config_.horizontal_fov_deg * kDegToRad);
  v.tan_half_y = v.tan_half_x * config_.height_px / config_.width_px;
  const double setback_m = 0.5 * config_.baseline_m / v.tan_half_x;
  v.eye =
      left_in_track.position + 0.5 * config_.baseline_m * v.axes.col(0) - setback_m * v.axes.col(2);
  v.far_m = config_.far_m + setback_m;
  return v;
}

void StereoCamera::simplify_ground(const Eigen::Vector3d& centre) {
  // MuJoCo draws an infinite plane as a 200 x 200 grid with a texture whose grain is below a
  // pixel from the car: a square of 4 x 4 quads in the mean colour looks the same and costs less
  for (int i = 0; i < scene_.ngeom; ++i) {
    mjvGeom& g = scene_.geoms[i];
    if (g.objtype != mjOBJ_GEOM || g.type != mjGEOM_PLANE || g.size[0] > 0.f || g.size[1] > 0.f)
      continue;
    g.dataid = -1;
    g.texid = -1;
    g.size[0] = g.size[1] = static_cast<float>(kGroundHalfSizeInFar * config_.far_m);
    g.pos[0] = static_cast<float>(centre.x());
    g.pos[1] = static_cast<float>(centre.y());
    std::copy(std::begin(kAsphalt), std::end(kAsphalt), g.rgba);
  }
}

void StereoCamera::aim(const core::Pose3& eye_in_track) {
  const Eigen::Vector3d forward = eye_in_track.orientation * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d up = eye_in_track.orientation * -Eigen::Vector3d::UnitY();

  // both GL cameras at the eye (stereo is off, MuJoCo averages them), symmetric frustum
  for (mjvGLCamera& cam : scene_.camera) {
    for (int i = 0; i < 3; ++i) {
      cam.pos[i] = static_cast<float>(eye_in_track.position[i]);
      cam.forward[i] = static_cast<float>(forward[i]);
      cam.up[i] = static_cast<float>(up[i]);
    }
    cam.frustum_center = 0.f;
    cam.frustum_bottom = -frustum_half_height_;
    cam.frustum_top = frustum_half_height_;
    cam.frustum_near = static_cast<float>(config_.near_m);
    cam.frustum_far = static_cast<float>(config_.far_m);
  }

  // the headlight shines from the eye along the optical axis
  for (int l = 0; l < scene_.nlight; ++l) {
    mjvLight& light = scene_.lights[l];
    if (!light.headlight) continue;
    for (int i = 0; i < 3; ++i) {
      light.pos[i] = static_cast<float>(eye_in_track.position[i]);
      light.dir[i] = static_cast<float>(forward[i]);
      light.ambient[i] = static_cast<float>(config_.light_ambient);
      light.diffuse[i] = static_cast<float>(config_.light_diffuse);
    }
  }
}

void StereoCamera::render_eye(const core::Pose3& eye_in_track, core::RgbImage& image,
                              std::vector<float>* depth_m) {
  const int w = config_.width_px, h = config_.height_px;
  aim(eye_in_track);

  // draw and read back RGBA from the offscreen buffer (rows bottom-up; alpha 0 where nothing
  // was drawn, since mjr_render clears to transparent black)
  const mjrRect viewport{0, 0, w, h};
  mjr_render(viewport, &scene_, &context_);
  glReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, rgba_scratch_.data());

  // flip to rows top to bottom and paint the sky where nothing was drawn: a gradient from the
  // horizon colour to the zenith colour with the elevation of the pixel's ray
  const core::CameraIntrinsics& k = intrinsics_;
  const Eigen::Matrix3d r_world = eye_in_track.orientation.toRotationMatrix();
  image.width_px = w;
  image.height_px = h;
  image.rgb.resize(3 * static_cast<size_t>(w) * h);
  float sky[3], sky_slope[3];  // colour = sky + t * sky_slope
  for (int i = 0; i < 3; ++i) {
    sky[i] = static_cast<float>(255.0 * kSkyHorizon[i]);
    sky_slope[i] = static_cast<float>(255.0 * (kSkyZenith[i] - kSkyHorizon[i]));
  }
  const Eigen::Vector3d world_z = r_world.row(2).transpose();  // optical-frame components of up
  for (int r = 0; r < h; ++r) {
    const uint8_t* src = rgba_scratch_.data() + 4 * static_cast<size_t>(h - 1 - r) * w;
    uint8_t* dst = image.rgb.data() + 3 * static_cast<size_t>(r) * w;
    const float* inverse_length = inverse_ray_length_.data() + static_cast<size_t>(r) * w;
    // world z of the ray (x, y, 1) is linear along the row
    const double z0 = world_z.dot(Eigen::Vector3d(-k.cx / k.fx, (r - k.cy) / k.fy, 1.0));
    const double dz = world_z.x() / k.fx;
    for (int c = 0; c < w; ++c, src += 4, dst += 3) {
      if (src[3] != 0) {
        dst[0] = src[0];
        dst[1] = src[1];
        dst[2] = src[2];
        continue;
      }
      const float sine = static_cast<float>(z0 + c * dz) * inverse_length[c];
      const float t = std::clamp(sine / static_cast<float>(kSkyGradientSine), 0.f, 1.f);
      for (int i = 0; i < 3; ++i) dst[i] = static_cast<uint8_t>(sky[i] + t * sky_slope[i]);
    }
  }
  if (!depth_m) return;

  // depth buffer to metric depth along the optical axis: z_b = (1/n - 1/d) / (1/n - 1/f);
  // the cleared value (nothing drawn: the sky) reads as infinite depth
  mjr_readPixels(nullptr, depth_scratch_.data(), viewport, &context_);
  const double n = static_cast<float>(config_.near_m), f = static_cast<float>(config_.far_m);
  depth_m->resize(static_cast<size_t>(w) * h);
  for (int r = 0; r < h; ++r) {
    const float* src = depth_scratch_.data() + static_cast<size_t>(h - 1 - r) * w;
    float* dst = depth_m->data() + static_cast<size_t>(r) * w;
    for (int c = 0; c < w; ++c)
      dst[c] = src[c] >= 1.0f ? std::numeric_limits<float>::infinity()
                              : static_cast<float>(n * f / (f - src[c] * (f - n)));
  }
}

}  // namespace conesim::sensors
