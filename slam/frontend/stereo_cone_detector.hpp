#pragma once
// Cones from a rectified stereo pair: colour segmentation of the left image (HSV), a bounding
// box and class per cone, stereo matching of each box along its epipolar line in the right
// image, and triangulation from the box centre and from the cone tip. OpenCV stays inside the
// .cpp files.
//
//   StereoConeDetector detector(config);
//   StereoDetections d = detector.detect(frame);   // vehicle frame at the frame's stamp

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
  // (the implementation adds its own tuning keys: HSV ranges, box sizes, matching window, noise)

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

  /// The observations alone, as SLAM takes them.
  core::ConeObservations observations() const;
};

/// Detects cones in stereo pairs. detect() is const and may run on any thread.
class StereoConeDetector {
 public:
  /// Throws std::invalid_argument when config.validate() fails.
  explicit StereoConeDetector(const StereoDetectorConfig& config);

  /// Finds the cones of one rectified pair (intrinsics and extrinsics from the frame).
  StereoDetections detect(const core::StereoFrame& frame) const;

  const StereoDetectorConfig& config() const { return config_; }

 private:
  StereoDetectorConfig config_;
};

}  // namespace conesim::slam::frontend
