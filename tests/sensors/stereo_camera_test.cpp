#include "sensors/stereo_camera.hpp"

#include <gtest/gtest.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>
#include <opencv2/calib3d.hpp>
#include <optional>
#include <set>
#include <utility>
#include <vector>

#include "core/cone_geometry.hpp"
#include "sensors/png_writer.hpp"
#include "sim/vehicle_sim.hpp"
#include "tracks/scenery.hpp"
#include "vehicle_models/vehicle_params.hpp"

namespace conesim::sensors {
namespace {

using core::ConeClass;
using Eigen::Vector2d;
using Eigen::Vector3d;

constexpr int kBlueAhead = 1;
constexpr int kYellowLeft = 2;
constexpr int kBigOrangeRight = 3;
constexpr int kBlueRight = 4;

// a pixel's colour, 0-255
struct Rgb {
  int r, g, b;
};

bool is_blue(Rgb c) {
  return c.b > c.r + 60 && c.b > c.g + 30;
}
bool is_yellow(Rgb c) {
  return c.r > 120 && c.g > 100 && c.b < c.g / 2;
}
bool is_orange(Rgb c) {
  return c.r > 150 && c.g < c.r * 3 / 4 && c.b < c.r / 3;
}
bool is_grey(Rgb c) {
  return std::abs(c.r - c.g) < 20 && std::abs(c.g - c.b) < 25 && c.r > 25 && c.r < 170;
}
bool is_sky(Rgb c) {
  return c.b > 150 && c.b >= c.r && c.b >= c.g;
}

Rgb pixel(const core::RgbImage& image, int u, int v) {
  const uint8_t* p = image.rgb.data() + 3 * (static_cast<size_t>(v) * image.width_px + u);
  return {p[0], p[1], p[2]};
}

// a few cones around the start: one straight ahead of the left camera 8 m away, one to the
// left, a big orange one and a blue one to the right
tracks::Track test_track(const StereoCameraConfig& config) {
  tracks::Track t;
  t.name = "camera_test";
  const double ahead_y = config.mount_y_m + 0.5 * config.baseline_m;
  t.cones = {{kBlueAhead, ConeClass::kBlue, {config.mount_x_m + 8.0, ahead_y}, std::nullopt},
             {kYellowLeft, ConeClass::kYellow, {10.0, 2.5}, std::nullopt},
             {kBigOrangeRight, ConeClass::kOrangeBig, {12.0, -2.0}, std::nullopt},
             {kBlueRight, ConeClass::kBlue, {6.0, -1.5}, std::nullopt}};
  return t;
}

// a car at rest at the track origin, its stereo camera, and one rendered frame
struct Rig {
  explicit Rig(const StereoCameraConfig& c = {}, std::set<int> knocked = {},
               std::vector<tracks::SceneryObject> objects = {})
      : config(c),
        track(test_track(c)),
        scenery(std::move(objects)),
        car(vehicle_models::VehicleParams{}, {}),
        camera(c, car.model(), track, scenery) {
    render(std::move(knocked));
  }
  void render(std::set<int> knocked) {
    camera.render(
        car.data(), car.vehicle_pose3(), 1234, [&](int id) { return knocked.count(id) > 0; }, true,
        frame, labels);
  }

  // pixel of a point in the track frame in the left or right image, nullopt behind the camera
  std::optional<Vector2d> project(const Vector3d& p, bool left) const {
    const core::Pose3& eye = left ? labels.left_in_track : labels.right_in_track;
    const Vector3d q = eye.inverse().transform(p);
    if (q.z() <= 0.0) return std::nullopt;
    const core::CameraIntrinsics& k = frame.intrinsics;
    return Vector2d(k.fx * q.x() / q.z() + k.cx, k.fy * q.y() / q.z() + k.cy);
  }

  // point on a cone's axis at mid-height of its lowest band
  Vector3d lower_band_centre(int id) const {
    const tracks::Cone& cone = track.cone(id);
    const core::ConeBand& band = core::cone_geometry(cone.cls).bands[0];
    return {cone.position.x(), cone.position.y(), 0.5 * (band.z_bottom_m + band.z_top_m)};
  }

