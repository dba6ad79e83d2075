#pragma once
// A rectified stereo camera rendered by MuJoCo under OSMesa: the car's own world (the car and an
// asphalt ground) plus the track's cones appended to the scene each frame, under a painted sky.
// Intrinsics are exact: the GL frustum is set from them, so a point projects through the
// published pinhole model to the pixel where it is drawn.

#include <mujoco/mujoco.h>

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/measurements.hpp"
#include "core/time.hpp"
#include "sensors/cone_render.hpp"
#include "sensors/image_response.hpp"
#include "sensors/osmesa_context.hpp"
#include "tracks/track.hpp"

namespace conesim::sensors {

/// The lens a scenario's camera has with `sensors.realism: on` (k1, k2, p1, p2, k3): a
/// low-distortion machine-vision lens of about 70 degrees as FS teams calibrate them (barrel,
/// 7 % at the image's corner; tangential terms of a slightly tilted sensor).
/// The sun's diffuse intensity with sensors.realism on: a clear day, its light on a level
/// surface about as strong as the headlight's and the ambient light together.
inline constexpr double kTypicalSunDiffuse = 0.5;
inline constexpr std::array<double, 5> kTypicalLensDistortion = {-0.12, 0.03, 0.0005, -0.0003, 0.0};

/// Configuration of the stereo rig. Defaults: a main-hoop pair looking ahead, slightly down.
struct StereoCameraConfig {
  /// Image size, pixels (at most the model's offscreen buffer, 1280 x 960 by default).
  int width_px = 640;
  int height_px = 480;
  /// Horizontal field of view, degrees; the vertical one follows from square pixels.
  double horizontal_fov_deg = 70.0;
  /// Distance between the two optical centres, metres.
  double baseline_m = 0.12;
  /// Midpoint between the optical centres in the vehicle frame (rear axle centre on the ground,
  /// x forward, y left, z up), metres.
  double mount_x_m = 0.60;
  double mount_y_m = 0.0;
  double mount_z_m = 1.05;
  /// Pitch of both optical axes below the horizontal, degrees.
  double pitch_down_deg = 5.0;
  /// Near clipping distance along the optical axis, metres.
  double near_m = 0.1;
  /// Far clipping distance along the optical axis, metres: nothing beyond is drawn, and pixels
  /// that show nothing (the sky) read as infinite depth.
  double far_m = 100.0;
  /// The light on the scene, from the eye (as the model's headlight): its ambient and diffuse
  /// intensity, 0-1 per channel (the model's 0.45 and 0.55 by default).
  double light_ambient = 0.45;
  double light_diffuse = 0.55;
  /// What the sensor does to the rendered light: exposure, shot and read noise, gamma.
  ImageResponse response;
  /// Lens distortion in OpenCV's model (k1, k2, p1, p2, k3; core::CameraIntrinsics): the images
  /// are drawn through it and the intrinsics published with each frame carry it, so
  /// cv::undistortPoints or cv::initUndistortRectifyMap with them gives the pinhole view back.
  /// All zero: a pinhole camera.
  std::array<double, 5> distortion{};
  /// Asphalt with a grain (fine speckle, blotches a few decimetres across and darker patches of
  /// a metre or two, drawn from the noise seed, fixed to the ground) instead of one flat grey
  /// with the same mean.
  bool ground_texture = false;
  /// The sun: a directional light from this elevation above the horizon and azimuth (degrees,
  /// anticlockwise from the track's x axis, the direction the light comes from) with this
  /// diffuse intensity, and the shadows it casts on the ground (every cone, object and the car
  /// cast theirs, projected along the light). An intensity of 0: no sun, the headlight alone;
  /// with a sun the headlight gives up its share (light_diffuse - sun_diffuse, at least 0).
  double sun_elevation_deg = 45.0;
  double sun_azimuth_deg = 135.0;
  double sun_diffuse = 0.0;
  /// How dark a shadow is: the share of the sun's light it takes away from the ground (1: all).
  double shadow_strength = 1.0;
  /// Exposure time, milliseconds: the image integrates the scene while the car moves, so what
  /// moves across the image during it is blurred along its track (0: a still image).
  double exposure_time_ms = 0.0;
  /// Seed of the images' noise (a run gives its scenario's seed).
  uint64_t noise_seed = 0;

