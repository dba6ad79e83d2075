#include "slam/frontend/stereo_cone_detector.hpp"

#include <gtest/gtest.h>
#include <mujoco/mujoco.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/cone.hpp"
#include "core/rng.hpp"
#include "sensors/png_writer.hpp"
#include "sensors/stereo_camera.hpp"
#include "sim/vehicle_sim.hpp"
#include "slam/frontend/fusion.hpp"
#include "tracks/generator.hpp"
#include "tracks/track.hpp"
#include "vehicle_models/mjcf_builder.hpp"
#include "vehicle_models/vehicle_params.hpp"

namespace conesim::slam::frontend {
namespace {

using core::ConeClass;
using Eigen::Vector2d;
using Eigen::Vector3d;

// the distance bands scored, 5 m each from the left camera; the first two (within 10 m) are
// held to the requirements, the others only reported
constexpr int kBands = 4;
constexpr int kRequiredBands = 2;
constexpr double kBandM = 5.0;
// a detection counts for a true cone within this distance (cones on a track are >= 3 m apart)
constexpr double kMatchGateM = 1.5;

// the car's MuJoCo model posed by hand: the camera reads only qpos, no physics runs
class PosedCar {
 public:
  PosedCar()
      : model_(sim::load_mjcf_model(vehicle_models::build_mjcf(params_))),
        data_(mj_makeData(model_)) {}
  ~PosedCar() {
    mj_deleteData(data_);
    mj_deleteModel(model_);
  }
  PosedCar(const PosedCar&) = delete;
  PosedCar& operator=(const PosedCar&) = delete;

  // moves the chassis (free joint: position, then quaternion w x y z) to a planar pose and
  // returns the vehicle frame (rear axle centre on the ground) in the track frame
  core::Pose3 place(const core::Pose2& pose) {
    const Eigen::Quaterniond q(Eigen::AngleAxisd(pose.yaw, Vector3d::UnitZ()));
    const double qpos[7] = {pose.x, pose.y, params_.wheel_radius_m, q.w(), q.x(), q.y(), q.z()};
    std::copy(qpos, qpos + 7, data_->qpos);
    mj_kinematics(model_, data_);
    return {{pose.x, pose.y, 0.0}, q};
  }

  const mjModel* model() const { return model_; }
  const mjData* data() const { return data_; }

