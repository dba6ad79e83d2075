// The labels of `conesim dataset` (sim/dataset.hpp) against the renderer: a cone's silhouette,
// rasterised from its mesh through the pinhole, covers the pixels MuJoCo's segmentation gives it;
// occlusion and truncation are measured, not guessed.
#include "sim/dataset.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <optional>

#include "core/error.hpp"

#include "sensors/stereo_camera.hpp"
#include "sim/vehicle_sim.hpp"
#include "vehicle_models/vehicle_params.hpp"

namespace conesim::sim {
namespace {

using core::ConeClass;

constexpr int kNear = 0;      // a big orange one 5 m ahead, seen whole
constexpr int kHidden = 1;    // a small one right behind it, 7 m ahead
constexpr int kEdge = 2;      // at the image's left edge
constexpr int kBig = 3;       // a big orange one, 12 m ahead to the right
constexpr int kYellow = 4;    // 8 m ahead to the left

tracks::Track scene_track() {
  tracks::Track t;
  t.name = "dataset_test";
  const sensors::StereoCameraConfig c;
  const double y = c.mount_y_m + 0.5 * c.baseline_m;  // on the left camera's axis
  // the image's left edge 7 m ahead of the camera: tan(35 deg) * 7 m = 4.9 m to the left
  // (from the camera 1.05 m up, the small cone's base at 7 m shows below the big one's apex at
  // 5 m, and its 0.23 m base hides behind the big one's 0.29 m: only its tip shows)
  t.cones = {{kNear, ConeClass::kOrangeBig, {c.mount_x_m + 5.0, y}, std::nullopt},
             {kHidden, ConeClass::kBlue, {c.mount_x_m + 7.0, y}, std::nullopt},
             {kEdge, ConeClass::kYellow, {c.mount_x_m + 7.0, y + 4.9}, std::nullopt},
             {kBig, ConeClass::kOrangeBig, {c.mount_x_m + 12.0, y - 2.5}, std::nullopt},
             {kYellow, ConeClass::kYellow, {c.mount_x_m + 8.0, y + 1.8}, std::nullopt}};
  return t;
}

struct Frame {
  explicit Frame(const tracks::GroundConfig& ground_config = {})
      : track(scene_track()),
        ground(track, ground_config, 7),
        car(vehicle_models::VehicleParams{}, {}, ground),
        camera({}, car.model(), track, {}, ground) {
    camera.render(car.data(), car.vehicle_pose3(), 0, {}, false, frame, poses);
    camera.render_segmentation(segmentation);
    labels = label_cones(track, ground, frame.intrinsics, poses.left_in_track, segmentation, 0.3, 16);
  }
  const ConeImageLabel* label(int id) const {
    for (const auto& l : labels)
      if (l.cone_id == id) return &l;
    return nullptr;
  }
  tracks::Track track;
  tracks::GroundModel ground;
  VehicleSim car;
  sensors::StereoCamera camera;
  core::StereoFrame frame;
  core::StereoLabels poses;
  sensors::SegmentationImage segmentation;
  std::vector<ConeImageLabel> labels;
};

// a cone with nothing in front, wholly in the image: its silhouette is the segmentation's
// cone to within the pixels along its outline, and its box the box of what is seen
void expect_matches_the_render(const ConeImageLabel* c, const char* what) {
  ASSERT_NE(c, nullptr) << what;
  std::printf("measured: %s: %d px seen, %d px silhouette, mask IoU %.3f, box IoU %.3f\n", what,
              c->visible_px, c->silhouette_px, c->mask_iou, c->box_iou);
  EXPECT_TRUE(c->boxed) << what;
  EXPECT_LT(c->occlusion, 0.05) << what;
  EXPECT_EQ(c->truncation, 0.0) << what;
  EXPECT_GE(c->mask_iou, 0.9) << what;
  EXPECT_GE(c->box_iou, 0.9) << what;
}

TEST(Dataset, AnUnhiddenConesBoxMatchesItsSegmentationMask) {
  const Frame f;
  expect_matches_the_render(f.label(kNear), "big orange 5 m ahead");
  expect_matches_the_render(f.label(kBig), "big orange 12 m ahead");
  expect_matches_the_render(f.label(kYellow), "yellow 8 m ahead");
}

TEST(Dataset, OnAGradeTheConesStandOnTheGroundTheCameraDraws) {
  tracks::GroundConfig g;
  g.grade_percent = 4.0;
  g.grade_heading_deg = 0.0;  // rising ahead: the cones stand higher than the car
  const Frame f(g);
  ASSERT_GT(f.ground.height(12.0, 0.0) - f.ground.height(0.0, 0.0), 0.3);
  expect_matches_the_render(f.label(kNear), "big orange 5 m ahead on a 4 % grade");
  expect_matches_the_render(f.label(kBig), "big orange 12 m ahead on a 4 % grade");
}

TEST(Dataset, ACoveredConeIsMeasuredHiddenAndGetsNoBox) {
  const Frame f;
  const ConeImageLabel* hidden = f.label(kHidden);
  ASSERT_NE(hidden, nullptr) << "its tip shows above the big cone";
  std::printf("measured: hidden cone: %d px seen of %d, occlusion %.3f\n", hidden->visible_px,
              hidden->silhouette_px, hidden->occlusion);
  EXPECT_GT(hidden->occlusion, 0.7);
  EXPECT_FALSE(hidden->boxed);
  // what is seen of it is the part of its silhouette not behind the big cone's
  EXPECT_GT(hidden->visible_px, 0);
  EXPECT_LT(hidden->visible_px, hidden->silhouette_px / 3);
  const ConeImageLabel* front = f.label(kNear);
  ASSERT_NE(front, nullptr);
  EXPECT_GT(hidden->x0, front->x0);  // behind it: inside the big cone's columns
  EXPECT_LT(hidden->x1, front->x1);
}

TEST(Dataset, AConeAtTheImageEdgeIsMeasuredTruncated) {
  const Frame f;
  const ConeImageLabel* edge = f.label(kEdge);
  ASSERT_NE(edge, nullptr);
  std::printf("measured: edge cone: truncation %.3f, box %.1f-%.1f\n", edge->truncation, edge->x0,
              edge->x1);
  EXPECT_GT(edge->truncation, 0.1);
  EXPECT_LT(edge->truncation, 0.9);
  EXPECT_EQ(edge->x0, 0.0);
  // inside the image the silhouette still agrees with the render
  EXPECT_GE(edge->mask_iou, 0.9);
  EXPECT_LT(edge->occlusion, 0.05);
}

TEST(Dataset, TheClassesAreFsocos) {
  EXPECT_EQ(yolo_class(ConeClass::kBlue), 0);
  EXPECT_EQ(yolo_class(ConeClass::kYellow), 1);
  EXPECT_EQ(yolo_class(ConeClass::kOrangeSmall), 2);
  EXPECT_EQ(yolo_class(ConeClass::kOrangeBig), 3);
  EXPECT_EQ(yolo_class(ConeClass::kUnknown), 4);
  EXPECT_EQ(yolo_class_names()[3], "large_orange_cone");
}

TEST(Dataset, BadOptionsAreRefusedNamingTheOption) {
  const auto error = [](auto mutate) -> std::string {
    DatasetOptions o;
    o.out_dir = ::testing::TempDir() + "conesim_dataset_options_unused";
    mutate(o);
    try {
      check_dataset_options(o);
    } catch (const core::InputError& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_NE(error([](auto& o) { o.frames = 0; }).find("--frames"), std::string::npos);
  EXPECT_NE(error([](auto& o) { o.runs = 0; }).find("--runs"), std::string::npos);
  EXPECT_NE(error([](auto& o) { o.every_s = 0.0; }).find("--every"), std::string::npos);
  EXPECT_NE(error([](auto& o) { o.min_visible = 1.5; }).find("--min-visible"), std::string::npos);
  EXPECT_NE(error([](auto& o) { o.min_pixels = 0; }).find("--min-pixels"), std::string::npos);
  EXPECT_EQ(error([](auto&) {}), "");
}

}  // namespace
}  // namespace conesim::sim
