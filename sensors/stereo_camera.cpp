#include "sensors/stereo_camera.hpp"

#include "core/rng.hpp"
#include "sensors/sun_shadow.hpp"
#include "vehicle_models/mjcf_builder.hpp"

#define GL_GLEXT_PROTOTYPES
#include <GL/gl.h>
#include <GL/glext.h>

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

// the asphalt texture's texels: 8 mm each, so that a 512-texel texture repeats every 4.1 m
constexpr double kAsphaltTexelM = 0.008;

// value noise on a periodic lattice of `cells` x `cells` over a size x size texture (so that the
// texture tiles without a seam): smooth, in [-1, 1]
std::vector<float> periodic_noise(int size, int cells, core::Rng& rng) {
  std::vector<float> lattice(static_cast<size_t>(cells) * cells);
  for (float& v : lattice) v = static_cast<float>(core::uniform(rng, -1.0, 1.0));
  std::vector<float> out(static_cast<size_t>(size) * size);
  const double step = static_cast<double>(cells) / size;
  const auto smooth = [](double t) { return t * t * (3.0 - 2.0 * t); };
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) {
      const double u = x * step, v = y * step;
      const int i = static_cast<int>(u), j = static_cast<int>(v);
      const double fu = smooth(u - i), fv = smooth(v - j);
      const auto at = [&](int a, int b) {
        return lattice[static_cast<size_t>(b % cells) * cells + static_cast<size_t>(a % cells)];
      };
      const double top = at(i, j) + fu * (at(i + 1, j) - at(i, j));
      const double bottom = at(i, j + 1) + fu * (at(i + 1, j + 1) - at(i, j + 1));
      out[static_cast<size_t>(y) * size + x] = static_cast<float>(top + fv * (bottom - top));
    }
  return out;
}

}  // namespace

std::vector<uint8_t> asphalt_texture(int size, uint64_t seed) {
  // asphalt as a camera sees it: a dark grey of the flat ground's mean colour with light and dark
  // stones of the aggregate (single texels), a grain of a few centimetres, blotches of some
  // decimetres, half a metre and patches of two (wear, repairs); every term drawn from the seed
  // (a stream of its own: the same seed also draws the images' noise)
  constexpr uint64_t kAsphaltStream = 0x61737068616c74;  // "asphalt"
  core::Rng rng(core::derive_seed(seed, kAsphaltStream));
  const std::vector<float> grain = periodic_noise(size, std::max(1, size / 4), rng);
  const std::vector<float> blotch = periodic_noise(size, std::max(1, size / 32), rng);
  const std::vector<float> mid = periodic_noise(size, 8, rng);
  const std::vector<float> patch = periodic_noise(size, 2, rng);
  std::vector<double> shade(grain.size());
  double sum = 0.0;
  for (size_t k = 0; k < grain.size(); ++k) {
    const double stone = core::uniform(rng, 0.0, 1.0);
    shade[k] =
        std::max(0.0, 1.0 + 0.10 * grain[k] + 0.15 * blotch[k] + 0.15 * mid[k] + 0.15 * patch[k] +
                          (stone < 0.03   ? 0.35
                           : stone > 0.97 ? -0.3
                                          : 0.0) +
                          0.06 * core::uniform(rng, -1.0, 1.0));
    sum += shade[k];
  }
  // (the mean shade of a drawn texture is 1)
  const double scale = static_cast<double>(shade.size()) / sum;
  std::vector<uint8_t> rgb(3 * static_cast<size_t>(size) * size);
  for (size_t k = 0; k < shade.size(); ++k)
    for (int c = 0; c < 3; ++c)
      rgb[3 * k + c] = static_cast<uint8_t>(
          std::clamp(255.0 * kAsphalt[c] * shade[k] * scale + 0.5, 0.0, 255.0));
  return rgb;
}

