#pragma once
// Cones from a rectified stereo pair: colour segmentation of the left image (HSV), a bounding
// box and class per cone, stereo matching of each box along its epipolar line in the right
// image, and triangulation from the box centre and from the cone tip. OpenCV stays inside the
// .cpp files.
//
//   StereoConeDetector detector(config);
//   StereoDetections d = detector.detect(frame);   // vehicle frame at the frame's stamp

#include <memory>
#include <string>
#include <vector>

#include "core/autonomy_types.hpp"
#include "core/measurements.hpp"

namespace conesim::slam::frontend {

/// An axis-aligned box in image pixels (left image).
struct PixelBox {
  int x = 0;
  int y = 0;
  int width = 0;
  int height = 0;
};

/// Parameters of the stereo cone detector.
struct StereoDetectorConfig {
  /// Cones farther than this are not reported, metres.
  double max_range_m = 20.0;
  /// Triangulate from the cone tip (true, the RaceUp thesis' choice) or the box centre.
  bool triangulate_tip = true;

  /// An HSV box in OpenCV's 8-bit convention: hue 0-179, saturation and value 0-255.
  struct HsvRange {
    int h_min = 0;
    int h_max = 179;
    int s_min = 0;
    int s_max = 255;
    int v_min = 0;
    int v_max = 255;
  };
  /// Body colours of the classes (stripes are found by merging the body blobs around them).
  HsvRange blue_hsv{100, 130, 130, 255, 40, 255};
  HsvRange yellow_hsv{18, 38, 130, 255, 90, 255};
  HsvRange orange_hsv{4, 17, 150, 255, 90, 255};
  /// Side of the square closing kernel applied to each colour mask, pixels (0: none).
  int close_kernel_px = 3;
  /// Colour blobs smaller than this are dropped, pixels.
  int min_blob_area_px = 3;
  /// Boxes (after merging) shorter than this are dropped, pixels.
  int min_box_height_px = 6;
  /// Two blobs of one colour stacked vertically are parts of one cone when the gap between them
  /// is at most this fraction of the shorter blob's height (plus one pixel).
  double merge_gap_fraction = 1.2;
  /// Two blobs merge only when the taller is at most this many times the shorter.
  double max_part_height_ratio = 2.5;
  /// Accepted width / height of a box.
  double min_aspect = 0.25;
  double max_aspect = 1.2;
  /// Accepted ratio of a box's height to the height a cone of its class has at the stereo depth.
  double min_height_ratio = 0.7;
  double max_height_ratio = 1.4;
  /// Largest disparity searched, pixels (the nearest cone the matcher can see).
  double max_disparity_px = 64.0;
  /// Matches whose mean squared colour difference per channel (0-1 scale) exceeds this are
  /// rejected.
  double max_match_cost = 0.02;
  /// Boxes closer than this to the left or right image border are dropped (cut cones), pixels.
  int border_px = 2;
  /// Share of the box height, from the top (at least three rows), that is matched on its own
  /// for the tip's disparity and whose colour pixels give the tip's column.
  double tip_fraction = 0.3;
  /// Noise of an image coordinate and of the disparity (one sigma), pixels: covariance model.
  double pixel_sigma_px = 0.5;
  double disparity_sigma_px = 0.1;
  /// Added to both diagonal terms of the covariance (model error), m^2.
  double min_variance_m2 = 0.001;

  /// Empty when valid, else a message naming the key and what was expected.
  std::string validate() const;
};

/// One cone found in a stereo pair.
struct CameraCone {
  /// Position (vehicle frame at the frame's stamp), class, covariance (depth variance grows
  /// with the square of the depth); track_id -1.
  core::ConeObservation observation;
  /// The box in the left image.
  PixelBox box;
  /// Disparity of the match, pixels.
  double disparity_px = 0.0;
  /// Depth along the optical axis, metres.
  double depth_m = 0.0;
};

/// The result of one stereo pair.
struct StereoDetections {
  core::TimeUs stamp = 0;
  std::vector<CameraCone> cones;
  /// Boxes found in the left image that could not be matched in the right one.
  int unmatched_boxes = 0;
  /// Boxes dropped by the shape checks (aspect, image border, height at the stereo depth).
  int rejected_boxes = 0;

  /// The observations alone, as SLAM takes them.
  core::ConeObservations observations() const;
};

/// Detects cones in stereo pairs. detect() is const and may run on any thread.
class StereoConeDetector {
 public:
  /// Throws std::invalid_argument when config.validate() fails.
  explicit StereoConeDetector(const StereoDetectorConfig& config);

  /// Finds the cones of one rectified pair (intrinsics and extrinsics from the frame). When the
  /// intrinsics carry lens distortion, both images are first undistorted to the pinhole camera
  /// of the same fx, fy, cx, cy (cv::initUndistortRectifyMap, computed once per calibration):
  /// the boxes and disparities are then those of the pinhole view.
  StereoDetections detect(const core::StereoFrame& frame) const;

  const StereoDetectorConfig& config() const { return config_; }

 private:
  StereoDetectorConfig config_;
  // the undistortion maps of the last calibration seen, shared by copies, under a lock
  struct Undistortion;
  std::shared_ptr<Undistortion> undistortion_;
};

}  // namespace conesim::slam::frontend