  /// Empty when the configuration is usable, otherwise a message that starts with the bad key.
  std::string validate() const;
};

/// The asphalt texture a camera with ground_texture draws: size x size RGB texels (rows in
/// order), 8 mm each, tiling without a seam, its mean the flat ground's colour; from the seed.
std::vector<uint8_t> asphalt_texture(int size, uint64_t seed);

/// The exposure time with sensors.realism on: a machine-vision camera outdoors in daylight.
inline constexpr double kTypicalExposureTimeMs = 2.0;

/// Blurs a pinhole image (rows top to bottom; k without distortion) as a camera moving with
/// linear velocity v and angular velocity w (its optical frame: x right, y down, z forward;
/// m/s, rad/s) sees a static scene over an exposure of exposure_s centred on the image's
/// moment: each pixel averages the image along the track its point makes meanwhile, from the
/// pixel's depth along the optical axis (infinite: only the turn moves it). A pixel whose point
/// lies in one of the spheres `riding` (centre in the optical frame, radius; the car's own
/// parts, which move with the camera) stays sharp. scratch: reused.
void motion_blur(core::RgbImage& image, const std::vector<float>& depth_m,
                 const core::CameraIntrinsics& k, const Eigen::Vector3d& v,
                 const Eigen::Vector3d& w, double exposure_s,
                 const std::vector<Eigen::Vector4d>& riding, std::vector<uint8_t>& scratch);

/// Intrinsics of a camera with this configuration (square pixels, principal point in the image
/// centre; pixel centres at integer coordinates, as in OpenCV), with its lens distortion.
core::CameraIntrinsics stereo_intrinsics(const StereoCameraConfig& config);

/// Left (left = true) or right camera pose in the vehicle frame, optical axes (x right, y down,
/// z forward).
core::Pose3 stereo_camera_in_vehicle(const StereoCameraConfig& config, bool left);

/// What each pixel of the left image shows, object by object (StereoCamera::render_segmentation).
struct SegmentationImage {
  /// Nothing drawn: the sky.
  static constexpr int32_t kNothing = -1;
  /// The ground (plane or height field).
  static constexpr int32_t kGround = -2;
  /// The car itself (its nose, wheels or wing in view).
  static constexpr int32_t kCar = -3;
  /// A scenery object: kSceneryBase minus its index in the scenery list (tracks/scenery.hpp).
  static constexpr int32_t kSceneryBase = kSceneryObjidBase;

  int width_px = 0;
  int height_px = 0;
  /// Per pixel, rows top to bottom: a cone's id (>= 0) or one of the codes above.
  std::vector<int32_t> object;
  /// With lens distortion: per pixel, the point of the pinhole view (pixels, the same fx, fy,
  /// cx, cy) whose object it shows: GL decides at the centres of the pinhole canvas's pixels,
  /// and each image pixel takes the nearest one. Empty (null) for a pinhole camera, where a
  /// pixel shows what lies at its own centre.
  std::shared_ptr<const std::vector<Eigen::Vector2d>> pinhole_point;

  int32_t at(int x, int y) const { return object[static_cast<size_t>(y) * width_px + x]; }
};

/// Renders stereo frames of one car's world. Holds its own OSMesa context, MuJoCo render
/// context, abstract scene, scratch mjData and a copy of the track's cones; the model must
/// outlive it. Not thread safe: render from one thread at a time.
class StereoCamera {
 public:
  /// Sets up rendering of `model` (built by vehicle_models::build_mjcf, which adds the cone
  /// meshes) with the cones of `track`. Throws std::invalid_argument for a bad configuration or
  /// an image larger than the model's offscreen buffer, std::runtime_error when GL fails.
  /// The scenery objects (tracks/scenery.hpp) are drawn as well; cones and objects stand on
  /// the ground (the model's height field when it is not flat).
  StereoCamera(const StereoCameraConfig& config, const mjModel* model, const tracks::Track& track,
               const std::vector<tracks::SceneryObject>& scenery = {},
               const tracks::GroundModel& ground = {});
  ~StereoCamera();
  StereoCamera(const StereoCamera&) = delete;
  StereoCamera& operator=(const StereoCamera&) = delete;

  /// Renders the left and right images (and the left depth when with_depth) as seen with the
  /// car in state `data` (only qpos is read) and the vehicle frame at `vehicle_in_track`; cones
  /// for which is_knocked returns true are not drawn (an empty is_knocked draws all). Buffers of
  /// `frame` are reused; `labels` receives the true camera poses in the track frame.
  void render(const mjData* data, const core::Pose3& vehicle_in_track, core::TimeUs stamp,
              const IsKnocked& is_knocked, bool with_depth, core::StereoFrame& frame,
              core::StereoLabels& labels);

  /// The left image of the last render() again, each pixel naming the object it shows (a
  /// per-pixel segmentation drawn by MuJoCo with flat, unlit id colours, the same geometry and
  /// depth test as the image). Call after render(); it changes neither the frame nor the scene.
  void render_segmentation(SegmentationImage& out);

  /// The configuration in use.
  const StereoCameraConfig& config() const { return config_; }
  /// Intrinsics of both cameras (published with every frame too).
  const core::CameraIntrinsics& intrinsics() const { return intrinsics_; }
  /// Cone geoms that did not fit in the scene over the camera's life (zero unless a bug).
  long dropped_geoms() const { return dropped_geoms_; }

