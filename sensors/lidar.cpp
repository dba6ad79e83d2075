#include "sensors/lidar.hpp"

#include <embree3/rtcore.h>

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

namespace conesim::sensors {

namespace {

constexpr int kPacketSize = 16;
constexpr int kClassCount = 5;
// the ground quad reaches this far beyond the cones and the start, on top of the max range
constexpr double kGroundMarginM = 20.0;
// rays are cut this far above the tallest cone
constexpr double kTopSlackM = 0.01;

// gaussian samples by the polar form of Box-Muller (Marsaglia) on core::uniform: no sine or
// cosine, and both values of each pair are used
class NormalSampler {
 public:
  explicit NormalSampler(core::Rng& rng) : rng_(rng) {}
  float next() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    float u, v, s;
    do {
      u = static_cast<float>(core::uniform(rng_, -1.0, 1.0));
      v = static_cast<float>(core::uniform(rng_, -1.0, 1.0));
      s = u * u + v * v;
    } while (s >= 1.f || s == 0.f);
    // single precision: a noise sample needs no more, and logf costs a third of log
    const float f = std::sqrt(-2.f * std::log(s) / s);
    spare_ = v * f;
    has_spare_ = true;
    return u * f;
  }

 private:
  core::Rng& rng_;
  bool has_spare_ = false;
  float spare_ = 0.f;
};

// how far a ray can find anything: down to just past the ground plane, or up to where it
// climbs above the tallest cone (0 when it starts above everything and does not descend)
float ray_length(float origin_z, float dir_z, float max_range, float top_z) {
  constexpr float kGroundSlackM = 1e-3f;
  if (dir_z < 0.f) return std::min(max_range, -origin_z / dir_z * 1.0001f + kGroundSlackM);
  if (origin_z >= top_z) return 0.f;
  if (dir_z > 0.f) return std::min(max_range, (top_z - origin_z) / dir_z);
  return max_range;
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

}  // namespace

struct Lidar::Impl {
  // one beam of a column, in ring order
  struct Channel {
    float cos_elevation;
    float sin_elevation;
  };
  // what a geometry id stands for: a cone (with its class) or the ground
  struct GeometryInfo {
    int cone_id = core::PointCloudLabels::kGroundLabel;
    int cls = -1;
    bool present = true;
  };

  LidarConfig config;
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  std::vector<Channel> channels;
  std::vector<float> column_cos;
  std::vector<float> column_sin;
  std::vector<core::TimeUs> column_offset_us;
  std::array<float, kSurfaceMaterialCount> reflectivity{};
  std::array<std::vector<SurfaceMaterial>, kClassCount> class_materials;
  std::vector<GeometryInfo> geometries;
  // nothing in the scene is higher than this: rays are cut where they climb above it
  float scene_top_z = 0.f;
  std::unordered_map<int, unsigned> cone_geometry;

  ~Impl() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }

  // a packet of rays with their directions in the sensor frame and the lanes in use
  struct Packet {
    RTCRayHit16 rays;
    std::array<int, kPacketSize> valid{};
    std::array<Eigen::Vector3f, kPacketSize> local_dir;
  };

  void build_beams();
  void build_scene(const tracks::Track& track);
  void throw_on_device_error(const char* what) const;
  void aim_packet(const core::Pose3& pose, int column, int first, int lanes, Packet& packet) const;
  std::optional<core::LidarPoint> measure(const Packet& packet, int lane, core::Rng& rng,
                                          NormalSampler& normal, LidarSweepStats& stats) const;
};