 private:
  vehicle_models::VehicleParams params_;
  mjModel* model_ = nullptr;
  mjData* data_ = nullptr;
};

// a rendered frame, the true vehicle pose and the cones a detector should find in it
struct LabelledFrame {
  core::StereoFrame frame;
  core::Pose3 vehicle_in_track;
  // the true cones in the vehicle frame, and which of them are fully in view and unoccluded
  std::vector<Vector2d> cones;
  std::vector<ConeClass> classes;
  std::vector<bool> visible;
};

// pixel of a vehicle-frame point in the left image and its depth; depth <= 0 behind the camera
Vector3d project(const core::StereoFrame& f, const Vector3d& in_vehicle) {
  const Vector3d q = f.left_in_vehicle.inverse().transform(in_vehicle);
  const core::CameraIntrinsics& k = f.intrinsics;
  return {k.fx * q.x() / q.z() + k.cx, k.fy * q.y() / q.z() + k.cy, q.z()};
}

// whether a cone is entirely inside the image (a small border aside) and not hidden behind
// another one, judged by the depth image at mid-height on its axis
bool fully_visible(const core::StereoFrame& f, const Vector2d& cone, ConeClass cls) {
  const core::ConeSize size = core::cone_size(cls);
  const double r = 0.5 * size.base_m;
  const int w = f.intrinsics.width_px, h = f.intrinsics.height_px;
  for (const Vector3d& corner :
       {Vector3d(cone.x(), cone.y() + r, 0.0), Vector3d(cone.x(), cone.y() - r, 0.0),
        Vector3d(cone.x() - r, cone.y(), 0.0), Vector3d(cone.x(), cone.y(), size.height_m)}) {
    const Vector3d px = project(f, corner);
    if (px.z() <= 0.1 || px.x() < 4 || px.x() > w - 5 || px.y() < 0 || px.y() > h - 1) return false;
  }
  const Vector3d mid = project(f, {cone.x(), cone.y(), 0.3 * size.height_m});
  const float seen = f.left_depth_m[static_cast<size_t>(std::lround(mid.y())) * w +
                                    static_cast<size_t>(std::lround(mid.x()))];
  return std::abs(seen - mid.z()) < 0.3;
}

// the left image with boxes drawn in a class colour and true cone axes marked, for viewing
core::RgbImage annotated(const LabelledFrame& lf, const StereoDetections& d) {
  core::RgbImage image = lf.frame.left;
  auto put = [&](int u, int v, uint8_t r, uint8_t g, uint8_t b) {
    if (u < 0 || v < 0 || u >= image.width_px || v >= image.height_px) return;
    uint8_t* p = image.rgb.data() + 3 * (static_cast<size_t>(v) * image.width_px + u);
    p[0] = r, p[1] = g, p[2] = b;
  };
  for (const CameraCone& c : d.cones) {
    const bool blue = c.observation.cls == ConeClass::kBlue;
    const uint8_t r = blue ? 0 : 255, g = c.observation.cls == ConeClass::kYellow ? 255 : 0;
    const uint8_t b = blue ? 255 : 0;
    for (int u = c.box.x - 1; u <= c.box.x + c.box.width; ++u)
      put(u, c.box.y - 1, r, g, b), put(u, c.box.y + c.box.height, r, g, b);
    for (int v = c.box.y - 1; v <= c.box.y + c.box.height; ++v)
      put(c.box.x - 1, v, r, g, b), put(c.box.x + c.box.width, v, r, g, b);
  }
  for (size_t i = 0; i < lf.cones.size(); ++i) {
    if (!lf.visible[i]) continue;
    const Vector3d px = project(lf.frame, {lf.cones[i].x(), lf.cones[i].y(), 0.0});
    for (int du = -2; du <= 2; ++du) put(int(px.x()) + du, int(px.y()) + 3, 255, 0, 255);
  }
  return image;
}

// frames rendered along the centre line of a generated circuit, every few metres
class RenderedTrack : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    frames_ = new std::vector<LabelledFrame>();
    PosedCar car;
    for (const uint64_t seed : {11u, 23u}) {
      const tracks::Track track = tracks::generate_circuit(seed);
      const std::vector<core::Vec2> line = tracks::derive_centre_line(track, 1.0);
      sensors::StereoCamera camera({}, car.model(), track);
      constexpr size_t kStepM = 9;
      for (size_t i = 0; i + 1 < line.size(); i += kStepM) {
        // the rear axle 1.5 m behind a centre-line point, half a metre to either side in turn,
        // heading along the line give or take 5 degrees
        const Vector2d dir = (line[i + 1] - line[i]).normalized();
        const double side = (i / kStepM) % 2 ? 0.5 : -0.5;
        const double yaw = std::atan2(dir.y(), dir.x()) + side * 0.17;
        const Vector2d rear = line[i] - 1.5 * dir + side * Vector2d(-dir.y(), dir.x());
        LabelledFrame lf;
        lf.vehicle_in_track = car.place({rear.x(), rear.y(), yaw});
        core::StereoLabels labels;
        camera.render(car.data(), lf.vehicle_in_track, static_cast<core::TimeUs>(i), {}, true,
                      lf.frame, labels);
        const core::Pose2 vehicle = lf.vehicle_in_track.planar();
        for (const tracks::Cone& cone : track.cones) {
          const Vector2d p = vehicle.inverse_transform(cone.position);
          lf.cones.push_back(p);
          lf.classes.push_back(cone.cls);
          lf.visible.push_back(fully_visible(lf.frame, p, cone.cls));
        }
        frames_->push_back(std::move(lf));
      }
    }
  }
  static void TearDownTestSuite() {
    delete frames_;
    frames_ = nullptr;
  }
  static std::vector<LabelledFrame>* frames_;
};
std::vector<LabelledFrame>* RenderedTrack::frames_ = nullptr;