namespace {

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
  if (!(sun_diffuse >= 0.0 && sun_diffuse <= 1.0)) return "sun.diffuse: must be 0-1";
  if (!(sun_elevation_deg >= 5.0 && sun_elevation_deg <= 90.0))
    return "sun.elevation_deg: must be 5-90 (a lower sun casts shadows longer than the view)";
  if (!std::isfinite(sun_azimuth_deg)) return "sun.azimuth_deg: must be finite";
  if (!(shadow_strength >= 0.0 && shadow_strength <= 1.0))
    return "sun.shadow_strength: must be 0-1";
  if (!(exposure_time_ms >= 0.0 && exposure_time_ms <= 50.0))
    return "exposure_time_ms: must be 0-50";
  // the lens: finite terms of a size real lenses have, and a radial map that keeps growing out
  // to the image's corner (else two rays would land on one pixel and the model has no inverse)
  const char* names[5] = {"k1", "k2", "p1", "p2", "k3"};
  for (size_t i = 0; i < distortion.size(); ++i) {
    const double limit = i == 2 || i == 3 ? 0.05 : 2.0;
    if (!(std::abs(distortion[i]) <= limit))
      return std::string("distortion: ") + names[i] + " must be within +-" +
             (limit < 1.0 ? "0.05" : "2") + ", got " + std::to_string(distortion[i]);
  }
  const double tan_half_x = std::tan(0.5 * horizontal_fov_deg * kDegToRad);
  const double corner = tan_half_x * std::hypot(1.0, static_cast<double>(height_px) / width_px);
  const auto& [k1, k2, p1, p2, k3] = distortion;
  double last = 0.0;
  for (int i = 1;; ++i) {
    const double r = corner * i / 1000.0, r2 = r * r;
    const double g = r * (1.0 + r2 * (k1 + r2 * (k2 + r2 * k3)));
    if (!(g > last))
      return "distortion: the radial terms fold the image over at " + std::to_string(r) +
             " from the axis (tangent of the angle), inside the image's corner at " +
             std::to_string(corner) + ": not a lens";
    if (g >= 1.02 * corner) break;
    if (i >= 10000) return "distortion: the radial terms never reach the image's corner";
    last = g;
  }
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
  k.distortion = c.distortion;
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

  // calibration, fixed for the camera's life; with distortion GL draws a larger pinhole canvas
  intrinsics_ = stereo_intrinsics(config);
  left_in_vehicle_ = stereo_camera_in_vehicle(config, true);
  right_in_vehicle_ = stereo_camera_in_vehicle(config, false);
  frustum_half_height_ = frustum_half_height(config);
  canvas_ = intrinsics_;
  canvas_.distortion = {};
  if (intrinsics_.distorted()) {
    plan_warp();
    if (canvas_.width_px > model->vis.global.offwidth ||
        canvas_.height_px > model->vis.global.offheight)
      throw std::invalid_argument(
          "stereo camera: distortion: the pinhole view it is drawn from needs " +
          std::to_string(canvas_.width_px) + " x " + std::to_string(canvas_.height_px) +
          " pixels, beyond the model's offscreen buffer of " +
          std::to_string(model->vis.global.offwidth) + " x " +
          std::to_string(model->vis.global.offheight));
    // the same focal length over the larger canvas (MuJoCo matches the width to the aspect)
    frustum_half_height_ = static_cast<float>(
        frustum_half_height_ * static_cast<double>(canvas_.height_px) / config.height_px);
  }
  const int cw = canvas_.width_px, ch = canvas_.height_px;

  // GL: one OSMesa context per camera, MuJoCo's render context drawing off-screen
  gl_ = std::make_unique<OsMesaContext>(cw, ch);
  mjr_defaultContext(&context_);
  mjr_makeContext(model, &context_, mjFONTSCALE_50);
  mjr_setBuffer(mjFB_OFFSCREEN, &context_);
  if (context_.currentBuffer != mjFB_OFFSCREEN) {
    mjr_freeContext(&context_);
    throw std::runtime_error("stereo camera: MuJoCo has no offscreen buffer under OSMesa");
  }

  // the motion blur: the body the camera rides on
  exposure_s_ = 1e-3 * config.exposure_time_ms;
  if (exposure_s_ > 0.0) {
    chassis_body_ = mj_name2id(model, mjOBJ_BODY, vehicle_models::MjcfNames::kChassis);
    if (chassis_body_ < 0)
      throw std::invalid_argument("stereo camera: exposure_time_ms: the model has no body " +
                                  std::string(vehicle_models::MjcfNames::kChassis));
  }