void Lidar::Impl::aim_packet(const core::Pose3& pose, int column, int first, int lanes,
                             Packet& packet) const {
  const Eigen::Matrix3f rotation = pose.orientation.toRotationMatrix().cast<float>();
  const Eigen::Vector3f origin = pose.position.cast<float>();
  const float max_range = static_cast<float>(config.max_range_m);
  RTCRay16& ray = packet.rays.ray;
  for (int i = 0; i < kPacketSize; ++i) {
    // lanes past the column's last beam stay idle
    packet.valid[i] = i < lanes ? -1 : 0;
    packet.rays.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
    if (i >= lanes) continue;

    // the beam's direction in the sensor frame and in the track frame
    const Channel& ch = channels[first + i];
    packet.local_dir[i] = {ch.cos_elevation * column_cos[column],
                           ch.cos_elevation * column_sin[column], ch.sin_elevation};
    const Eigen::Vector3f d = rotation * packet.local_dir[i];

    // the ray, as long as it can find anything (a beam that cannot is not cast)
    ray.org_x[i] = origin.x();
    ray.org_y[i] = origin.y();
    ray.org_z[i] = origin.z();
    ray.dir_x[i] = d.x();
    ray.dir_y[i] = d.y();
    ray.dir_z[i] = d.z();
    ray.tnear[i] = 0.f;
    ray.tfar[i] = ray_length(origin.z(), d.z(), max_range, scene_top_z);
    if (ray.tfar[i] <= 0.f) packet.valid[i] = 0;
    ray.time[i] = 0.f;
    ray.mask[i] = 0xFFFFFFFFu;
    ray.id[i] = static_cast<unsigned>(i);
    ray.flags[i] = 0;
  }
}

std::optional<core::LidarPoint> Lidar::Impl::measure(const Packet& packet, int lane, core::Rng& rng,
                                                     NormalSampler& normal,
                                                     LidarSweepStats& stats) const {
  const RTCRay16& ray = packet.rays.ray;
  const RTCHit16& hit = packet.rays.hit;

  // a return, unless the dropout takes it
  ++stats.hits;
  if (config.dropout_probability > 0.0 &&
      core::uniform(rng, 0.0, 1.0) < config.dropout_probability) {
    ++stats.dropped;
    return std::nullopt;
  }

  // range noise; a noisy range outside the sensor's window is no return
  const float range = ray.tfar[lane];
  const float sigma = static_cast<float>(config.range_noise_sigma_m);
  const float measured = sigma > 0.f ? range + sigma * normal.next() : range;
  if (measured < config.min_range_m || measured > config.max_range_m) {
    ++stats.out_of_range;
    return std::nullopt;
  }

  // intensity: the material's reflectivity, times the cosine of incidence and the range
  // fall-off, plus noise
  const GeometryInfo& info = geometries[hit.geomID[lane]];
  const SurfaceMaterial material =
      info.cls < 0 ? SurfaceMaterial::kGround : class_materials[info.cls][hit.primID[lane]];
  const Eigen::Vector3f surface_normal(hit.Ng_x[lane], hit.Ng_y[lane], hit.Ng_z[lane]);
  const Eigen::Vector3f dir(ray.dir_x[lane], ray.dir_y[lane], ray.dir_z[lane]);
  const float cos_incidence = std::abs(dir.dot(surface_normal)) / surface_normal.norm();
  const float falloff = static_cast<float>(config.intensity_falloff_m);
  float intensity = 255.f * reflectivity[static_cast<int>(material)] * cos_incidence /
                    (1.f + (range * range) / (falloff * falloff));
  if (config.intensity_noise_sigma > 0.0)
    intensity += static_cast<float>(config.intensity_noise_sigma) * normal.next();

  // the point in the sensor frame of its column (ring and time are the caller's)
  const Eigen::Vector3f p = packet.local_dir[lane] * measured;
  return core::LidarPoint{p.x(), p.y(), p.z(), std::clamp(intensity, 0.f, 255.f), 0, 0.f};
}