// what a detector achieved over the frames, per distance band
struct Score {
  int visible[kBands] = {};
  int found[kBands] = {};
  double squared_error[kBands] = {};
  // within 10 m: matched cones whose class is right, all matched, and matched per true class
  int class_correct = 0;
  int matched = 0;
  int per_class[5] = {};
  int false_positives = 0;
  // squared Mahalanobis distances of the errors under the reported covariance, all bands
  std::vector<double> mahalanobis2;
  std::vector<double> ms;

  double recall(int band) const { return visible[band] ? double(found[band]) / visible[band] : 0; }
  double recall_all() const {
    return double(found[0] + found[1]) / std::max(1, visible[0] + visible[1]);  // within 10 m
  }
  double rmse(int band) const {
    return found[band] ? std::sqrt(squared_error[band] / found[band]) : 0;
  }
  double class_accuracy() const { return matched ? double(class_correct) / matched : 0.0; }
  double median_ms() const {
    std::vector<double> s = ms;
    std::nth_element(s.begin(), s.begin() + s.size() / 2, s.end());
    return s[s.size() / 2];
  }
};

// processor time used by the process (OpenCV's worker threads included), milliseconds
double cpu_ms() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return 1e3 * static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_nsec);
}

Score score(const StereoDetectorConfig& config, const std::vector<LabelledFrame>& frames,
            const char* dump_prefix) {
  const StereoConeDetector detector(config);
  Score s;
  const char* dump_dir = std::getenv("CONESIM_DUMP_DIR");
  for (size_t f = 0; f < frames.size(); ++f) {
    const LabelledFrame& lf = frames[f];
    // processor time: the shared test machine's load does not count
    const double start_ms = cpu_ms();
    const StereoDetections d = detector.detect(lf.frame);
    s.ms.push_back(cpu_ms() - start_ms);
    if (dump_dir)
      sensors::write_png(std::string(dump_dir) + "/" + dump_prefix + std::to_string(f) + ".png",
                         annotated(lf, d));

    // greedy one-to-one matching of detections to true cones, nearest pairs first
    const Vector2d camera = lf.frame.left_in_vehicle.position.head<2>();
    struct Pair {
      double distance;
      size_t truth, detection;
    };
    std::vector<Pair> pairs;
    for (size_t t = 0; t < lf.cones.size(); ++t)
      for (size_t i = 0; i < d.cones.size(); ++i) {
        const double e = (lf.cones[t] - d.cones[i].observation.position).norm();
        if (e < kMatchGateM) pairs.push_back({e, t, i});
      }
    std::sort(pairs.begin(), pairs.end(),
              [](const Pair& a, const Pair& b) { return a.distance < b.distance; });
    std::vector<bool> truth_used(lf.cones.size(), false), detection_used(d.cones.size(), false);
    for (const Pair& p : pairs) {
      if (truth_used[p.truth] || detection_used[p.detection]) continue;
      truth_used[p.truth] = detection_used[p.detection] = true;
      const double range = (lf.cones[p.truth] - camera).norm();
      if (!lf.visible[p.truth] || range >= kBands * kBandM) continue;
      const int band = static_cast<int>(range / kBandM);
      const core::ConeObservation& o = d.cones[p.detection].observation;
      ++s.found[band];
      s.squared_error[band] += p.distance * p.distance;
      const Vector2d e = o.position - lf.cones[p.truth];
      s.mahalanobis2.push_back(e.dot(o.covariance.ldlt().solve(e)));
      if (band >= kRequiredBands) continue;
      ++s.matched;
      ++s.per_class[static_cast<int>(lf.classes[p.truth])];
      s.class_correct += o.cls == lf.classes[p.truth];
    }
    for (size_t t = 0; t < lf.cones.size(); ++t) {
      const double range = (lf.cones[t] - camera).norm();
      if (!lf.visible[t] || range >= kBands * kBandM) continue;
      ++s.visible[static_cast<int>(range / kBandM)];
      if (dump_dir && !truth_used[t] && range < kRequiredBands * kBandM) {
        const Vector3d px = project(lf.frame, {lf.cones[t].x(), lf.cones[t].y(), 0.0});
        std::printf("  missed frame %zu: %s at %.1f m, pixel %.0f %.0f\n", f,
                    std::string(core::to_string(lf.classes[t])).c_str(), range, px.x(), px.y());
      }
    }
    for (size_t i = 0; i < d.cones.size(); ++i)
      if (!detection_used[i] &&
          (d.cones[i].observation.position - camera).norm() < kRequiredBands * kBandM) {
        ++s.false_positives;
        if (dump_dir)
          std::printf("  false positive frame %zu: box %d %d %d %d at %.1f %.1f\n", f,
                      d.cones[i].box.x, d.cones[i].box.y, d.cones[i].box.width,
                      d.cones[i].box.height, d.cones[i].observation.position.x(),
                      d.cones[i].observation.position.y());
      }
  }
  return s;
}