  StereoCameraConfig config;
  tracks::Track track;
  std::vector<tracks::SceneryObject> scenery;
  sim::VehicleSim car;
  StereoCamera camera;
  core::StereoFrame frame;
  core::StereoLabels labels;
};

// mean column of the pixels of a colour inside a box around a cone's image, and their count
std::pair<double, int> colour_centroid(const core::RgbImage& image, const Vector2d& centre,
                                       int half_box_px, bool (*colour)(Rgb)) {
  double sum = 0.0;
  int count = 0;
  for (int v = std::max(0, int(centre.y()) - half_box_px);
       v < std::min(image.height_px, int(centre.y()) + half_box_px); ++v)
    for (int u = std::max(0, int(centre.x()) - half_box_px);
         u < std::min(image.width_px, int(centre.x()) + half_box_px); ++u)
      if (colour(pixel(image, u, v))) {
        sum += u;
        ++count;
      }
  return {count ? sum / count : 0.0, count};
}

TEST(StereoCamera, PublishesExactCalibrationWithEachFrame) {
  const Rig rig;
  const StereoCameraConfig& c = rig.config;
  const core::CameraIntrinsics& k = rig.frame.intrinsics;

  // pinhole from the field of view, principal point in the centre
  const double f =
      0.5 * c.width_px / std::tan(0.5 * c.horizontal_fov_deg * std::numbers::pi / 180.0);
  EXPECT_EQ(k.width_px, c.width_px);
  EXPECT_EQ(k.height_px, c.height_px);
  EXPECT_NEAR(k.fx, f, 1e-3);
  EXPECT_NEAR(k.fy, f, 1e-3);
  EXPECT_DOUBLE_EQ(k.cx, 0.5 * c.width_px - 0.5);
  EXPECT_DOUBLE_EQ(k.cy, 0.5 * c.height_px - 0.5);

  // extrinsics: left camera to the left, baseline apart, looking forward and down
  EXPECT_EQ(rig.frame.stamp, 1234);
  EXPECT_NEAR(rig.frame.baseline_m, c.baseline_m, 1e-12);
  const Vector3d lr = rig.frame.left_in_vehicle.position - rig.frame.right_in_vehicle.position;
  EXPECT_NEAR(lr.y(), c.baseline_m, 1e-12);
  EXPECT_NEAR(lr.x(), 0.0, 1e-12);
  const Vector3d axis = rig.frame.left_in_vehicle.orientation * Vector3d::UnitZ();
  EXPECT_NEAR(std::asin(-axis.z()), c.pitch_down_deg * std::numbers::pi / 180.0, 1e-9);
  EXPECT_NEAR(axis.y(), 0.0, 1e-12);
  const Vector3d right = rig.frame.left_in_vehicle.orientation * Vector3d::UnitX();
  EXPECT_NEAR(right.y(), -1.0, 1e-12);

  // labels: the same poses in the track frame
  const core::Pose3 expected = rig.car.vehicle_pose3().compose(rig.frame.left_in_vehicle);
  EXPECT_LT((rig.labels.left_in_track.position - expected.position).norm(), 1e-12);
  EXPECT_TRUE(rig.frame.left_depth_m.size() == size_t(c.width_px) * c.height_px);
}

TEST(StereoCamera, ConeProjectsThroughTheIntrinsicsToItsColour) {
  const Rig rig;
  const struct {
    int id;
    bool (*colour)(Rgb);
  } cases[] = {{kBlueAhead, is_blue},
               {kYellowLeft, is_yellow},
               {kBigOrangeRight, is_orange},
               {kBlueRight, is_blue}};
  for (const auto& c : cases) {
    for (const bool left : {true, false}) {
      const auto uv = rig.project(rig.lower_band_centre(c.id), left);
      ASSERT_TRUE(uv.has_value());
      const int u = static_cast<int>(std::lround(uv->x())),
                v = static_cast<int>(std::lround(uv->y()));
      ASSERT_TRUE(u >= 0 && u < rig.config.width_px && v >= 0 && v < rig.config.height_px);
      const Rgb p = pixel(left ? rig.frame.left : rig.frame.right, u, v);
      EXPECT_TRUE(c.colour(p)) << "cone " << c.id << (left ? " left" : " right") << " at " << u
                               << "," << v << ": " << p.r << " " << p.g << " " << p.b;
    }
  }
}

TEST(StereoCamera, DisparityIsBaselineTimesFocalOverDepth) {
  const Rig rig;
  const Vector3d centre = rig.lower_band_centre(kBlueAhead);
  const auto left = rig.project(centre, true);
  const auto right = rig.project(centre, false);
  ASSERT_TRUE(left && right);

  // the cone's column in each image: centroid of its blue pixels (the cone is ~20 px wide)
  const auto [u_left, n_left] = colour_centroid(rig.frame.left, *left, 30, is_blue);
  const auto [u_right, n_right] = colour_centroid(rig.frame.right, *right, 30, is_blue);
  ASSERT_GT(n_left, 50);
  ASSERT_GT(n_right, 50);

  // depth of the cone's axis along the optical axis
  const double z = rig.labels.left_in_track.inverse().transform(centre).z();
  const double expected = rig.frame.baseline_m * rig.frame.intrinsics.fx / z;
  // a silhouette's centroid is quantised to whole pixels over ~20 columns: well under 0.5 px
  std::printf("measured: disparity %.3f px, B f / Z %.3f px\n", u_left - u_right, expected);
  EXPECT_NEAR(u_left - u_right, expected, 0.5);
}

TEST(StereoCamera, DepthIsTheDistanceToTheSurfaceAlongTheOpticalAxis) {
  const Rig rig;
  const core::Pose3 camera_from_track = rig.labels.left_in_track.inverse();
  const core::CameraIntrinsics& k = rig.frame.intrinsics;
  const auto depth_at = [&](const Vector2d& uv) {
    return rig.frame.left_depth_m[std::lround(uv.y()) * k.width_px + std::lround(uv.x())];
  };

  // the front of the cone straight ahead, at mid-height of its lower band
  const tracks::Cone& cone = rig.track.cone(kBlueAhead);
  const core::ConeBand& band = core::cone_geometry(cone.cls).bands[0];
  const Vector3d eye = rig.labels.left_in_track.position;
  const Vector2d towards_eye = (Vector2d(eye.x(), eye.y()) - cone.position).normalized();
  const double radius = 0.5 * (band.radius_bottom_m + band.radius_top_m);
  const Vector2d front = cone.position + radius * towards_eye;
  const Vector3d surface(front.x(), front.y(), 0.5 * (band.z_bottom_m + band.z_top_m));
  const auto uv = rig.project(surface, true);
  ASSERT_TRUE(uv.has_value());
  // errors: half a pixel of rounding on the slanted side (2 mm), facets (< 2 mm), buffer (< 1 mm)
  const double cone_z = camera_from_track.transform(surface).z();
  std::printf("measured: cone depth %.4f m, true %.4f m\n", depth_at(*uv), cone_z);
  EXPECT_NEAR(depth_at(*uv), cone_z, 0.01);

  // the ground below the horizon: where the pixel's ray meets the plane z = 0
  for (const double row : {0.7, 0.85}) {
    const Vector2d ground_uv(k.cx + 40.0, row * k.height_px);
    const Vector3d ray =
        rig.labels.left_in_track.orientation *
        Vector3d((ground_uv.x() - k.cx) / k.fx, (ground_uv.y() - k.cy) / k.fy, 1.0);
    const double z = -eye.z() / ray.z();  // the ray's optical z is 1, so its length is the depth
    std::printf("measured: ground depth %.4f m, true %.4f m\n", depth_at(ground_uv), z);
    EXPECT_NEAR(depth_at(ground_uv), z, 0.01);
  }

  // the sky has no depth
  EXPECT_TRUE(std::isinf(rig.frame.left_depth_m[k.width_px / 2]));
}

TEST(StereoCamera, KnockedConesAreNotDrawn) {
  Rig rig({}, {kBlueRight});
  const auto uv = rig.project(rig.lower_band_centre(kBlueRight), true);
  ASSERT_TRUE(uv.has_value());
  EXPECT_EQ(colour_centroid(rig.frame.left, *uv, 40, is_blue).second, 0);
  EXPECT_TRUE(is_grey(pixel(rig.frame.left, std::lround(uv->x()), std::lround(uv->y()))));

  // standing again, it is drawn
  rig.render({});
  EXPECT_GT(colour_centroid(rig.frame.left, *uv, 40, is_blue).second, 50);
}

// A scenery object (issue 17) is drawn in both images where it stands, and only there: the red
// half of a road barrier 15 m ahead, to the left of the cones
TEST(StereoCamera, SceneryIsDrawnWhereItStands) {
  const core::Pose2 pose{15.0, 4.5, 0.0};
  const tracks::SceneryObject barrier =
      tracks::make_scenery_object(core::ClutterClass::kBarrier, pose);
  const tracks::ScenePrimitive& red = barrier.parts.front();
  const Vector3d centre(pose.x + red.centre.x(), pose.y + red.centre.y(), red.centre.z());
  const auto is_red = [](Rgb c) { return c.r > c.g + 50 && c.r > c.b + 50; };
  const Rig with({}, {}, {barrier}), without;
  for (const bool left : {true, false}) {
    const auto uv = with.project(centre, left);
    ASSERT_TRUE(uv.has_value());
    const int u = static_cast<int>(std::lround(uv->x())),
              v = static_cast<int>(std::lround(uv->y()));
    ASSERT_TRUE(u >= 0 && u < with.config.width_px && v >= 0 && v < with.config.height_px);
    const Rgb p = pixel(left ? with.frame.left : with.frame.right, u, v);
    EXPECT_TRUE(is_red(p)) << u << "," << v << ": " << p.r << " " << p.g << " " << p.b;
    EXPECT_FALSE(is_red(pixel(left ? without.frame.left : without.frame.right, u, v)));
  }
}

TEST(StereoCamera, GroundLooksLikeAsphaltAndTheSkyIsAbove) {
  const Rig rig;
  const core::RgbImage& image = rig.frame.left;
  int grey = 0, sky = 0, samples = 0;
  for (int u = 10; u < image.width_px; u += 60, ++samples) {
    grey += is_grey(pixel(image, u, image.height_px * 3 / 4));
    sky += is_sky(pixel(image, u, 10));
  }
  EXPECT_EQ(grey, samples);
  EXPECT_EQ(sky, samples);
}

// The segmentation render names the object of every pixel, in register with the image: each
// cone's band centre carries its id, the barrier's red half its scenery code, the ground and
// the sky theirs; every blue pixel of the image below the sky belongs to a blue cone and most of a
// blue cone's pixels are blue or its white stripe; the frame drawn next is unchanged by it
TEST(StereoCamera, SegmentationNamesTheObjectOfEveryPixel) {
  const core::Pose2 pose{15.0, 4.5, 0.0};
  const tracks::SceneryObject barrier =
      tracks::make_scenery_object(core::ClutterClass::kBarrier, pose);
  Rig rig({}, {}, {barrier});
  const core::StereoFrame before = rig.frame;
  SegmentationImage seg;
  rig.camera.render_segmentation(seg);
  ASSERT_EQ(seg.width_px, rig.config.width_px);
  ASSERT_EQ(seg.object.size(), static_cast<size_t>(seg.width_px) * seg.height_px);

  for (const int id : {kBlueAhead, kYellowLeft, kBigOrangeRight, kBlueRight}) {
    const auto uv = rig.project(rig.lower_band_centre(id), true);
    ASSERT_TRUE(uv.has_value());
    EXPECT_EQ(seg.at(std::lround(uv->x()), std::lround(uv->y())), id) << "cone " << id;
  }
  const tracks::ScenePrimitive& red = barrier.parts.front();
  const auto barrier_uv =
      rig.project(Vector3d(pose.x + red.centre.x(), pose.y + red.centre.y(), red.centre.z()), true);
  ASSERT_TRUE(barrier_uv.has_value());
  EXPECT_EQ(seg.at(std::lround(barrier_uv->x()), std::lround(barrier_uv->y())),
            SegmentationImage::kSceneryBase);
  EXPECT_EQ(seg.at(20, seg.height_px * 3 / 4), SegmentationImage::kGround);
  EXPECT_EQ(seg.at(20, 5), SegmentationImage::kNothing);

  int blue = 0, blue_in_blue_cone = 0;
  std::map<int, std::pair<int, int>> cone_pixels;  // id: (pixels, blue or white ones)
  for (int v = 0; v < seg.height_px; ++v)
    for (int u = 0; u < seg.width_px; ++u) {
      const Rgb c = pixel(rig.frame.left, u, v);
      const int id = seg.at(u, v);
      if (is_blue(c) && id != SegmentationImage::kNothing) {  // (the painted sky is blue too)
        ++blue;
        blue_in_blue_cone += id == kBlueAhead || id == kBlueRight;
      }
      if (id == kBlueAhead || id == kBlueRight) {
        auto& [n, coloured] = cone_pixels[id];
        ++n;
        coloured += is_blue(c) || (c.r > 150 && c.g > 150 && c.b > 150);
      }
    }
  ASSERT_GT(blue, 200);
  EXPECT_EQ(blue_in_blue_cone, blue);
  for (const auto& [id, counts] : cone_pixels) {
    EXPECT_GT(counts.first, 50) << "cone " << id;
    // the silhouette's edge pixels blend with the ground: a ring one pixel wide
    EXPECT_GE(counts.second, 0.8 * counts.first) << "cone " << id;
  }

  // the next frame is drawn as before (flags and segmentation ids restored)
  rig.render({});
  EXPECT_EQ(rig.frame.left.rgb, before.left.rgb);
  EXPECT_EQ(rig.frame.right.rgb, before.right.rgb);
}

// A lens in OpenCV's model (the scenario default with sensors.realism on): the camera draws each
// pixel through it, and cv::undistortPoints with the intrinsics the frame carries takes the
// image back to the pinhole camera. Cones all over the view, near the corners too: each cone's
// centroid in the lens's segmentation, undistorted, lands within 0.5 px of its centroid in the
// pinhole camera's segmentation of the same view; and the lens really moves them (by pixels).
// (What is left is the segmentation's own rounding: each image pixel shows the object at the
// nearest pixel centre of the pinhole canvas, up to half a pixel from its ray.)
TEST(StereoCamera, OpenCvUndoesTheLensWithThePublishedIntrinsics) {
  StereoCameraConfig pinhole;
  StereoCameraConfig lens = pinhole;
  lens.distortion = kTypicalLensDistortion;
  tracks::Track track;
  track.name = "lens_test";
  const double tan_half = std::tan(0.5 * pinhole.horizontal_fov_deg * std::numbers::pi / 180.0);
  int id = 0;
  for (const double x : {3.0, 4.5, 6.5, 9.0, 13.0})
    for (const double side : {-0.85, -0.55, -0.25, 0.0, 0.3, 0.6, 0.88})
      track.cones.push_back({id++,
                             id % 2 ? ConeClass::kBlue : ConeClass::kYellow,
                             {pinhole.mount_x_m + x, side * x * tan_half},
                             std::nullopt});
  sim::VehicleSim car(vehicle_models::VehicleParams{}, {});
  StereoCamera straight(pinhole, car.model(), track);
  StereoCamera curved(lens, car.model(), track);
  core::StereoFrame frame_straight, frame_curved;
  core::StereoLabels labels;
  SegmentationImage seg_straight, seg_curved;
  straight.render(car.data(), car.vehicle_pose3(), 0, {}, false, frame_straight, labels);
  straight.render_segmentation(seg_straight);
  curved.render(car.data(), car.vehicle_pose3(), 0, {}, false, frame_curved, labels);
  curved.render_segmentation(seg_curved);
  ASSERT_EQ(seg_curved.width_px, lens.width_px);
  ASSERT_EQ(frame_curved.left.width_px, lens.width_px);
  const core::CameraIntrinsics& k = frame_curved.intrinsics;
  ASSERT_EQ(k.distortion, kTypicalLensDistortion);

  // each cone's centroid, its pixel count, and whether it touches the border
  struct Blob {
    double u = 0, v = 0;
    int n = 0;
    bool edge = false;
  };
  auto blobs = [](const SegmentationImage& seg) {
    std::map<int, Blob> out;
    for (int v = 0; v < seg.height_px; ++v)
      for (int u = 0; u < seg.width_px; ++u)
        if (const int id = seg.at(u, v); id >= 0) {
          Blob& b = out[id];
          b.u += u, b.v += v, ++b.n;
          b.edge = b.edge || u == 0 || v == 0 || u == seg.width_px - 1 || v == seg.height_px - 1;
        }
    for (auto& [id, b] : out) b.u /= b.n, b.v /= b.n;
    return out;
  };
  const std::map<int, Blob> a = blobs(seg_straight), b = blobs(seg_curved);
  std::vector<cv::Point2d> seen;
  std::vector<Blob> expected;
  for (const auto& [cone, blob] : b)
    if (const auto it = a.find(cone);
        it != a.end() && !blob.edge && !it->second.edge && blob.n >= 60 && it->second.n >= 60) {
      seen.emplace_back(blob.u, blob.v);
      expected.push_back(it->second);
    }
  ASSERT_GE(seen.size(), 15u);
  const cv::Matx33d camera(k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0);
  const std::vector<double> coefficients(k.distortion.begin(), k.distortion.end());
  std::vector<cv::Point2d> undone;
  cv::undistortPoints(seen, undone, camera, coefficients, cv::noArray(), camera);
  double worst = 0.0, moved = 0.0;
  for (size_t i = 0; i < seen.size(); ++i) {
    worst = std::max(worst, std::hypot(undone[i].x - expected[i].u, undone[i].y - expected[i].v));
    moved = std::max(moved, std::hypot(seen[i].x - expected[i].u, seen[i].y - expected[i].v));
  }
  std::vector<double> errors;
  for (size_t i = 0; i < seen.size(); ++i)
    errors.push_back(std::hypot(undone[i].x - expected[i].u, undone[i].y - expected[i].v));
  std::sort(errors.begin(), errors.end());
  std::printf(
      "[lens] %zu cones: the lens moved them up to %.1f px; undone to within %.3f px "
      "(median %.3f px)\n",
      seen.size(), moved, worst, errors[errors.size() / 2]);
  EXPECT_LE(worst, 0.5);
  EXPECT_GE(moved, 5.0);
  // the image is drawn through the same lens as the segmentation: its blue pixels (but the
  // sky's) are on the blue cones' silhouettes, but for the edges that blend with the ground
  int blue = 0, on_blue_cone = 0;
  for (int v = 0; v < seg_curved.height_px; ++v)
    for (int u = 0; u < seg_curved.width_px; ++u) {
      const int id = seg_curved.at(u, v);
      if (id == SegmentationImage::kNothing || !is_blue(pixel(frame_curved.left, u, v))) continue;
      ++blue;
      on_blue_cone += id >= 0 && track.cone(id).cls == ConeClass::kBlue;
    }
  ASSERT_GT(blue, 500);
  EXPECT_GE(on_blue_cone, 0.98 * blue);
}

TEST(StereoCamera, WritesViewablePngs) {
  const Rig rig;
  const std::string dir = ::testing::TempDir();
  EXPECT_EQ(write_png(dir + "conesim_stereo_left.png", rig.frame.left), "");
  EXPECT_EQ(write_png(dir + "conesim_stereo_right.png", rig.frame.right), "");
  const core::RgbImage depth = depth_to_image(rig.frame.left_depth_m, rig.frame.intrinsics.width_px,
                                              rig.frame.intrinsics.height_px, 30.0);
  EXPECT_EQ(write_png(dir + "conesim_stereo_depth.png", depth), "");

  // the encoding round-trips: signature, then the scanlines inside the IDAT chunk
  const std::vector<uint8_t> png = encode_png(rig.frame.left);
  ASSERT_GT(png.size(), 57u);
  EXPECT_EQ(png[1], 'P');
  const size_t idat_length = (png[33] << 24) | (png[34] << 16) | (png[35] << 8) | png[36];
  const size_t w = rig.frame.left.width_px, h = rig.frame.left.height_px;
  std::vector<uint8_t> raw((3 * w + 1) * h);
  uLongf raw_size = raw.size();
  ASSERT_EQ(uncompress(raw.data(), &raw_size, png.data() + 41, idat_length), Z_OK);
  ASSERT_EQ(raw_size, raw.size());
  EXPECT_EQ(raw[0], 0);
  EXPECT_EQ(raw[(3 * w + 1) * 100 + 1 + 3 * 200], rig.frame.left.rgb[3 * (w * 100 + 200)]);
}

// The sensor's noise (issue 17) is on both images, of the size its response gives at each
// pixel's level, and changes nothing the renderer decides: the noiseless image is the same
// scene, pixel for pixel within the noise.
TEST(StereoCamera, TheSensorsNoiseIsOnBothImages) {
  StereoCameraConfig quiet;
  quiet.response.full_well_e = 0.0;
  const Rig noisy, clean(quiet);
  for (const bool left : {true, false}) {
    const core::RgbImage& a = left ? noisy.frame.left : noisy.frame.right;
    const core::RgbImage& b = left ? clean.frame.left : clean.frame.right;
    ASSERT_EQ(a.rgb.size(), b.rgb.size());
    // the noise in units of its own sigma at the clean level, away from the clipped ends
    double squares = 0.0;
    int n = 0, far_off = 0;
    for (size_t i = 0; i < a.rgb.size(); ++i) {
      if (b.rgb[i] < 8 || b.rgb[i] > 247) continue;
      const double sigma =
          std::sqrt(std::pow(quiet.response.noise_sigma(b.rgb[i]), 2) +
                    std::pow(StereoCameraConfig{}.response.noise_sigma(b.rgb[i]), 2) + 1.0 / 12.0);
      const double z = (static_cast<double>(a.rgb[i]) - b.rgb[i]) / sigma;
      squares += z * z;
      far_off += std::abs(z) > 6.0;
      ++n;
    }
    ASSERT_GT(n, 100000);
    EXPECT_NEAR(std::sqrt(squares / n), 1.0, 0.1) << (left ? "left" : "right");
    EXPECT_LT(far_off, n / 100000 + 1) << (left ? "left" : "right");
  }
}

// The light on the scene is a key (world.randomise draws it): a dimmer light gives a darker
// ground, and the defaults are the model's own headlight.
TEST(StereoCamera, TheLightIsAKey) {
  StereoCameraConfig quiet;
  quiet.response.full_well_e = 0.0;
  StereoCameraConfig dim = quiet, model_light = quiet;
  dim.light_ambient = 0.25;
  dim.light_diffuse = 0.3;
  model_light.light_ambient = 0.45;
  model_light.light_diffuse = 0.55;
  const Rig normal(quiet), darker(dim), same(model_light);
  // the lower half of the image: mostly ground
  auto mean_lower = [](const core::RgbImage& image) {
    double sum = 0.0;
    const size_t from = image.rgb.size() / 2;
    for (size_t i = from; i < image.rgb.size(); ++i) sum += image.rgb[i];
    return sum / static_cast<double>(image.rgb.size() - from);
  };
  EXPECT_LT(mean_lower(darker.frame.left), 0.8 * mean_lower(normal.frame.left));
  EXPECT_EQ(same.frame.left.rgb, normal.frame.left.rgb);
}

TEST(StereoCamera, ConfigurationErrorsNameTheKey) {
  EXPECT_EQ(StereoCameraConfig{}.validate(), "");
  const auto error = [](auto mutate) {
    StereoCameraConfig c;
    mutate(c);
    return c.validate();
  };
  EXPECT_EQ(error([](auto& c) { c.width_px = 0; }).rfind("width_px", 0), 0u);
  EXPECT_EQ(error([](auto& c) { c.horizontal_fov_deg = 200; }).rfind("horizontal_fov_deg", 0), 0u);
  EXPECT_EQ(error([](auto& c) { c.baseline_m = -0.1; }).rfind("baseline_m", 0), 0u);
  EXPECT_EQ(error([](auto& c) { c.far_m = 0.5; }).rfind("far_m", 0), 0u);
  // a lens whose radial terms fold the image over before its corner, or a NaN term
  EXPECT_EQ(error([](auto& c) {
              c.distortion = {-0.9, 0.0, 0.0, 0.0, 0.0};
            }).rfind("distortion", 0),
            0u);
  EXPECT_EQ(error([](auto& c) { c.distortion[1] = std::nan(""); }).rfind("distortion: k2", 0), 0u);
  EXPECT_EQ(error([](auto& c) { c.distortion = kTypicalLensDistortion; }), "");

  // larger than the model's offscreen buffer
  StereoCameraConfig huge;
  huge.width_px = 4000;
  const tracks::Track track = test_track(huge);
  const sim::VehicleSim car(vehicle_models::VehicleParams{}, {});
  EXPECT_THROW(StereoCamera(huge, car.model(), track), std::invalid_argument);
}

namespace texture_and_sun {

// the left image of a camera on a car at rest at (x, 0) heading along x, on a track without
// cones, the sensor's noise off
core::RgbImage left_image(const StereoCameraConfig& config, double x,
                          const std::vector<tracks::SceneryObject>& scenery = {},
                          const tracks::Track& track = tracks::Track{}) {
  const sim::VehicleSim car(vehicle_models::VehicleParams{}, {x, 0.0, 0.0});
  StereoCamera camera(config, car.model(), track, scenery);
  core::StereoFrame frame;
  core::StereoLabels labels;
  camera.render(car.data(), car.vehicle_pose3(), 0, {}, false, frame, labels);
  return frame.left;
}

// mean absolute difference of two images over rows [from, to)
double mean_difference(const core::RgbImage& a, const core::RgbImage& b, int from, int to) {
  double sum = 0.0;
  const size_t begin = 3 * static_cast<size_t>(from) * a.width_px;
  const size_t end = 3 * static_cast<size_t>(to) * a.width_px;
  for (size_t i = begin; i < end; ++i) sum += std::abs(int(a.rgb[i]) - int(b.rgb[i]));
  return sum / static_cast<double>(end - begin);
}

// the grain of an image over rows [from, to): the mean absolute difference of levels 8 pixels
// apart along a row (a few centimetres on the ground there; a smooth shading has none)
double grain_of(const core::RgbImage& image, int from, int to) {
  constexpr size_t kApart = 3 * 8;
  double sum = 0.0;
  const size_t begin = 3 * static_cast<size_t>(from) * image.width_px;
  const size_t end = 3 * static_cast<size_t>(to) * image.width_px;
  for (size_t i = begin; i + kApart < end; ++i)
    sum += std::abs(int(image.rgb[i + kApart]) - int(image.rgb[i]));
  return sum / static_cast<double>(end - begin);
}

}  // namespace texture_and_sun

// The asphalt's texture (issue 17): its mean is the flat ground's colour; the image of the
// ground has a grain the flat ground has not; the grain is fixed to the ground: a car one
// texture period (512 texels of 8 mm) further on sees the same ground, half a period further
// on it does not.
TEST(StereoCamera, TheAsphaltHasAGrainFixedToTheGround) {
  using namespace texture_and_sun;
  const std::vector<uint8_t> texels = asphalt_texture(512, 7);
  double mean[3] = {0.0, 0.0, 0.0};
  for (size_t i = 0; i < texels.size(); ++i) mean[i % 3] += texels[i];
  const double flat_colour[3] = {0.30 * 255, 0.30 * 255, 0.32 * 255};
  for (int c = 0; c < 3; ++c)
    EXPECT_NEAR(mean[c] / static_cast<double>(texels.size() / 3), flat_colour[c],
                0.03 * flat_colour[c]);
  EXPECT_EQ(texels, asphalt_texture(512, 7));
  EXPECT_NE(texels, asphalt_texture(512, 8));

  StereoCameraConfig plain;
  plain.response.full_well_e = 0.0;
  StereoCameraConfig grained = plain;
  grained.ground_texture = true;
  // the ground 3 to 6 m ahead, above the car's nose
  const int from = 330, to = 420;
  const core::RgbImage flat_ground = left_image(plain, 0.0), at = left_image(grained, 0.0),
                       period = left_image(grained, 512 * 0.008),
                       half = left_image(grained, 256 * 0.008);
  const double flat = grain_of(flat_ground, from, to), grain = grain_of(at, from, to);
  const double same = mean_difference(at, period, from, to);
  const double moved = mean_difference(at, half, from, to);
  EXPECT_LT(flat, 0.3);
  EXPECT_GT(grain, 1.5) << flat;
  EXPECT_LT(same, 0.5) << "the grain moved with the car";
  EXPECT_GT(moved, 5.0 * std::max(same, 0.2)) << same;
}

// The sun (issue 17): a cone's shadow falls on the ground away from the sun, as dark as the
// sun's share of the light there; the ground on the sun's side of the cone is as bright as
// anywhere; no sun, no shadow.
TEST(StereoCamera, TheSunCastsAConesShadowOnTheGround) {
  using namespace texture_and_sun;
  StereoCameraConfig config;
  config.response.full_well_e = 0.0;
  config.sun_diffuse = 0.5;
  config.sun_elevation_deg = 30.0;
  config.sun_azimuth_deg = 90.0;  // from the left: shadows fall to the right (-y)
  tracks::Track track;
  track.cones = {{1, ConeClass::kOrangeBig, {8.0, 0.0}, std::nullopt}};
  const sim::VehicleSim car(vehicle_models::VehicleParams{}, {0.0, 0.0, 0.0});
  StereoCamera camera(config, car.model(), track);
  core::StereoFrame frame;
  core::StereoLabels labels;
  camera.render(car.data(), car.vehicle_pose3(), 0, {}, false, frame, labels);
  const auto pixel_of = [&](const Vector3d& p) {
    const Vector3d q = labels.left_in_track.inverse().transform(p);
    const core::CameraIntrinsics& k = frame.intrinsics;
    Vector2d uv(k.fx * q.x() / q.z() + k.cx, k.fy * q.y() / q.z() + k.cy);
    // (through the default lens: none here)
    return uv;
  };
  const auto grey = [&](const core::RgbImage& image, const Vector3d& p) {
    const Vector2d uv = pixel_of(p);
    const Rgb c =
        pixel(image, static_cast<int>(std::lround(uv.x())), static_cast<int>(std::lround(uv.y())));
    return (c.r + c.g + c.b) / 3.0;
  };
  // the big cone is 0.505 m tall: its shadow reaches 0.87 m to its right; half of it lies
  // 0.45 m to the right, the sun's side 0.45 m to the left
  const Vector3d shaded(8.0, -0.45, 0.0), sunny(8.0, 0.45, 0.0), open(8.0, -1.4, 0.0);
  const double in_shadow = grey(frame.left, shaded), beside = grey(frame.left, sunny),
               away = grey(frame.left, open);
  // the light on level ground: ambient, the headlight along the optical axis (its cosine on
  // the ground is the axis's dip) and the sun; the shadow takes the sun's
  const Vector3d forward = labels.left_in_track.orientation * Vector3d::UnitZ();
  const double sun = 0.5 * std::sin(30.0 * std::numbers::pi / 180.0);
  const double lit = config.light_ambient +
                     (config.light_diffuse - config.sun_diffuse) * std::max(0.0, -forward.z()) +
                     sun;
  EXPECT_NEAR(beside, away, 0.03 * away);
  EXPECT_NEAR(in_shadow / away, 1.0 - sun / lit, 0.05) << in_shadow << " " << away;

  // a second cone 0.5 m to the sun's side: its shadow covers the first one's half way out, and
  // the ground there is no darker for lying in two shadows (the sun is blocked or it is not)
  const Vector3d both(8.0, -0.3, 0.0);
  const double in_one = grey(frame.left, both);
  track.cones.push_back({2, ConeClass::kOrangeBig, {8.0, 0.5}, std::nullopt});
  StereoCamera pair(config, car.model(), track);
  pair.render(car.data(), car.vehicle_pose3(), 0, {}, false, frame, labels);
  EXPECT_NEAR(in_one / away, 1.0 - sun / lit, 0.05) << in_one << " " << away;
  EXPECT_NEAR(grey(frame.left, both), in_one, 2.0);

  // no sun: no shadow
  config.sun_diffuse = 0.0;
  StereoCamera unlit(config, car.model(), track);
  unlit.render(car.data(), car.vehicle_pose3(), 0, {}, false, frame, labels);
  EXPECT_NEAR(grey(frame.left, shaded), grey(frame.left, open), 2.0);
}

// Motion blur (issue 17): an edge a camera passes sideways is smeared over the distance its image
// moves during the exposure, f v T / Z pixels; a turn smears everything by f w T whatever the
// depth; a still camera leaves the image as it is; the blur keeps each row's mean.
TEST(StereoCamera, MotionBlurSmearsAnEdgeOverItsTrackDuringTheExposure) {
  core::CameraIntrinsics k;
  k.width_px = 200;
  k.height_px = 20;
  k.fx = k.fy = 400.0;
  k.cx = 99.5;
  k.cy = 9.5;
  core::RgbImage edge;
  edge.width_px = k.width_px;
  edge.height_px = k.height_px;
  edge.rgb.assign(3 * 200 * 20, 0);
  for (int r = 0; r < 20; ++r)
    for (int c = 100; c < 200; ++c)
      for (int j = 0; j < 3; ++j) edge.rgb[3 * (r * 200 + c) + j] = 255;
  const std::vector<float> depth(200 * 20, 5.0f);
  std::vector<uint8_t> scratch;
  // the length of the smear in row 10 (the edge's step spread into a ramp: the spread of the
  // ramp's slope, whose standard deviation is length / sqrt(12) for an even smear), and the
  // row's mean
  const auto ramp = [](const core::RgbImage& image) {
    double sum = 0.0, weight = 0.0, first = 0.0, second = 0.0;
    for (int c = 0; c < 200; ++c) {
      const int level = image.rgb[3 * (10 * 200 + c)];
      sum += level;
      if (c + 1 < 200) {
        const double slope = image.rgb[3 * (10 * 200 + c + 1)] - level;
        weight += slope;
        first += slope * (c + 0.5);
        second += slope * (c + 0.5) * (c + 0.5);
      }
    }
    const double mean = first / weight;
    return std::pair<double, double>(std::sqrt(12.0 * (second / weight - mean * mean)),
                                     sum / 200.0);
  };
  const double exposure = 0.004;
  // 10 m/s sideways at 5 m: 400 x 10 x 0.004 / 5 = 3.2 px
  core::RgbImage moving = edge;
  motion_blur(moving, depth, k, {10.0, 0.0, 0.0}, Vector3d::Zero(), exposure, {}, scratch);
  const auto [width, mean] = ramp(moving);
  EXPECT_NEAR(width, 3.2, 0.6);
  EXPECT_NEAR(mean, ramp(edge).second, 1.0);
  // twice as far: half the smear, the same turn rate at any depth
  const std::vector<float> far(200 * 20, 10.0f);
  core::RgbImage farther = edge;
  motion_blur(farther, far, k, {20.0, 0.0, 0.0}, Vector3d::Zero(), exposure, {}, scratch);
  EXPECT_EQ(farther.rgb, moving.rgb);
  // a turn of 2 rad/s about the camera's down axis: 400 x 2 x 0.004 = 3.2 px at the centre
  core::RgbImage turning = edge;
  motion_blur(turning, far, k, Vector3d::Zero(), {0.0, 2.0, 0.0}, exposure, {}, scratch);
  EXPECT_NEAR(ramp(turning).first, 3.2, 0.6);
  // 30 m/s: 9.6 px
  core::RgbImage fast = edge;
  motion_blur(fast, depth, k, {30.0, 0.0, 0.0}, Vector3d::Zero(), exposure, {}, scratch);
  EXPECT_NEAR(ramp(fast).first, 9.6, 0.8);
  // what rides with the camera (the car's nose: a sphere round the points at 5 m) stays sharp
  core::RgbImage riding = edge;
  motion_blur(riding, depth, k, {10.0, 0.0, 0.0}, Vector3d::Zero(), exposure,
              {Eigen::Vector4d(0.0, 0.0, 5.0, 1.0)}, scratch);
  EXPECT_EQ(riding.rgb, edge.rgb);
  // still
  core::RgbImage still = edge;
  motion_blur(still, depth, k, Vector3d::Zero(), Vector3d::Zero(), exposure, {}, scratch);
  EXPECT_EQ(still.rgb, edge.rgb);
}

}  // namespace
}  // namespace conesim::sensors
