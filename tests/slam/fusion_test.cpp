#include "slam/frontend/fusion.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>

#include "core/cone.hpp"
#include "sensors/stereo_camera.hpp"

namespace conesim::slam::frontend {
namespace {

using core::ConeClass;
using Eigen::Vector2d;
using Eigen::Vector3d;

// the default stereo rig's left camera, the one the fusion projects into
struct Rig {
  sensors::StereoCameraConfig config;
  core::CameraIntrinsics intrinsics = sensors::stereo_intrinsics(config);
  core::Pose3 left_in_vehicle = sensors::stereo_camera_in_vehicle(config, true);

  Vector3d project(const Vector3d& in_vehicle) const {
    const Vector3d q = left_in_vehicle.inverse().transform(in_vehicle);
    return {intrinsics.fx * q.x() / q.z() + intrinsics.cx,
            intrinsics.fy * q.y() / q.z() + intrinsics.cy, q.z()};
  }

  // the camera's view of a small cone at a vehicle-frame position: the box spanned by its base
  // and tip, the class seen, and the position measured (here exact, or shifted by `error`)
  CameraCone camera_cone(const Vector2d& position, ConeClass cls,
                         const Vector2d& error = Vector2d::Zero()) const {
    const core::ConeSize size = core::cone_size(cls);
    const Vector3d base = project({position.x(), position.y(), 0.0});
    const Vector3d tip = project({position.x(), position.y(), size.height_m});
    const double half_width = 0.5 * size.base_m * intrinsics.fx / base.z();
    CameraCone c;
    c.box = {static_cast<int>(std::floor(base.x() - half_width)),
             static_cast<int>(std::floor(tip.y())), static_cast<int>(std::ceil(2 * half_width)),
             static_cast<int>(std::ceil(base.y() - tip.y()))};
    // depth and disparity of the position measured
    const Vector2d measured = position + error;
    c.depth_m = project({measured.x(), measured.y(), 0.0}).z();
    c.disparity_px = intrinsics.fx * config.baseline_m / c.depth_m;
    c.observation.position = position + error;
    c.observation.cls = cls;
    c.observation.covariance = Eigen::Matrix2d::Identity() * 0.04;
    return c;
  }
};

LidarCone lidar_cone(const Vector2d& position, ConeClass cls = ConeClass::kUnknown) {
  LidarCone c;
  c.observation.position = position;
  c.observation.cls = cls;
  c.observation.covariance = Eigen::Matrix2d::Identity() * 0.0025;
  c.points = 20;
  return c;
}

// the fused cone nearest a position, or nullptr
const core::ConeObservation* nearest(const core::ConeObservations& cones, const Vector2d& p) {
  const core::ConeObservation* best = nullptr;
  for (const core::ConeObservation& c : cones.cones)
    if (!best || (c.position - p).norm() < (best->position - p).norm()) best = &c;
  return best;
}

TEST(Fusion, LidarConeInsideABoxTakesTheBoxClassAndKeepsItsPosition) {
  const Rig rig;
  LidarDetections lidar;
  lidar.stamp = 100;
  lidar.cones = {lidar_cone({8.0, 1.8}), lidar_cone({8.2, -1.7}), lidar_cone({14.0, 2.0})};
  StereoDetections camera;
  camera.stamp = 100;
  // the camera sees all three, 0.3 m off in depth (stereo is the less precise sensor)
  camera.cones = {rig.camera_cone({8.0, 1.8}, ConeClass::kBlue, {0.3, 0.0}),
                  rig.camera_cone({8.2, -1.7}, ConeClass::kYellow, {-0.3, 0.05}),
                  rig.camera_cone({14.0, 2.0}, ConeClass::kOrangeBig, {0.4, 0.0})};

  const core::ConeObservations fused =
      fuse({}, lidar, camera, rig.intrinsics, rig.left_in_vehicle, {});
  EXPECT_EQ(fused.stamp, 100);
  ASSERT_EQ(fused.cones.size(), 3u);  // no camera-only cones: the LiDAR explains every box
  const ConeClass expected[3] = {ConeClass::kBlue, ConeClass::kYellow, ConeClass::kOrangeBig};
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(fused.cones[i].cls, expected[i]) << i;
    EXPECT_EQ(fused.cones[i].position, lidar.cones[i].observation.position) << i;
    EXPECT_EQ(fused.cones[i].covariance, lidar.cones[i].observation.covariance) << i;
  }
}

TEST(Fusion, LidarConeOutsideEveryBoxKeepsItsOwnClass) {
  const Rig rig;
  LidarDetections lidar;
  // one cone in view but with no box, one behind the car, and one on the line of sight to a
  // far cone, 4 m away where the camera saw 16 m: a different object
  const Vector2d far(16.0, -3.2);
  const Vector2d eye = rig.left_in_vehicle.position.head<2>();
  const Vector2d near = eye + 0.25 * (far - eye);
  lidar.cones = {lidar_cone({9.0, 2.5}, ConeClass::kYellow), lidar_cone({-3.0, 1.0}),
                 lidar_cone(near)};
  StereoDetections camera;
  camera.cones = {rig.camera_cone({9.0, -1.8}, ConeClass::kBlue),
                  rig.camera_cone(far, ConeClass::kBlue)};
  // the far box grown down over the near cone's projection (as a wrong merge would): only the
  // depth keeps the two apart
  const Vector3d pixel = rig.project({near.x(), near.y(), FusionConfig{}.projection_height_m});
  PixelBox& box = camera.cones[1].box;
  ASSERT_TRUE(pixel.x() >= box.x && pixel.x() <= box.x + box.width - 1) << pixel.x();
  box.height = static_cast<int>(std::ceil(pixel.y())) + 2 - box.y;

  FusionConfig config;
  config.add_camera_only = false;
  const core::ConeObservations fused =
      fuse(config, lidar, camera, rig.intrinsics, rig.left_in_vehicle, {});
  ASSERT_EQ(fused.cones.size(), 3u);
  EXPECT_EQ(fused.cones[0].cls, ConeClass::kYellow);
  EXPECT_EQ(fused.cones[1].cls, ConeClass::kUnknown);
  EXPECT_EQ(fused.cones[2].cls, ConeClass::kUnknown);
}

TEST(Fusion, OverlappingBoxesGiveTheClassOfTheBoxTheConeIsCentredIn) {
  const Rig rig;
  // a big orange cone with a blue one just behind it and 0.25 m to the right: their boxes
  // overlap in the image, and the stereo depths, 0.15 m off each the other way, match the
  // other cone's LiDAR depth better than their own
  LidarDetections lidar;
  lidar.cones = {lidar_cone({14.6, 0.8}), lidar_cone({14.7, 0.55})};
  StereoDetections camera;
  camera.cones = {rig.camera_cone({14.6, 0.8}, ConeClass::kOrangeBig, {0.15, 0.0}),
                  rig.camera_cone({14.7, 0.55}, ConeClass::kBlue, {-0.15, 0.0})};
  const PixelBox& orange = camera.cones[0].box;
  const PixelBox& blue = camera.cones[1].box;
  ASSERT_LT(blue.x, orange.x + orange.width + 4);  // the margins overlap

  const core::ConeObservations fused =
      fuse({}, lidar, camera, rig.intrinsics, rig.left_in_vehicle, {});
  ASSERT_EQ(fused.cones.size(), 2u);
  EXPECT_EQ(fused.cones[0].cls, ConeClass::kOrangeBig);
  EXPECT_EQ(fused.cones[1].cls, ConeClass::kBlue);
}

TEST(Fusion, CameraOnlyConesAreAddedWhenConfigured) {
  const Rig rig;
  LidarDetections lidar;
  lidar.cones = {lidar_cone({8.0, 1.8})};
  StereoDetections camera;
  camera.cones = {rig.camera_cone({8.0, 1.8}, ConeClass::kBlue),
                  rig.camera_cone({12.0, -2.0}, ConeClass::kYellow)};

  const core::ConeObservations with =
      fuse({}, lidar, camera, rig.intrinsics, rig.left_in_vehicle, {});
  ASSERT_EQ(with.cones.size(), 2u);
  EXPECT_EQ(with.cones[0].cls, ConeClass::kBlue);
  EXPECT_EQ(with.cones[1].cls, ConeClass::kYellow);
  EXPECT_TRUE(with.cones[1].position.isApprox(Vector2d(12.0, -2.0)));
  EXPECT_EQ(with.cones[1].covariance, camera.cones[1].observation.covariance);

  FusionConfig colour_only;
  colour_only.add_camera_only = false;
  const core::ConeObservations without =
      fuse(colour_only, lidar, camera, rig.intrinsics, rig.left_in_vehicle, {});
  ASSERT_EQ(without.cones.size(), 1u);
  EXPECT_EQ(without.cones[0].cls, ConeClass::kBlue);
}

TEST(Fusion, CameraConeNearALidarConeIsNotAddedTwice) {
  const Rig rig;
  LidarDetections lidar;
  // the LiDAR cone misses the box (say the box is cut short) but sits 0.5 m from the camera cone
  lidar.cones = {lidar_cone({8.0, 1.8})};
  StereoDetections camera;
  CameraCone seen = rig.camera_cone({8.0, 1.8}, ConeClass::kBlue, {0.5, 0.0});
  seen.box.y -= 60;
  camera.cones = {seen};
  const core::ConeObservations fused =
      fuse({}, lidar, camera, rig.intrinsics, rig.left_in_vehicle, {});
  ASSERT_EQ(fused.cones.size(), 1u);
  EXPECT_EQ(fused.cones[0].cls, ConeClass::kUnknown);
}

TEST(Fusion, CameraFrameOfAnEarlierStampIsMovedIntoTheLidarFrame) {
  const Rig rig;
  // the stereo pair was taken when the car stood 1 m further back and turned 5 degrees left:
  // the camera's vehicle frame in the LiDAR's vehicle frame
  const core::Pose2 camera_in_lidar{-1.0, 0.0, 5.0 * std::numbers::pi / 180.0};
  const Vector2d blue_lidar(8.0, 1.8), yellow_lidar(12.0, -2.0);
  LidarDetections lidar;
  lidar.stamp = 200;
  lidar.cones = {lidar_cone(blue_lidar)};
  StereoDetections camera;
  camera.stamp = 150;
  const core::Pose2 lidar_in_camera = camera_in_lidar.inverse();
  camera.cones = {rig.camera_cone(lidar_in_camera.transform(blue_lidar), ConeClass::kBlue),
                  rig.camera_cone(lidar_in_camera.transform(yellow_lidar), ConeClass::kYellow)};

  const core::ConeObservations fused =
      fuse({}, lidar, camera, rig.intrinsics, rig.left_in_vehicle, camera_in_lidar);
  EXPECT_EQ(fused.stamp, 200);
  ASSERT_EQ(fused.cones.size(), 2u);
  EXPECT_EQ(fused.cones[0].cls, ConeClass::kBlue);
  EXPECT_EQ(fused.cones[1].cls, ConeClass::kYellow);
  EXPECT_TRUE(fused.cones[1].position.isApprox(yellow_lidar, 1e-9));
}

TEST(Fusion, WithoutCameraTheLidarConesPassThrough) {
  const Rig rig;
  LidarDetections lidar;
  lidar.stamp = 300;
  lidar.cones = {lidar_cone({8.0, 1.8}, ConeClass::kBlue), lidar_cone({8.0, -1.8}),
                 lidar_cone({12.0, 1.9}, ConeClass::kYellow)};
  const core::ConeObservations fused =
      fuse({}, lidar, std::nullopt, rig.intrinsics, rig.left_in_vehicle, {});
  EXPECT_EQ(fused.stamp, 300);
  ASSERT_EQ(fused.cones.size(), 3u);
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(fused.cones[i].cls, lidar.cones[i].observation.cls);
    EXPECT_EQ(fused.cones[i].position, lidar.cones[i].observation.position);
  }
}