  // the ground's grain: the model's asphalt texture, drawn afresh from the seed
  if (config.ground_texture) {
    const int id = mj_name2id(model, mjOBJ_TEXTURE, "asphalt");
    if (id < 0 || model->tex_type[id] != mjTEXTURE_2D || id >= context_.ntexture)
      throw std::invalid_argument(
          "stereo camera: ground_texture: the model has no 2D texture named asphalt");
    const int size = std::min(model->tex_width[id], model->tex_height[id]);
    const std::vector<uint8_t> rgb = asphalt_texture(size, config.noise_seed);
    glBindTexture(GL_TEXTURE_2D, context_.texture[id]);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB, size, size, 0, GL_RGB, GL_UNSIGNED_BYTE, rgb.data());
    glGenerateMipmap(GL_TEXTURE_2D);
    // bilinear within the nearest mipmap level: trilinear (blending two levels) cost the software
    // rasteriser 6 ms of a 26 ms stereo pair, this 2 ms; the level's seams are lost in the grain
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_REPEAT);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_REPEAT);
    asphalt_texture_ = id;
    asphalt_period_m_ = size * kAsphaltTexelM;
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
  rgba_scratch_.resize(4 * static_cast<size_t>(cw) * ch);
  depth_scratch_.resize(static_cast<size_t>(cw) * ch);

  // ray lengths for painting the sky by elevation
  inverse_ray_length_.resize(depth_scratch_.size());
  for (int r = 0; r < ch; ++r)
    for (int c = 0; c < cw; ++c) {
      const double x = (c - canvas_.cx) / canvas_.fx;
      const double y = (r - canvas_.cy) / canvas_.fy;
      inverse_ray_length_[static_cast<size_t>(r) * cw + c] =
          static_cast<float>(1.0 / std::sqrt(1.0 + x * x + y * y));
    }
}