void print(const char* name, const Score& s) {
  std::printf(
      "[%s] recall within 10 m %.3f, class accuracy %.3f over %d (blue %d, yellow %d, "
      "orange %d, big orange %d), false positives within 10 m %d, median %.2f ms (CPU) per pair\n",
      name, s.recall_all(), s.class_accuracy(), s.matched, s.per_class[0], s.per_class[1],
      s.per_class[2], s.per_class[3], s.false_positives, s.median_ms());
  for (int b = 0; b < kBands; ++b)
    std::printf("[%s]   %2.0f-%2.0f m: recall %3d/%3d = %.3f, RMSE %.3f m\n", name, b * kBandM,
                (b + 1) * kBandM, s.found[b], s.visible[b], s.recall(b), s.rmse(b));
}

TEST_F(RenderedTrack, FindsAndPlacesConesWithTipTriangulation) {
  StereoDetectorConfig config;
  config.triangulate_tip = true;
  const Score s = score(config, *frames_, "tip_");
  print("tip", s);
  ASSERT_GT(s.visible[0] + s.visible[1], 50) << "too few cones in view to judge";
  EXPECT_GE(s.recall_all(), 0.9);
  EXPECT_LE(s.rmse(1), 0.3);
  EXPECT_GE(s.class_accuracy(), 0.95);
}

TEST_F(RenderedTrack, FindsAndPlacesConesWithCentreTriangulation) {
  StereoDetectorConfig config;
  config.triangulate_tip = false;
  const Score s = score(config, *frames_, "centre_");
  print("centre", s);
  EXPECT_GE(s.recall_all(), 0.9);
  EXPECT_LE(s.rmse(1), 0.3);
  EXPECT_GE(s.class_accuracy(), 0.95);
}

TEST_F(RenderedTrack, CovarianceFitsTheErrors) {
  // with an honest covariance the squared Mahalanobis errors follow a chi-square with two
  // degrees of freedom: nine in ten fall below 4.61 and their mean is 2. The model has to
  // cover the worse of the two triangulations, so it may be cautious for the better one, but
  // not by more than a factor of two in sigma (mean at least 2 / 4)
  for (const bool tip : {true, false}) {
    StereoDetectorConfig config;
    config.triangulate_tip = tip;
    const Score s = score(config, *frames_, tip ? "cov_tip_" : "cov_centre_");
    ASSERT_FALSE(s.mahalanobis2.empty());
    const double within = std::count_if(s.mahalanobis2.begin(), s.mahalanobis2.end(),
                                        [](double m2) { return m2 < 4.61; }) /
                          static_cast<double>(s.mahalanobis2.size());
    double mean = 0.0;
    for (const double m2 : s.mahalanobis2) mean += m2 / s.mahalanobis2.size();
    std::printf("[%s] errors inside the 90 %% ellipse %.3f, mean squared Mahalanobis %.2f\n",
                tip ? "tip" : "centre", within, mean);
    EXPECT_GE(within, 0.8) << (tip ? "tip" : "centre");
    EXPECT_GE(mean, 0.5) << (tip ? "tip" : "centre");
  }
}