void Lidar::Impl::build_beams() {
  // channels sorted by elevation: ring 0 is the lowest beam
  std::vector<double> elevations = config.elevations_deg;
  std::sort(elevations.begin(), elevations.end());
  for (double e : elevations) {
    const double rad = e * std::numbers::pi / 180.0;
    channels.push_back({static_cast<float>(std::cos(rad)), static_cast<float>(std::sin(rad))});
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

  // reflectivity per material
  for (int m = 0; m < kSurfaceMaterialCount; ++m)
    reflectivity[m] = static_cast<float>(config.reflectivity.of(static_cast<SurfaceMaterial>(m)));
}

void Lidar::Impl::build_scene(const tracks::Track& track) {
  device = rtcNewDevice("threads=1");
  if (!device) throw std::runtime_error("lidar: Embree device could not be created");
  scene = rtcNewScene(device);
  // medium quality: rays are as fast as with a high-quality build here, and a knocked cone's
  // rebuild is a quarter cheaper
  rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_MEDIUM);

  // ground: one quad over the cones and the start pose, reaching the max range beyond them
  Eigen::Vector2d lo(track.start.x, track.start.y), hi = lo;
  for (const tracks::Cone& cone : track.cones) {
    lo = lo.cwiseMin(cone.position);
    hi = hi.cwiseMax(cone.position);
  }
  const double margin = config.max_range_m + kGroundMarginM;
  lo.array() -= margin;
  hi.array() += margin;
  const std::vector<Eigen::Vector3f> ground_vertices{
      {static_cast<float>(lo.x()), static_cast<float>(lo.y()), 0.f},
      {static_cast<float>(hi.x()), static_cast<float>(lo.y()), 0.f},
      {static_cast<float>(hi.x()), static_cast<float>(hi.y()), 0.f},
      {static_cast<float>(lo.x()), static_cast<float>(hi.y()), 0.f}};
  RTCGeometry ground = make_triangle_geometry(device, ground_vertices, {{0, 1, 2}, {0, 2, 3}});
  const unsigned ground_id = rtcAttachGeometry(scene, ground);
  rtcReleaseGeometry(ground);
  geometries.resize(ground_id + 1);

  // one mesh per class, its materials shared by every cone of the class
  std::array<ConeMesh, kClassCount> meshes;
  for (int k = 0; k < kClassCount; ++k) {
    meshes[k] =
        build_cone_mesh(cone_shape(static_cast<core::ConeClass>(k)), config.cone_mesh_sides);
    class_materials[k] = meshes[k].materials;
  }

  // every cone: its class mesh moved to the cone's place, one geometry each
  for (const tracks::Cone& cone : track.cones) {
    const int k = class_index(cone.cls);
    std::vector<Eigen::Vector3f> vertices = meshes[k].vertices;
    const Eigen::Vector3f offset(static_cast<float>(cone.position.x()),
                                 static_cast<float>(cone.position.y()), 0.f);
    for (Eigen::Vector3f& v : vertices) v += offset;
    RTCGeometry geom = make_triangle_geometry(device, vertices, meshes[k].triangles);
    const unsigned id = rtcAttachGeometry(scene, geom);
    rtcReleaseGeometry(geom);
    if (geometries.size() <= id) geometries.resize(id + 1);
    geometries[id] = {cone.id, k, true};
    scene_top_z =
        std::max(scene_top_z, static_cast<float>(cone_shape(cone.cls).height_m + kTopSlackM));
    cone_geometry[cone.id] = id;
  }
  rtcCommitScene(scene);
  throw_on_device_error("building the scene");
}

void Lidar::Impl::throw_on_device_error(const char* what) const {
  const RTCError error = rtcGetDeviceError(device);
  if (error != RTC_ERROR_NONE)
    throw std::runtime_error(std::string("lidar: Embree error ") +
                             std::to_string(static_cast<int>(error)) + " while " + what);
}

Lidar::Lidar(const LidarConfig& config, const tracks::Track& track)
    : impl_(std::make_unique<Impl>()) {
  if (const std::string error = config.validate(); !error.empty())
    throw std::invalid_argument("lidar: " + error);
  impl_->config = config;
  impl_->build_beams();
  impl_->build_scene(track);
}