void StereoCamera::plan_warp() {
  const core::CameraIntrinsics& k = intrinsics_;
  const int w = k.width_px, h = k.height_px;
  const auto& [k1, k2, p1, p2, k3] = k.distortion;
  // the normalised pinhole point each pixel shows: Newton on the lens model from the pixel's
  // own normalised position (validate() keeps the radial map growing, so it converges)
  std::vector<Eigen::Vector2d> source(static_cast<size_t>(w) * h);
  double reach_x = 0.0, reach_y = 0.0;  // farthest source from the principal point, pixels
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      const Eigen::Vector2d target((c - k.cx) / k.fx, (r - k.cy) / k.fy);
      Eigen::Vector2d p = target;
      for (int it = 0; it < 50; ++it) {
        const double x = p.x(), y = p.y(), r2 = x * x + y * y;
        const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        const double slope = k1 + r2 * (2.0 * k2 + 3.0 * r2 * k3);  // d radial / d r2
        const Eigen::Vector2d drawn(x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
                                    y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y);
        // the Jacobian (symmetric) and its 2 x 2 solve
        const double jxx = radial + 2.0 * x * x * slope + 2.0 * p1 * y + 6.0 * p2 * x;
        const double jxy = 2.0 * x * y * slope + 2.0 * p1 * x + 2.0 * p2 * y;
        const double jyy = radial + 2.0 * y * y * slope + 6.0 * p1 * y + 2.0 * p2 * x;
        const Eigen::Vector2d miss = drawn - target;
        const double det = jxx * jyy - jxy * jxy;
        const Eigen::Vector2d step((jyy * miss.x() - jxy * miss.y()) / det,
                                   (jxx * miss.y() - jxy * miss.x()) / det);
        p -= step;
        if (step.norm() < 1e-13) break;
      }
      const Eigen::Vector2d pixel(k.fx * p.x() + k.cx, k.fy * p.y() + k.cy);
      if (!pixel.allFinite())
        throw std::invalid_argument("stereo camera: distortion: no pinhole ray for pixel (" +
                                    std::to_string(c) + ", " + std::to_string(r) + ")");
      source[static_cast<size_t>(r) * w + c] = pixel;
      reach_x = std::max(reach_x, std::abs(pixel.x() - k.cx));
      reach_y = std::max(reach_y, std::abs(pixel.y() - k.cy));
    }
  // the canvas: the image grown by the same margin either side (the principal point stays in
  // its centre, on the same pixel grid), one pixel more than the farthest source for blending
  const int margin_x = std::max(0, static_cast<int>(std::ceil(reach_x - k.cx)) + 1);
  const int margin_y = std::max(0, static_cast<int>(std::ceil(reach_y - k.cy)) + 1);
  canvas_.width_px = w + 2 * margin_x;
  canvas_.height_px = h + 2 * margin_y;
  canvas_.cx = k.cx + margin_x;
  canvas_.cy = k.cy + margin_y;
  warp_.resize(source.size());
  auto nearest = std::make_shared<std::vector<Eigen::Vector2d>>(source.size());
  for (size_t i = 0; i < source.size(); ++i) {
    const double x = source[i].x() + margin_x, y = source[i].y() + margin_y;
    const double x0 = std::floor(x), y0 = std::floor(y);
    warp_[i] = {static_cast<int32_t>(y0) * canvas_.width_px + static_cast<int32_t>(x0),
                static_cast<float>(x - x0), static_cast<float>(y - y0),
                static_cast<uint32_t>(std::lround(256.0 * (x - x0))),
                static_cast<uint32_t>(std::lround(256.0 * (y - y0)))};
    const int32_t at = warp_[i].nearest(canvas_.width_px);
    (*nearest)[i] = {at % canvas_.width_px - margin_x, at / canvas_.width_px - margin_y};
  }
  nearest_pinhole_ = nearest;
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
  add_sun(labels.left_in_track);

  // the car's motion now, for the blur: both eyes move as the chassis does midway between them
  if (exposure_s_ > 0.0) {
    mjtNum velocity[6];
    mj_objectVelocity(model_, data, mjOBJ_BODY, chassis_body_, velocity, 0);
    const Eigen::Vector3d turn(velocity[0], velocity[1], velocity[2]);
    const Eigen::Vector3d origin(data->xpos[3 * chassis_body_], data->xpos[3 * chassis_body_ + 1],
                                 data->xpos[3 * chassis_body_ + 2]);
    const Eigen::Vector3d mid =
        0.5 * (labels.left_in_track.position + labels.right_in_track.position);
    eye_angular_velocity_ = turn;
    // the car's own geoms (those of its bodies, not the world's ground)
    car_spheres_.clear();
    for (int g = 0; g < model_->ngeom; ++g)
      if (model_->geom_bodyid[g] != 0)
        car_spheres_.emplace_back(scratch_->geom_xpos[3 * g], scratch_->geom_xpos[3 * g + 1],
                                  scratch_->geom_xpos[3 * g + 2], model_->geom_rbound[g]);
    eye_velocity_ =
        Eigen::Vector3d(velocity[3], velocity[4], velocity[5]) + turn.cross(mid - origin);
  }

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
  const int w = canvas_.width_px, h = canvas_.height_px;

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
  for (int i = 0; i < scene_.ngeom; ++i)
    scene_.geoms[i].segid = saved_segid[static_cast<size_t>(i)];

  // decode, flipping rows to top to bottom; colour 0 (the cleared background) is the sky
  auto decode = [&](int r, int c) {
    const uint8_t* src = rgba_scratch_.data() + 4 * (static_cast<size_t>(h - 1 - r) * w + c);
    const int id = (src[0] | (src[1] << 8) | (src[2] << 16)) - 1;
    return id >= 0 && id < static_cast<int>(shows.size()) ? shows[static_cast<size_t>(id)]
                                                          : SegmentationImage::kNothing;
  };
  out.width_px = config_.width_px;
  out.height_px = config_.height_px;
  out.object.resize(static_cast<size_t>(out.width_px) * out.height_px);
  out.pinhole_point = nearest_pinhole_;
  if (warp_.empty()) {
    for (int r = 0; r < h; ++r)
      for (int c = 0; c < w; ++c) out.object[static_cast<size_t>(r) * w + c] = decode(r, c);
    return;
  }
  // through the lens: the nearest canvas pixel's object (ids are not blended)
  for (size_t i = 0; i < warp_.size(); ++i) {
    const int32_t at = warp_[i].nearest(w);
    out.object[i] = decode(at / w, at % w);
  }
}