 private:
  // replaces MuJoCo's infinite ground plane by a plain square of asphalt around the rig
  void simplify_ground(const Eigen::Vector3d& centre);
  // the sun as a directional light, and the shadows it casts on the ground (shadow_triangles_)
  void add_sun(const core::Pose3& eye_in_track);
  // draws shadow_triangles_ over what mjr_render() drew from an eye
  void draw_shadows(const core::Pose3& eye_in_track) const;
  // the headlight's diffuse intensity: the config's, less the sun's
  double headlight_diffuse() const;
  // poses both GL cameras (and the headlight) at an eye, with the configured frustum
  void aim(const core::Pose3& eye_in_track);
  // renders the scene from one eye into an RGB image, and the depth buffer if depth_m is given
  void render_eye(const core::Pose3& eye_in_track, core::RgbImage& image,
                  std::vector<float>* depth_m);
  // the image through the lens from the canvas (nothing without a lens)
  void warp_canvas(core::RgbImage& out_image) const;
  // the rig's view volume, for skipping cones outside both images
  ViewVolume rig_view(const core::Pose3& left_in_track) const;
  // with distortion: where each image pixel takes its value from on the pinhole canvas
  void plan_warp();

  // one image pixel's source on the canvas: the top-left of its four neighbours (row-major,
  // rows top to bottom) and the weights of the right and lower ones
  struct WarpSample {
    int32_t index = 0;
    float wx = 0.f;
    float wy = 0.f;
    // the same weights in 1/256 (the blend in integers)
    uint32_t ix = 0;
    uint32_t iy = 0;
    // the nearest of the four (depth and segmentation are not blended across edges)
    int32_t nearest(int canvas_width) const {
      return index + (wx >= 0.5f ? 1 : 0) + (wy >= 0.5f ? canvas_width : 0);
    }
  };

  StereoCameraConfig config_;
  core::CameraIntrinsics intrinsics_;
  // what GL draws: the pinhole view, larger than the image when the lens distorts, so that
  // every image pixel's ray is on it (the image itself when it does not)
  core::CameraIntrinsics canvas_;
  std::vector<WarpSample> warp_;
  // for each image pixel, the centre of the canvas pixel warp_ takes its nearest value from, in
  // the pinhole image's pixel coordinates (SegmentationImage::pinhole_point)
  std::shared_ptr<const std::vector<Eigen::Vector2d>> nearest_pinhole_;
  core::RgbImage canvas_rgb_;
  std::vector<float> canvas_depth_;
  core::Pose3 left_in_vehicle_;
  core::Pose3 right_in_vehicle_;
  float frustum_half_height_ = 0.f;

  const mjModel* model_ = nullptr;
  mjData* scratch_ = nullptr;
  std::unique_ptr<OsMesaContext> gl_;
  std::unique_ptr<ConeSceneWriter> cones_;
  std::vector<tracks::SceneryObject> scenery_;
  tracks::GroundModel ground_;
  mjvScene scene_;
  mjrContext context_;
  mjvOption option_;
  mjvCamera free_camera_;
  mjvPerturb perturb_;
  std::vector<unsigned char> rgba_scratch_;
  // the sun's shadows on the ground for the frame being drawn: triangles in the track frame,
  // each vertex with its shadow's opacity
  struct ShadowVertex {
    float x, y, z, alpha;
  };
  std::vector<ShadowVertex> shadow_triangles_;
  // the motion blur: the exposure, the car's body the camera rides on, the eyes' velocity and
  // turn rate in the track frame for the frame being drawn, and buffers
  double exposure_s_ = 0.0;
  int chassis_body_ = -1;
  Eigen::Vector3d eye_velocity_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d eye_angular_velocity_ = Eigen::Vector3d::Zero();
  std::vector<float> blur_depth_;
  // the car's parts as spheres in the track frame (centre, radius), for the frame being drawn
  std::vector<Eigen::Vector4d> car_spheres_;
  std::vector<uint8_t> blur_scratch_;
  // the model's asphalt texture (when the config asks for one), and the size in metres over
  // which it repeats
  int asphalt_texture_ = -1;
  double asphalt_period_m_ = 0.0;
  ImageResponseFilter response_filter_;
  // 1 / length of each pixel's ray (x, y, 1) in the optical frame, rows top to bottom
  std::vector<float> inverse_ray_length_;
  std::vector<float> depth_scratch_;
  long dropped_geoms_ = 0;
  // the left eye of the last render(), for render_segmentation()
  core::Pose3 last_left_in_track_;
  bool rendered_ = false;
};

}  // namespace conesim::sensors
