#pragma once
// Labelled training data from closed-loop runs (`conesim dataset`, issue 17): camera images with
// YOLO boxes, per-pixel class and instance masks, LiDAR sweeps as PCD with a label per point,
// and a manifest with the poses and intrinsics, N frames from M runs whose world is drawn from
// the seed. docs/dataset.md describes the files.

#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <string>
#include <vector>

#include "core/cone.hpp"
#include "core/measurements.hpp"
#include "sensors/stereo_camera.hpp"
#include "tracks/ground.hpp"
#include "tracks/track.hpp"

namespace conesim::sim {

/// What `conesim dataset` is asked for.
struct DatasetOptions {
  /// Labelled camera frames in all.
  int frames = 1000;
  /// Runs they come from at least: each run gives at most frames / runs of them; more runs
  /// (further seeds) follow while frames are missing.
  int runs = 10;
  /// The dataset's seed: the runs' seeds and their worlds come from it.
  uint64_t seed = 1;
  /// The scenario each run starts from (a shipped name or a file).
  std::string scenario = "autocross";
  /// key.path=value overrides of the scenario, after the randomisation.
  std::vector<std::string> sets;
  /// The folder to write (must not exist, or be empty).
  std::filesystem::path out_dir;
  /// Sim seconds between two frames of a run.
  double every_s = 0.5;
  /// A cone gets a box when at least this fraction of its silhouette is seen (not hidden by
  /// nearer objects, inside the image) ...
  double min_visible = 0.3;
  /// ... and at least this many of its pixels.
  int min_pixels = 16;
  /// Write the LiDAR sweep nearest each frame as PCD.
  bool lidar = true;
  /// Draw each run's clutter and ground from the seed (false: the scenario's world as it is).
  bool randomise = true;
};

/// The YOLO class of a cone class (FSOCO's five: blue_cone 0, yellow_cone 1, orange_cone 2,
/// large_orange_cone 3, unknown_cone 4).
int yolo_class(core::ConeClass c);
/// The YOLO class names in class order.
const std::vector<std::string>& yolo_class_names();

/// Codes of the class mask (one byte per pixel).
struct MaskClass {
  static constexpr uint8_t kNothing = 0;  // the sky
  static constexpr uint8_t kGround = 1;
  static constexpr uint8_t kCar = 2;
  /// A cone: kConeBase + its YOLO class.
  static constexpr uint8_t kConeBase = 10;
  /// A scenery object: kClutterBase + its core::ClutterClass.
  static constexpr uint8_t kClutterBase = 20;
};

/// A cone seen in the left image, judged from its mesh (rasterised through the exact pinhole,
/// standing on the ground) and from the segmentation render.
struct ConeImageLabel {
  int cone_id = -1;
  core::ConeClass cls = core::ConeClass::kUnknown;
  /// From the left camera, metres (in the ground plane).
  double range_m = 0.0;
  /// Pixels the segmentation gives the cone (what is seen).
  int visible_px = 0;
  /// Pixels its rasterised mesh covers inside the image (what would be seen with nothing in
  /// front), and in all (inside and outside the image).
  int silhouette_px = 0;
  int silhouette_total_px = 0;
  /// The box of the rasterised silhouette clipped to the image, pixel edges (0..width).
  double x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  /// The box of the seen pixels, pixel edges.
  double seen_x0 = 0, seen_y0 = 0, seen_x1 = 0, seen_y1 = 0;
  /// 1 - seen / silhouette inside the image; 1 - inside / all.
  double occlusion = 0.0;
  double truncation = 0.0;
  /// Intersection over union of the silhouette with the seen pixels, and of their boxes.
  double mask_iou = 0.0;
  double box_iou = 0.0;
  /// Part of the cone lies behind the camera's near plane: no silhouette, no box.
  bool too_near = false;
  /// It gets a YOLO box (seen enough).
  bool boxed = false;
};

/// The cones of `track` that the segmentation shows, each with its silhouette and boxes;
/// boxed when min_visible and min_pixels are met.
std::vector<ConeImageLabel> label_cones(const tracks::Track& track,
                                        const tracks::GroundModel& ground,
                                        const core::CameraIntrinsics& intrinsics,
                                        const core::Pose3& left_in_track,
                                        const sensors::SegmentationImage& segmentation,
                                        double min_visible, int min_pixels);

/// What a dataset holds.
struct DatasetSummary {
  int frames = 0;
  int runs = 0;
  int boxes = 0;
  int lidar_sweeps = 0;
  /// Boxed cones with nothing in front and wholly inside the image, whose silhouette is checked
  /// against the segmentation, the smallest box IoU among them and how many fell below 0.9.
  int checked_boxes = 0;
  double min_box_iou = 1.0;
  int boxes_below_iou = 0;
  double wall_s = 0.0;
};

/// Refuses options that cannot give a dataset (core::InputError naming the option).
void check_dataset_options(const DatasetOptions& options);

/// Runs the scenario as often as it takes and writes the dataset to options.out_dir, the
/// manifest last (a folder without manifest.json is not a dataset; an interrupted one says so in
/// its INCOMPLETE file). Progress lines go to `log`. Throws core::InputError for bad input.
DatasetSummary write_dataset(const DatasetOptions& options, std::ostream& log);

}  // namespace conesim::sim