ViewVolume StereoCamera::rig_view(const core::Pose3& left_in_track) const {
  // one pyramid holding both cameras' ones: its apex sits behind the midpoint of the optical
  // centres, far enough back that its sides pass through both centres
  ViewVolume v;
  v.axes = left_in_track.orientation.toRotationMatrix();
  v.tan_half_x = std::tan(0.5 * config_.horizontal_fov_deg * kDegToRad);
  v.tan_half_y = v.tan_half_x * config_.height_px / config_.width_px;
  if (!warp_.empty()) {
    // the canvas the lens draws from, a little wider than the pinhole image
    v.tan_half_x = (0.5 * canvas_.width_px) / canvas_.fx;
    v.tan_half_y = (0.5 * canvas_.height_px) / canvas_.fy;
  }
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
    if (asphalt_texture_ >= 0) {
      // the texture in white light, repeating every period across the square, which stands on
      // a whole number of periods so that the grain stays where it is on the ground
      g.texid = asphalt_texture_;
      g.texuniform = 1;
      const double period = asphalt_period_m_;
      const double half = std::ceil(kGroundHalfSizeInFar * config_.far_m / period) * period;
      g.size[0] = g.size[1] = static_cast<float>(half);
      g.pos[0] = static_cast<float>(std::round(centre.x() / period) * period);
      g.pos[1] = static_cast<float>(std::round(centre.y() / period) * period);
      g.texrepeat[0] = g.texrepeat[1] = static_cast<float>(2.0 / period);
      std::fill(g.rgba, g.rgba + 3, 1.f);
    }
  }
}

void StereoCamera::add_sun(const core::Pose3& eye_in_track) {
  shadow_triangles_.clear();
  const double strength = config_.sun_diffuse;
  if (!(strength > 0.0) || scene_.nlight >= mjMAXLIGHT) return;
  // the direction the sunlight travels
  const double elevation = config_.sun_elevation_deg * kDegToRad;
  const double azimuth = config_.sun_azimuth_deg * kDegToRad;
  const Eigen::Vector3d d(-std::cos(elevation) * std::cos(azimuth),
                          -std::cos(elevation) * std::sin(azimuth), -std::sin(elevation));
  mjvLight& sun = scene_.lights[scene_.nlight++];
  sun = mjvLight{};
  for (int i = 0; i < 3; ++i) {
    sun.dir[i] = static_cast<float>(d[i]);
    sun.pos[i] = static_cast<float>(eye_in_track.position[i] - 100.0 * d[i]);
    sun.diffuse[i] = static_cast<float>(strength);
  }
  sun.attenuation[0] = 1.f;
  sun.cutoff = 180.f;
  sun.directional = 1;
  if (!(config_.shadow_strength > 0.0)) return;

  // the shadows: every solid the scene holds (cones, scenery, the car) casts its outline along
  // the light onto the ground under it (the plane touching the ground there), a couple of
  // millimetres above it; render_eye() draws them over the ground in black with the share of the
  // light the sun gives there as their opacity. A shadow falls on the ground only (not on other
  // objects); the sunlit and shaded sides of the solids themselves come from the light.
  const Eigen::Vector3d forward = eye_in_track.orientation * Eigen::Vector3d::UnitZ();
  const ViewVolume view = rig_view(eye_in_track);
  constexpr double kLift = 2e-3;
  std::vector<Eigen::Vector3d> points;
  const auto cast = [&](const Eigen::Vector3d& at) {
    const Eigen::Vector3d q(at.x(), at.y(), ground_.height(at.x(), at.y()));
    const Eigen::Vector3d n = ground_.normal(at.x(), at.y());
    const std::vector<Eigen::Vector3d> outline = cast_shadow(points, d, q, n);
    points.clear();
    if (outline.empty()) return;
    // (one out of view is not drawn)
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (const Eigen::Vector3d& p : outline) centre += p;
    centre /= static_cast<double>(outline.size());
    double radius = 0.0;
    for (const Eigen::Vector3d& p : outline) radius = std::max(radius, (p - centre).norm());
    if (!view.may_see(centre, radius)) return;
    const double lit_sun = strength * -d.dot(n);
    const double lit =
        config_.light_ambient + headlight_diffuse() * std::max(0.0, -forward.dot(n)) + lit_sun;
    const auto alpha = static_cast<float>(config_.shadow_strength * lit_sun / lit);
    const auto vertex = [&](const Eigen::Vector3d& p) {
      const Eigen::Vector3d lifted = p + kLift * n;
      shadow_triangles_.push_back({static_cast<float>(lifted.x()), static_cast<float>(lifted.y()),
                                   static_cast<float>(lifted.z()), alpha});
    };
    for (size_t i = 1; i + 1 < outline.size(); ++i) {
      vertex(outline[0]);
      vertex(outline[i]);
      vertex(outline[i + 1]);
    }
  };
  for (int i = 0; i < scene_.ngeom; ++i) {
    const mjvGeom& g = scene_.geoms[i];
    if (g.type == mjGEOM_PLANE || g.type == mjGEOM_HFIELD || g.rgba[3] < 0.995f) continue;
    // a cone as the boxes that stand in for it (a few corners instead of its mesh's vertices)
    const std::vector<ConeSceneWriter::Box> boxes = cones_->shadow_boxes(g);
    for (const ConeSceneWriter::Box& box : boxes) {
      mjvGeom b = g;
      b.type = mjGEOM_BOX;
      for (int r = 0; r < 3; ++r) {
        b.pos[r] = static_cast<float>(box.centre[r]);
        b.size[r] = static_cast<float>(box.half[r]);
        for (int c = 0; c < 3; ++c) b.mat[3 * r + c] = r == c ? 1.f : 0.f;
      }
      shadow_caster_points(b, model_, d, points);
      cast(box.centre);
    }
    if (!boxes.empty()) continue;
    shadow_caster_points(g, model_, d, points);
    cast(Eigen::Vector3d(g.pos[0], g.pos[1], g.pos[2]));
  }
}