Lidar::~Lidar() = default;
Lidar::Lidar(Lidar&&) noexcept = default;
Lidar& Lidar::operator=(Lidar&&) noexcept = default;

const LidarConfig& Lidar::config() const {
  return impl_->config;
}

void Lidar::set_cone_present(int cone_id, bool present) {
  const auto it = impl_->cone_geometry.find(cone_id);
  if (it == impl_->cone_geometry.end())
    throw std::out_of_range("lidar: no cone with id " + std::to_string(cone_id));
  Impl::GeometryInfo& info = impl_->geometries[it->second];
  if (info.present == present) return;

  // enabling or disabling a geometry takes effect at the next scene commit
  info.present = present;
  RTCGeometry geom = rtcGetGeometry(impl_->scene, it->second);
  if (present)
    rtcEnableGeometry(geom);
  else
    rtcDisableGeometry(geom);
  rtcCommitScene(impl_->scene);
  impl_->throw_on_device_error("updating the scene");
}

bool Lidar::cone_present(int cone_id) const {
  const auto it = impl_->cone_geometry.find(cone_id);
  return it != impl_->cone_geometry.end() && impl_->geometries[it->second].present;
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
  const Impl& im = *impl_;
  const LidarConfig& cfg = im.config;
  const int channel_count = static_cast<int>(im.channels.size());

  // the poses must span every column's firing time
  const core::TimeUs end = sweep_end(sweep_start);
  if (!vehicle_poses.covers(sweep_start, end)) {
    std::ostringstream msg;
    msg << "lidar sweep: the sweep needs poses over [" << sweep_start << ", " << end
        << "] us, the history covers ";
    if (vehicle_poses.empty())
      msg << "nothing";
    else
      msg << "[" << vehicle_poses.oldest() << ", " << vehicle_poses.newest() << "] us";
    throw std::invalid_argument(msg.str());
  }

  // the scan, its labels and the sensor poses at the first and last columns
  LidarScan scan;
  scan.cloud.stamp = sweep_start;
  scan.cloud.points.reserve(static_cast<size_t>(cfg.columns) * channel_count / 2);
  scan.labels.cone_id.reserve(scan.cloud.points.capacity());
  scan.labels.sensor_pose_start = sensor_pose(vehicle_poses.at(sweep_start));
  scan.labels.sensor_pose_end = sensor_pose(vehicle_poses.at(end));

  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  NormalSampler normal(rng);
  Impl::Packet packet;

  for (int c = 0; c < cfg.columns; ++c) {
    // the sensor pose when this column fires
    const core::TimeUs offset_us = im.column_offset_us[c];
    const core::Pose3 pose = sensor_pose(vehicle_poses.at(sweep_start + offset_us));
    const float time_offset_s = static_cast<float>(core::to_seconds(offset_us));

    for (int first = 0; first < channel_count; first += kPacketSize) {
      // one packet of up to 16 beams of the column, cast together
      const int lanes = std::min(kPacketSize, channel_count - first);
      im.aim_packet(pose, c, first, lanes, packet);
      rtcIntersect16(packet.valid.data(), im.scene, &context, &packet.rays);
      scan.stats.rays += lanes;

      // each hit becomes a point, unless a fault or the range window takes it
      for (int i = 0; i < lanes; ++i) {
        if (packet.rays.hit.geomID[i] == RTC_INVALID_GEOMETRY_ID) continue;
        const std::optional<core::LidarPoint> point =
            im.measure(packet, i, rng, normal, scan.stats);
        if (!point) continue;
        scan.cloud.points.push_back(*point);
        scan.cloud.points.back().ring = static_cast<uint16_t>(first + i);
        scan.cloud.points.back().time_offset_s = time_offset_s;
        scan.labels.cone_id.push_back(im.geometries[packet.rays.hit.geomID[i]].cone_id);
      }
    }
  }
  return scan;
}

}  // namespace conesim::sensors