TEST_F(RenderedTrack, DepthSigmaGrowsWithTheSquareOfDepth) {
  const StereoConeDetector detector({});
  const StereoDetectorConfig& c = detector.config();
  int checked = 0;
  for (const LabelledFrame& lf : *frames_) {
    const StereoDetections d = detector.detect(lf.frame);
    for (const CameraCone& cone : d.cones) {
      // the disparity noise stretches the point along its viewing ray by sigma_d / d times
      // the ray's length: depth * range * sigma_d / (f B), i.e. depth squared on the axis
      const Vector2d offset =
          cone.observation.position - lf.frame.left_in_vehicle.position.head<2>();
      const Vector2d ray = offset.normalized();
      const double along = ray.dot(cone.observation.covariance * ray) - c.min_variance_m2;
      const double sigma = cone.depth_m * offset.norm() * c.disparity_sigma_px /
                           (lf.frame.intrinsics.fx * lf.frame.baseline_m);
      EXPECT_NEAR(std::sqrt(along) / sigma, 1.0, 0.05) << "depth " << cone.depth_m;
      ++checked;
    }
  }
  EXPECT_GT(checked, 50);
}

TEST_F(RenderedTrack, FusionColoursLidarConesFromRenderedFrames) {
  // LiDAR cones made by hand from the truth (2 cm noise, no colour) for every cone ahead within
  // 15 m; the camera's detections of the rendered frame colour them
  const StereoConeDetector detector({});
  core::Rng rng(6);
  int in_view = 0, coloured_right = 0, coloured_wrong = 0;
  for (const LabelledFrame& lf : *frames_) {
    const StereoDetections camera = detector.detect(lf.frame);
    LidarDetections lidar;
    lidar.stamp = lf.frame.stamp;
    std::vector<size_t> truth;
    for (size_t t = 0; t < lf.cones.size(); ++t) {
      if (lf.cones[t].x() < 0.5 || lf.cones[t].norm() > 15.0) continue;
      LidarCone c;
      c.observation.position =
          lf.cones[t] + Vector2d(core::gaussian(rng, 0.0, 0.02), core::gaussian(rng, 0.0, 0.02));
      lidar.cones.push_back(c);
      truth.push_back(t);
    }
    const core::ConeObservations fused =
        fuse({}, lidar, camera, lf.frame.intrinsics, lf.frame.left_in_vehicle, core::Pose2{});
    ASSERT_GE(fused.cones.size(), lidar.cones.size());
    for (size_t i = 0; i < truth.size(); ++i) {
      const ConeClass cls = fused.cones[i].cls;
      const size_t t = truth[i];
      const double range = (lf.cones[t] - lf.frame.left_in_vehicle.position.head<2>()).norm();
      if (lf.visible[t] && range < kRequiredBands * kBandM) {
        ++in_view;
        coloured_right += cls == lf.classes[t];
      }
      if (cls != ConeClass::kUnknown && cls != lf.classes[t]) {
        ++coloured_wrong;
        std::printf("  wrong colour: %s coloured %s at %.1f %.1f (%s)\n",
                    std::string(core::to_string(lf.classes[t])).c_str(),
                    std::string(core::to_string(cls)).c_str(), lf.cones[t].x(), lf.cones[t].y(),
                    lf.visible[t] ? "in view" : "not fully in view");
      }
    }
  }
  std::printf("[fusion] LiDAR cones in view within 10 m coloured right %d/%d, wrong colours %d\n",
              coloured_right, in_view, coloured_wrong);
  ASSERT_GT(in_view, 50);
  EXPECT_GE(static_cast<double>(coloured_right) / in_view, 0.9);
  EXPECT_EQ(coloured_wrong, 0);
}