TEST(Fusion, WithoutLidarTheCameraConesPassThrough) {
  const Rig rig;
  StereoDetections camera;
  camera.stamp = 400;
  camera.cones = {rig.camera_cone({8.0, 1.8}, ConeClass::kBlue),
                  rig.camera_cone({10.0, -1.8}, ConeClass::kYellow)};
  // even with camera-only cones switched off: the camera is all there is
  FusionConfig colour_only;
  colour_only.add_camera_only = false;
  const core::ConeObservations fused =
      fuse(colour_only, std::nullopt, camera, rig.intrinsics, rig.left_in_vehicle, {});
  EXPECT_EQ(fused.stamp, 400);
  ASSERT_EQ(fused.cones.size(), 2u);
  EXPECT_EQ(fused.cones[0].cls, ConeClass::kBlue);
  EXPECT_EQ(fused.cones[1].cls, ConeClass::kYellow);
  const core::ConeObservation* yellow = nearest(fused, {10.0, -1.8});
  ASSERT_NE(yellow, nullptr);
  EXPECT_TRUE(yellow->position.isApprox(Vector2d(10.0, -1.8)));

  EXPECT_TRUE(
      fuse({}, std::nullopt, std::nullopt, rig.intrinsics, rig.left_in_vehicle, {}).cones.empty());
}

TEST(Fusion, RejectsBadConfiguration) {
  FusionConfig config;
  EXPECT_TRUE(config.validate().empty());
  config.box_margin_px = -1.0;
  EXPECT_NE(config.validate().find("box_margin_px"), std::string::npos);
}

}  // namespace
}  // namespace conesim::slam::frontend