void StereoCamera::draw_shadows(const core::Pose3& eye_in_track) const {
  if (shadow_triangles_.empty()) return;
  // the view MuJoCo drew with (a symmetric frustum, the eye looking along its optical z axis
  // with its -y up)
  const double half_h = frustum_half_height_;
  const double half_w = half_h * canvas_.width_px / canvas_.height_px;
  const Eigen::Matrix3d axes = eye_in_track.orientation.toRotationMatrix();
  // GL's eye frame: x right, y up, z backwards
  Eigen::Matrix4d view = Eigen::Matrix4d::Identity();
  view.row(0).head<3>() = axes.col(0).transpose();
  view.row(1).head<3>() = -axes.col(1).transpose();
  view.row(2).head<3>() = -axes.col(2).transpose();
  view.block<3, 1>(0, 3) = -view.block<3, 3>(0, 0) * eye_in_track.position;
  const Eigen::Matrix4f view_f = view.cast<float>();  // column-major, as GL takes it

  // (GL's state as MuJoCo left it is restored after: its lighting and materials too, which
  // glColor would change while GL_COLOR_MATERIAL is on)
  glPushAttrib(GL_ENABLE_BIT | GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT | GL_STENCIL_BUFFER_BIT |
               GL_POLYGON_BIT | GL_CURRENT_BIT | GL_TRANSFORM_BIT | GL_LIGHTING_BIT);
  glMatrixMode(GL_PROJECTION);
  glPushMatrix();
  glLoadIdentity();
  glFrustum(-half_w, half_w, -half_h, half_h, config_.near_m, config_.far_m);
  glMatrixMode(GL_MODELVIEW);
  glPushMatrix();
  glLoadMatrixf(view_f.data());
  glDisable(GL_LIGHTING);
  glDisable(GL_COLOR_MATERIAL);
  glDisable(GL_TEXTURE_2D);
  glDisable(GL_CULL_FACE);
  glDisable(GL_FOG);
  // hidden where a solid stands in front; over the ground, which they lie just above
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LEQUAL);
  glDepthMask(GL_FALSE);
  glEnable(GL_POLYGON_OFFSET_FILL);
  glPolygonOffset(-1.f, -1.f);
  // each pixel darkened once where shadows overlap (the sun is either blocked there or not)
  glClearStencil(0);
  glClear(GL_STENCIL_BUFFER_BIT);
  glEnable(GL_STENCIL_TEST);
  glStencilFunc(GL_EQUAL, 0, 0xff);
  glStencilOp(GL_KEEP, GL_KEEP, GL_INCR);
  glEnable(GL_BLEND);
  glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
  // (the alpha channel marks what was drawn; the sky is painted where it is 0)
  glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_FALSE);
  glBegin(GL_TRIANGLES);
  for (const ShadowVertex& v : shadow_triangles_) {
    glColor4f(0.f, 0.f, 0.f, v.alpha);
    glVertex3f(v.x, v.y, v.z);
  }
  glEnd();
  glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
  glPopMatrix();
  glMatrixMode(GL_PROJECTION);
  glPopMatrix();
  glPopAttrib();
}