TEST(StereoConeDetector, TellsEveryClassApart) {
  // a hand-made layout ahead of the car with all four classes at 4 to 12 m, each cone on its
  // own bearing so that none hides another
  tracks::Track track;
  track.name = "classes";
  const std::vector<std::pair<ConeClass, Vector2d>> layout = {
      {ConeClass::kOrangeSmall, {6.0, 1.5}},  {ConeClass::kOrangeSmall, {10.0, -0.2}},
      {ConeClass::kOrangeSmall, {12.0, 0.4}}, {ConeClass::kOrangeBig, {4.5, -0.6}},
      {ConeClass::kOrangeBig, {7.0, -2.2}},   {ConeClass::kOrangeBig, {11.0, 1.8}},
      {ConeClass::kBlue, {5.0, 2.0}},         {ConeClass::kYellow, {9.0, -4.2}}};
  for (size_t i = 0; i < layout.size(); ++i)
    track.cones.push_back({static_cast<int>(i) + 1, layout[i].first, layout[i].second, {}});
  PosedCar car;
  sensors::StereoCamera camera({}, car.model(), track);
  core::StereoFrame frame;
  core::StereoLabels labels;
  camera.render(car.data(), car.place({0.0, 0.0, 0.0}), 0, {}, false, frame, labels);

  const StereoDetections d = StereoConeDetector({}).detect(frame);
  if (const char* dump_dir = std::getenv("CONESIM_DUMP_DIR")) {
    LabelledFrame lf;
    lf.frame = frame;
    sensors::write_png(std::string(dump_dir) + "/classes.png", annotated(lf, d));
    for (const CameraCone& c : d.cones)
      std::printf("  %s at %.2f %.2f box %d %d %d %d\n",
                  std::string(core::to_string(c.observation.cls)).c_str(),
                  c.observation.position.x(), c.observation.position.y(), c.box.x, c.box.y,
                  c.box.width, c.box.height);
  }
  for (const auto& [cls, position] : layout) {
    const CameraCone* found = nullptr;
    for (const CameraCone& c : d.cones)
      if ((c.observation.position - position).norm() < 0.5) found = &c;
    ASSERT_NE(found, nullptr) << core::to_string(cls) << " at " << position.transpose();
    EXPECT_EQ(found->observation.cls, cls)
        << core::to_string(cls) << " at " << position.transpose();
  }
  EXPECT_EQ(d.cones.size(), layout.size());
}

TEST(StereoConeDetector, EmptyFrameGivesNoCones) {
  const StereoConeDetector detector({});
  core::StereoFrame frame;
  frame.stamp = 42;
  const StereoDetections d = detector.detect(frame);
  EXPECT_EQ(d.stamp, 42);
  EXPECT_TRUE(d.cones.empty());
  EXPECT_TRUE(d.observations().cones.empty());
}

TEST(StereoConeDetector, RejectsBadConfiguration) {
  StereoDetectorConfig config;
  config.blue_hsv.h_max = 200;
  EXPECT_NE(config.validate().find("blue_hsv"), std::string::npos);
  EXPECT_THROW(StereoConeDetector{config}, std::invalid_argument);
  config = {};
  config.disparity_sigma_px = 0.0;
  EXPECT_NE(config.validate().find("disparity_sigma_px"), std::string::npos);
  EXPECT_TRUE(StereoDetectorConfig{}.validate().empty());
}

}  // namespace
}  // namespace conesim::slam::frontend