double StereoCamera::headlight_diffuse() const {
  // in sunshine the light from the eye gives up the sun's share, so that a face lit by both
  // stays within full light (the headlight stands for the light a day spreads evenly)
  return std::max(0.0, config_.light_diffuse - config_.sun_diffuse);
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
      light.diffuse[i] = static_cast<float>(headlight_diffuse());
    }
  }
}

void StereoCamera::warp_canvas(core::RgbImage& out_image) const {
  // each image pixel blends the four canvas pixels round its ray (bilinear)
  if (warp_.empty()) return;
  const size_t row = 3 * static_cast<size_t>(canvas_.width_px);
  out_image.width_px = config_.width_px;
  out_image.height_px = config_.height_px;
  out_image.rgb.resize(3 * warp_.size());
  const uint8_t* src = canvas_rgb_.rgb.data();
  uint8_t* dst = out_image.rgb.data();
  for (const WarpSample& s : warp_) {
    const uint8_t* a = src + 3 * static_cast<size_t>(s.index);
    const uint32_t wx = s.ix, wy = s.iy;  // in 1/256
    for (int i = 0; i < 3; ++i, ++a) {
      const uint32_t top = a[0] * (256 - wx) + a[3] * wx;
      const uint32_t bottom = a[row] * (256 - wx) + a[row + 3] * wx;
      *dst++ = static_cast<uint8_t>((top * (256 - wy) + bottom * wy + 32768) >> 16);
    }
  }
}

void motion_blur(core::RgbImage& image, const std::vector<float>& depth_m,
                 const core::CameraIntrinsics& k, const Eigen::Vector3d& v,
                 const Eigen::Vector3d& w, double exposure_s,
                 const std::vector<Eigen::Vector4d>& riding, std::vector<uint8_t>& scratch) {
  // a static point at normalised image coordinates (x, y) and depth Z moves over the image as
  // x' = (-vx + x vz) / Z + x y wx - (1 + x^2) wy + y wz,
  // y' = (-vy + y vz) / Z + (1 + y^2) wx - x y wy - x wz (a pinhole camera moving with v, w);
  // each pixel averages what passes over it during the exposure: samples along that track, at
  // the middles of equal parts of the exposure (centred on the image's moment), about one per
  // pixel it crosses
  constexpr int kMostSamples = 9;
  const int width = image.width_px, height = image.height_px;
  // a camera at rest: nothing moves
  if (v.squaredNorm() == 0.0 && w.squaredNorm() == 0.0) return;
  scratch = image.rgb;
  const double f = k.fx, t = exposure_s;
  // nothing riding with the camera lies beyond this depth
  double riding_depth = 0.0;
  for (const Eigen::Vector4d& sphere : riding)
    riding_depth = std::max(riding_depth, sphere.z() + sphere.w());
  for (int r = 0; r < height; ++r) {
    const double y = (r - k.cy) / k.fy;
    for (int c = 0; c < width; ++c) {
      const size_t at = static_cast<size_t>(r) * width + c;
      const double x = (c - k.cx) / k.fx;
      const double z = depth_m[at];
      if (z < riding_depth) {
        const Eigen::Vector3d point(x * z, y * z, z);
        if (std::any_of(riding.begin(), riding.end(), [&](const Eigen::Vector4d& sphere) {
              return (point - sphere.head<3>()).squaredNorm() <= sphere.w() * sphere.w();
            }))
          continue;
      }
      const double inv = std::isfinite(z) && z > 0.0 ? 1.0 / z : 0.0;
      const double du =
          f * t * ((-v.x() + x * v.z()) * inv + x * y * w.x() - (1.0 + x * x) * w.y() + y * w.z());
      const double dv =
          f * t * ((-v.y() + y * v.z()) * inv + (1.0 + y * y) * w.x() - x * y * w.y() - x * w.z());
      const double squared = du * du + dv * dv;
      if (!(squared >= 0.25)) continue;
      const int samples =
          std::min(kMostSamples, static_cast<int>(std::ceil(std::sqrt(squared))) + 1);
      int sum[3] = {0, 0, 0};
      for (int i = 0; i < samples; ++i) {
        const double s = (i + 0.5) / samples - 0.5;
        const int sc = std::clamp(static_cast<int>(std::lround(c + s * du)), 0, width - 1);
        const int sr = std::clamp(static_cast<int>(std::lround(r + s * dv)), 0, height - 1);
        const uint8_t* p = scratch.data() + 3 * (static_cast<size_t>(sr) * width + sc);
        for (int j = 0; j < 3; ++j) sum[j] += p[j];
      }
      for (int j = 0; j < 3; ++j)
        image.rgb[3 * at + j] = static_cast<uint8_t>((sum[j] + samples / 2) / samples);
    }
  }
}

void StereoCamera::render_eye(const core::Pose3& eye_in_track, core::RgbImage& out_image,
                              std::vector<float>* out_depth_m) {
  // GL draws the pinhole canvas: the image itself, or with distortion a larger one that the
  // image then samples through the lens model
  const bool warp = !warp_.empty();
  core::RgbImage& image = warp ? canvas_rgb_ : out_image;
  std::vector<float>* depth_m = warp && out_depth_m ? &canvas_depth_ : out_depth_m;
  const int w = canvas_.width_px, h = canvas_.height_px;
  aim(eye_in_track);

  // draw and read back RGBA from the offscreen buffer (rows bottom-up; alpha 0 where nothing
  // was drawn, since mjr_render clears to transparent black)
  const mjrRect viewport{0, 0, w, h};
  mjr_render(viewport, &scene_, &context_);
  draw_shadows(eye_in_track);
  glReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, rgba_scratch_.data());

  // flip to rows top to bottom and paint the sky where nothing was drawn: a gradient from the
  // horizon colour to the zenith colour with the elevation of the pixel's ray
  const core::CameraIntrinsics& k = canvas_;
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
  // the canvas's depth along the optical axis, when the blur or the caller needs it: the depth
  // buffer's z_b = (1/n - 1/d) / (1/n - 1/f); the cleared value (the sky) is infinitely far
  // (a car at rest blurs nothing: no depth read for it)
  const bool blur = exposure_s_ > 0.0 && (eye_velocity_.squaredNorm() > 0.0 ||
                                          eye_angular_velocity_.squaredNorm() > 0.0);
  if (!depth_m && !blur) {
    warp_canvas(out_image);
    return;
  }
  std::vector<float>& depth = depth_m ? *depth_m : blur_depth_;
  mjr_readPixels(nullptr, depth_scratch_.data(), viewport, &context_);
  const double n = static_cast<float>(config_.near_m), f = static_cast<float>(config_.far_m);
  depth.resize(static_cast<size_t>(w) * h);
  for (int r = 0; r < h; ++r) {
    const float* src = depth_scratch_.data() + static_cast<size_t>(h - 1 - r) * w;
    float* dst = depth.data() + static_cast<size_t>(r) * w;
    for (int c = 0; c < w; ++c)
      dst[c] = src[c] >= 1.0f ? std::numeric_limits<float>::infinity()
                              : static_cast<float>(n * f / (f - src[c] * (f - n)));
  }
  // the motion during the exposure, of the eye in its own frame
  if (blur) {
    const Eigen::Matrix3d to_eye = r_world.transpose();
    const core::Pose3 track_in_eye = eye_in_track.inverse();
    std::vector<Eigen::Vector4d> riding;
    for (const Eigen::Vector4d& sphere : car_spheres_) {
      const Eigen::Vector3d centre = track_in_eye.transform(sphere.head<3>());
      riding.emplace_back(centre.x(), centre.y(), centre.z(), sphere.w());
    }
    motion_blur(image, depth, canvas_, to_eye * eye_velocity_, to_eye * eye_angular_velocity_,
                exposure_s_, riding, blur_scratch_);
  }
  warp_canvas(out_image);
  if (!depth_m) return;
  if (warp) {
    // depth is not blended across edges: the nearest canvas pixel's
    out_depth_m->resize(warp_.size());
    for (size_t i = 0; i < warp_.size(); ++i)
      (*out_depth_m)[i] = canvas_depth_[static_cast<size_t>(warp_[i].nearest(w))];
  }
}

}  // namespace conesim::sensors
