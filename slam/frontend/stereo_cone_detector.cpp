#include "slam/frontend/stereo_cone_detector.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <opencv2/core.hpp>
#include <mutex>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "core/cone.hpp"

namespace conesim::slam::frontend {
namespace {

using HsvRange = StereoDetectorConfig::HsvRange;

// the body colours the detector segments, in the order of the masks
enum BodyColour { kBlueBody = 0, kYellowBody = 1, kOrangeBody = 2 };
constexpr int kBodyColours = 3;

// one colour blob, or several of one colour merged across the stripes of one cone
struct Blob {
  BodyColour colour = kBlueBody;
  cv::Rect box;
  int parts = 1;
};

// where a box was found in both images: disparity and the pixel it refers to
struct StereoPoint {
  double u = 0.0;
  double v = 0.0;
  double disparity_px = 0.0;
};

std::string check_hsv(const std::string& key, const HsvRange& r) {
  const bool hue_ok = 0 <= r.h_min && r.h_min <= r.h_max && r.h_max <= 179;
  const bool s_ok = 0 <= r.s_min && r.s_min <= r.s_max && r.s_max <= 255;
  const bool v_ok = 0 <= r.v_min && r.v_min <= r.v_max && r.v_max <= 255;
  if (hue_ok && s_ok && v_ok) return "";
  return key + ": expected 0 <= min <= max <= 179 (hue) or 255 (saturation, value)";
}

// whether an HSV pixel (OpenCV's 8-bit convention) lies in a range
bool in_range(int h, int sat, int v, const HsvRange& r) {
  return h >= r.h_min && h <= r.h_max && sat >= r.s_min && sat <= r.s_max && v >= r.v_min &&
         v <= r.v_max;
}

// the pixels of each body colour in an RGB image, in one pass. The hue, saturation and value
// are those of cv::cvtColor(COLOR_RGB2HSV) to within rounding, but computed only for pixels
// saturated enough for some range: the asphalt, the sky and the stripes, most of the image,
// cost a comparison (converting the whole image and three cv::inRange passes took most of
// the detector's time)
std::array<cv::Mat, kBodyColours> colour_masks(const cv::Mat& rgb, const StereoDetectorConfig& c) {
  std::array<cv::Mat, kBodyColours> masks;
  for (cv::Mat& m : masks) m = cv::Mat::zeros(rgb.size(), CV_8U);
  const std::array<const HsvRange*, kBodyColours> ranges = {&c.blue_hsv, &c.yellow_hsv,
                                                            &c.orange_hsv};
  int least_saturation = 255;
  for (const HsvRange* r : ranges) least_saturation = std::min(least_saturation, r->s_min);
  for (int row = 0; row < rgb.rows; ++row) {
    const uint8_t* p = rgb.ptr<uint8_t>(row);
    std::array<uint8_t*, kBodyColours> out;
    for (int k = 0; k < kBodyColours; ++k) out[k] = masks[k].ptr<uint8_t>(row);
    for (int col = 0; col < rgb.cols; ++col, p += 3) {
      const int r = p[0], g = p[1], b = p[2];
      const int v = std::max({r, g, b});
      const int spread = v - std::min({r, g, b});
      // saturation 255 * spread / v below the least asked for: skip without dividing
      if (v == 0 || 255 * spread < least_saturation * v) continue;
      const int sat = (255 * spread + v / 2) / v;
      double hue_deg = v == r   ? 60.0 * (g - b) / spread
                       : v == g ? 120.0 + 60.0 * (b - r) / spread
                                : 240.0 + 60.0 * (r - g) / spread;
      if (hue_deg < 0.0) hue_deg += 360.0;
      const int h = static_cast<int>(std::lround(0.5 * hue_deg)) % 180;
      for (int k = 0; k < kBodyColours; ++k)
        if (in_range(h, sat, v, *ranges[k])) out[k][col] = 255;
    }
  }
  return masks;
}

// an RGB image of the frame as an OpenCV header (no copy)
cv::Mat as_mat(const core::RgbImage& image) {
  return cv::Mat(image.height_px, image.width_px, CV_8UC3, const_cast<uint8_t*>(image.rgb.data()));
}

// the blobs of one colour mask, as boxes
std::vector<Blob> find_blobs(const cv::Mat& mask, BodyColour colour, int min_area_px) {
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
  std::vector<Blob> blobs;
  for (int i = 1; i < n; ++i) {
    if (stats.at<int>(i, cv::CC_STAT_AREA) < min_area_px) continue;
    Blob b;
    b.colour = colour;
    b.box = cv::Rect(stats.at<int>(i, cv::CC_STAT_LEFT), stats.at<int>(i, cv::CC_STAT_TOP),
                     stats.at<int>(i, cv::CC_STAT_WIDTH), stats.at<int>(i, cv::CC_STAT_HEIGHT));
    blobs.push_back(b);
  }
  return blobs;
}

// widest extent of the mask's pixels over rows [row0, row1) within the columns of a box, pixels
int widest_row(const cv::Mat& mask, const cv::Rect& box, int row0, int row1) {
  int widest = 0;
  for (int row = std::max(row0, box.y); row < std::min(row1, box.y + box.height); ++row) {
    const uint8_t* p = mask.ptr<uint8_t>(row);
    int first = -1, last = -1;
    for (int c = box.x; c < box.x + box.width; ++c)
      if (p[c]) {
        if (first < 0) first = c;
        last = c;
      }
    if (first >= 0) widest = std::max(widest, last - first + 1);
  }
  return widest;
}

// merges blobs of one colour that a stripe cut apart. Two parts are one cone when the upper
// sits above the lower one, centred over it, with a gap no taller than a stripe; their heights
// are alike (bands and stripes are of similar height); the cone keeps tapering across the gap
// (the upper part's bottom rows are no wider than the lower part's top rows); and the cone does
// not get more parts than its stripes allow. Among the candidate pairs the one with the
// smallest relative gap merges first. These keep a far cone standing just above the tip of a
// near one apart from it.
std::vector<Blob> merge_stripes(std::vector<Blob> blobs, const cv::Mat& mask, int max_parts,
                                double gap_fraction, double max_height_ratio) {
  for (;;) {
    size_t best_upper = 0, best_lower = 0;
    double best_gap = std::numeric_limits<double>::infinity();
    for (size_t i = 0; i < blobs.size(); ++i) {
      for (size_t j = 0; j < blobs.size(); ++j) {
        if (i == j || blobs[i].parts + blobs[j].parts > max_parts) continue;
        const cv::Rect& upper = blobs[i].box;
        const cv::Rect& lower = blobs[j].box;
        const int upper_bottom = upper.y + upper.height - 1;
        if (upper_bottom >= lower.y) continue;
        const int gap = lower.y - upper_bottom - 1;
        const int shorter = std::min(upper.height, lower.height);
        if (gap > gap_fraction * shorter + 1.0) continue;
        if (std::max(upper.height, lower.height) > max_height_ratio * shorter + 1.0) continue;
        const double upper_centre = upper.x + 0.5 * upper.width;
        if (upper_centre < lower.x - 1.0 || upper_centre > lower.x + lower.width + 1.0) continue;
        if (upper.width > lower.width + 1) continue;
        // the edge rows follow the curved stripe boundary: compare a few rows on each side
        const int rows = std::max(2, shorter / 3);
        if (widest_row(mask, upper, upper_bottom + 1 - rows, upper_bottom + 1) >
            widest_row(mask, lower, lower.y, lower.y + rows) + 1)
          continue;
        const double relative_gap = static_cast<double>(gap) / shorter;
        if (relative_gap < best_gap) {
          best_gap = relative_gap;
          best_upper = i;
          best_lower = j;
        }
      }
    }
    if (!std::isfinite(best_gap)) return blobs;
    blobs[best_lower].box |= blobs[best_upper].box;
    blobs[best_lower].parts += blobs[best_upper].parts;
    blobs.erase(blobs.begin() + static_cast<long>(best_upper));
  }
}

// mean over the rows [row0, row1) of a box of the centroid column of the mask's pixels in each
// row (rows without pixels skipped): the cone's axis near its tip; NaN when no row has pixels
double axis_column(const cv::Mat& mask, const cv::Rect& box, int row0, int row1) {
  double sum = 0.0;
  int rows = 0;
  for (int r = std::max(row0, box.y); r < std::min(row1, box.y + box.height); ++r) {
    const uint8_t* p = mask.ptr<uint8_t>(r);
    double columns = 0.0;
    int count = 0;
    for (int c = box.x; c < box.x + box.width; ++c)
      if (p[c]) columns += c, ++count;
    if (count == 0) continue;
    sum += columns / count;
    ++rows;
  }
  return rows ? sum / rows : std::numeric_limits<double>::quiet_NaN();
}

// vertex of the parabola through three equally spaced samples, as an offset in (-0.5, 0.5)
double parabola_offset(double before, double at, double after) {
  const double curvature = before - 2.0 * at + after;
  if (curvature <= 0.0) return 0.0;
  return std::clamp(0.5 * (before - after) / curvature, -0.5, 0.5);
}

// the result of matching a masked left patch along its rows in the right image
struct RowMatch {
  bool found = false;
  double disparity_px = 0.0;
  // mean squared colour difference per masked channel at the best match, 0-1 scale
  double cost = 0.0;
};

// slides a left-image patch (masked) along the same rows of the right image over disparities
// [d_lo, d_hi] and returns the sub-pixel disparity of the least squared difference; not found
// when the range does not fit in the image or the best match lies on the range's edge. The sum
// runs over the masked pixels only (cv::matchTemplate with a mask goes through Fourier
// transforms, slower than this on patches of a few hundred pixels)
RowMatch match_along_row(const cv::Mat& left, const cv::Mat& right, const cv::Rect& patch,
                         const cv::Mat& mask, double d_lo, double d_hi) {
  RowMatch m;
  const int first =
      std::max(static_cast<int>(std::floor(d_lo)), patch.x + patch.width - right.cols);
  const int last = std::min(static_cast<int>(std::ceil(d_hi)), patch.x);
  if (last - first < 2) return m;

  // the masked pixels, as offsets into a row-major RGB image, and their left-image colours
  std::vector<int> offsets;
  std::vector<uint8_t> colours;
  for (int r = 0; r < patch.height; ++r) {
    const uint8_t* keep = mask.ptr<uint8_t>(r);
    const uint8_t* src = left.ptr<uint8_t>(patch.y + r) + 3 * patch.x;
    for (int c = 0; c < patch.width; ++c)
      if (keep[c]) {
        offsets.push_back(static_cast<int>((patch.y + r) * right.step[0]) + 3 * (patch.x + c));
        colours.insert(colours.end(), src + 3 * c, src + 3 * c + 3);
      }
  }
  if (offsets.empty()) return m;

  // squared difference at each whole disparity
  std::vector<double> cost(static_cast<size_t>(last - first + 1));
  for (int d = first; d <= last; ++d) {
    const uint8_t* base = right.data - 3 * d;
    long sum = 0;
    for (size_t i = 0; i < offsets.size(); ++i) {
      const uint8_t* q = base + offsets[i];
      const int e0 = q[0] - colours[3 * i], e1 = q[1] - colours[3 * i + 1],
                e2 = q[2] - colours[3 * i + 2];
      sum += e0 * e0 + e1 * e1 + e2 * e2;
    }
    cost[static_cast<size_t>(d - first)] = static_cast<double>(sum);
  }
  const size_t at = static_cast<size_t>(std::min_element(cost.begin(), cost.end()) - cost.begin());
  if (at == 0 || at == cost.size() - 1) return m;
  m.disparity_px =
      first + static_cast<double>(at) + parabola_offset(cost[at - 1], cost[at], cost[at + 1]);
  m.cost = cost[at] / (3.0 * 255.0 * 255.0 * static_cast<double>(offsets.size()));
  m.found = m.disparity_px > 0.0;
  return m;
}

}  // namespace

std::string StereoDetectorConfig::validate() const {
  if (!(max_range_m > 0.0)) return "max_range_m: expected > 0";
  for (const auto& [key, range] : {std::pair<std::string, const HsvRange*>{"blue_hsv", &blue_hsv},
                                   {"yellow_hsv", &yellow_hsv},
                                   {"orange_hsv", &orange_hsv}})
    if (std::string e = check_hsv(key, *range); !e.empty()) return e;
  if (close_kernel_px < 0) return "close_kernel_px: expected >= 0";
  if (min_blob_area_px < 1) return "min_blob_area_px: expected >= 1";
  if (min_box_height_px < 2) return "min_box_height_px: expected >= 2";
  if (!(merge_gap_fraction >= 0.0)) return "merge_gap_fraction: expected >= 0";
  if (!(max_part_height_ratio >= 1.0)) return "max_part_height_ratio: expected >= 1";
  if (!(min_aspect > 0.0 && min_aspect < max_aspect))
    return "min_aspect, max_aspect: expected 0 < min_aspect < max_aspect";
  if (!(min_height_ratio > 0.0 && min_height_ratio < 1.0 && max_height_ratio > 1.0))
    return "min_height_ratio, max_height_ratio: expected 0 < min < 1 < max";
  if (!(max_disparity_px > 1.0)) return "max_disparity_px: expected > 1";
  if (!(max_match_cost > 0.0)) return "max_match_cost: expected > 0";
  if (border_px < 0) return "border_px: expected >= 0";
  if (!(tip_fraction > 0.0 && tip_fraction <= 1.0)) return "tip_fraction: expected in (0, 1]";
  if (!(pixel_sigma_px > 0.0)) return "pixel_sigma_px: expected > 0";
  if (!(disparity_sigma_px > 0.0)) return "disparity_sigma_px: expected > 0";
  if (!(min_variance_m2 >= 0.0)) return "min_variance_m2: expected >= 0";
  return "";
}

core::ConeObservations StereoDetections::observations() const {
  core::ConeObservations out;
  out.stamp = stamp;
  out.cones.reserve(cones.size());
  for (const CameraCone& c : cones) out.cones.push_back(c.observation);
  return out;
}

struct StereoConeDetector::Undistortion {
  std::mutex mutex;
  // the calibration the maps are for
  core::CameraIntrinsics intrinsics;
  cv::Mat map1, map2;
};

StereoConeDetector::StereoConeDetector(const StereoDetectorConfig& config)
    : config_(config), undistortion_(std::make_shared<Undistortion>()) {
  if (const std::string error = config.validate(); !error.empty())
    throw std::invalid_argument("stereo detector: " + error);
}

StereoDetections StereoConeDetector::detect(const core::StereoFrame& frame) const {
  const StereoDetectorConfig& c = config_;
  StereoDetections out;
  out.stamp = frame.stamp;
  const int width = frame.left.width_px;
  const int height = frame.left.height_px;
  const size_t bytes = 3 * static_cast<size_t>(width) * static_cast<size_t>(height);
  if (width <= 0 || height <= 0) return out;
  if (frame.left.rgb.size() != bytes || frame.right.width_px != width ||
      frame.right.height_px != height || frame.right.rgb.size() != bytes)
    throw std::invalid_argument("stereo detector: left and right images differ in size");
  const core::CameraIntrinsics& k = frame.intrinsics;
  const double focal_baseline = k.fx * frame.baseline_m;
  if (!(focal_baseline > 0.0)) throw std::invalid_argument("stereo detector: no baseline");

  // the pinhole view of both images (a lens that distorts is undone with its own calibration)
  cv::Mat left = as_mat(frame.left);
  cv::Mat right = as_mat(frame.right);
  if (k.distorted()) {
    cv::Mat map1, map2;
    {
      Undistortion& u = *undistortion_;
      const std::lock_guard<std::mutex> lock(u.mutex);
      if (u.map1.empty() || u.intrinsics != k) {
        const cv::Matx33d camera(k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0);
        const cv::Mat lens(k.distortion.size(), 1, CV_64F, const_cast<double*>(k.distortion.data()));
        // fresh buffers: a caller may still be reading the old maps
        cv::Mat fresh1, fresh2;
        cv::initUndistortRectifyMap(camera, lens, cv::Mat(), camera, cv::Size(width, height),
                                    CV_16SC2, fresh1, fresh2);
        u.map1 = fresh1;
        u.map2 = fresh2;
        u.intrinsics = k;
      }
      map1 = u.map1;  // shared, read-only from here on
      map2 = u.map2;
    }
    cv::Mat straight_left, straight_right;
    cv::remap(left, straight_left, map1, map2, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
    cv::remap(right, straight_right, map1, map2, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
    left = straight_left;
    right = straight_right;
  }

  // colour masks of the left image, closed so that a pixel-wide gap does not split a band
  const std::array<cv::Mat, kBodyColours> masks = colour_masks(left, c);
  std::vector<Blob> boxes;
  const cv::Mat kernel =
      c.close_kernel_px > 0
          ? cv::getStructuringElement(cv::MORPH_RECT, {c.close_kernel_px, c.close_kernel_px})
          : cv::Mat();
  for (int colour = 0; colour < kBodyColours; ++colour) {
    const auto body = static_cast<BodyColour>(colour);
    cv::Mat closed = masks[colour];
    if (!kernel.empty()) {
      closed = cv::Mat();  // a new buffer: the raw mask is kept for matching
      cv::morphologyEx(masks[colour], closed, cv::MORPH_CLOSE, kernel);
    }

    // blobs, and the stripe-split parts of each cone merged into one box
    std::vector<Blob> merged =
        merge_stripes(find_blobs(closed, body, c.min_blob_area_px), closed,
                      body == kOrangeBody ? 3 : 2, c.merge_gap_fraction, c.max_part_height_ratio);
    boxes.insert(boxes.end(), merged.begin(), merged.end());
  }

  for (const Blob& blob : boxes) {
    const cv::Rect& box = blob.box;

    // shape sanity before matching: tall enough, cone-like aspect, not cut by a side border
    if (box.height < c.min_box_height_px) continue;
    const double aspect = static_cast<double>(box.width) / box.height;
    if (aspect < c.min_aspect || aspect > c.max_aspect) {
      ++out.rejected_boxes;
      continue;
    }
    if (box.x < c.border_px || box.x + box.width > width - c.border_px) {
      ++out.rejected_boxes;
      continue;
    }

    // disparity range implied by the box height: small cone (or big orange) from half to twice
    const double small_h = core::cone_size(core::ConeClass::kOrangeSmall).height_m;
    const double big_h = core::cone_size(core::ConeClass::kOrangeBig).height_m;
    const double tallest = blob.colour == kOrangeBody ? big_h : small_h;
    const double d_near = focal_baseline * box.height / (k.fy * small_h);
    const double d_far = focal_baseline * box.height / (k.fy * tallest);
    const double d_lo = std::max(0.0, 0.5 * d_far - 1.0);
    const double d_hi = std::min(c.max_disparity_px, 2.0 * d_near + 1.0);

    // template: the box grown by a pixel; mask: the convex hull of its colour pixels, grown by
    // a pixel, so that the stripes count and the background behind the cone does not
    const cv::Rect tbox = (box + cv::Size(2, 2) - cv::Point(1, 1)) & cv::Rect(0, 0, width, height);
    std::vector<cv::Point> pixels;
    cv::findNonZero(masks[blob.colour](tbox), pixels);
    if (pixels.size() < 3) continue;
    std::vector<cv::Point> hull;
    cv::convexHull(pixels, hull);
    cv::Mat tmask = cv::Mat::zeros(tbox.size(), CV_8U);
    cv::fillConvexPoly(tmask, hull, cv::Scalar(255));
    cv::dilate(tmask, tmask, cv::getStructuringElement(cv::MORPH_RECT, {3, 3}));

    // the whole cone matched along its epipolar line
    const RowMatch whole = match_along_row(left, right, tbox, tmask, d_lo, d_hi);
    if (!whole.found || whole.cost > c.max_match_cost) {
      ++out.unmatched_boxes;
      continue;
    }
    const double disparity = whole.disparity_px;

    // class: the colour, and for orange the size whose expected height fits the box best
    const double depth_box = focal_baseline / disparity;
    core::ConeClass cls = blob.colour == kBlueBody     ? core::ConeClass::kBlue
                          : blob.colour == kYellowBody ? core::ConeClass::kYellow
                                                       : core::ConeClass::kOrangeSmall;
    auto height_ratio = [&](core::ConeClass cc) {
      return box.height / (k.fy * core::cone_size(cc).height_m / depth_box);
    };
    if (cls == core::ConeClass::kOrangeSmall &&
        std::abs(std::log(height_ratio(core::ConeClass::kOrangeBig))) <
            std::abs(std::log(height_ratio(core::ConeClass::kOrangeSmall))))
      cls = core::ConeClass::kOrangeBig;
    const double ratio = height_ratio(cls);
    if (ratio < c.min_height_ratio || ratio > c.max_height_ratio) {
      ++out.rejected_boxes;
      continue;
    }

    // the point triangulated: the box centre with the whole cone's disparity, or the tip: the
    // top rows of the cone matched on their own (a pixel around the whole cone's disparity), at
    // the axis column of their colour pixels
    StereoPoint point{box.x + 0.5 * (box.width - 1), box.y + 0.5 * (box.height - 1), disparity};
    if (c.triangulate_tip) {
      const int tip_rows = std::max(3, static_cast<int>(std::lround(c.tip_fraction * box.height)));
      const cv::Rect top(tbox.x, tbox.y, tbox.width, std::min(tbox.height, tip_rows + 1));
      const RowMatch tip = match_along_row(left, right, top, tmask(top - tbox.tl()),
                                           disparity - 2.0, disparity + 2.0);
      const double u = axis_column(masks[blob.colour], box, box.y, box.y + tip_rows);
      if (!tip.found || !std::isfinite(u)) {
        ++out.unmatched_boxes;
        continue;
      }
      point = {u, static_cast<double>(box.y), tip.disparity_px};
    }

    // triangulation in the left camera's optical frame, then into the vehicle frame
    const double depth = focal_baseline / point.disparity_px;
    if (depth > c.max_range_m) continue;
    const Eigen::Vector3d in_camera((point.u - k.cx) * depth / k.fx,
                                    (point.v - k.cy) * depth / k.fy, depth);
    const Eigen::Vector3d in_vehicle = frame.left_in_vehicle.transform(in_camera);

    // covariance: pixel and disparity noise through the triangulation Jacobian (depth sigma
    // grows with the square of the depth), rotated into the vehicle frame
    Eigen::Matrix3d jacobian;
    jacobian << depth / k.fx, 0.0, -in_camera.x() / point.disparity_px,  //
        0.0, depth / k.fy, -in_camera.y() / point.disparity_px,          //
        0.0, 0.0, -depth / point.disparity_px;
    const Eigen::Vector3d noise(c.pixel_sigma_px, c.pixel_sigma_px, c.disparity_sigma_px);
    const Eigen::Matrix3d camera_cov =
        jacobian * noise.cwiseAbs2().asDiagonal() * jacobian.transpose();
    const Eigen::Matrix3d rotation = frame.left_in_vehicle.orientation.toRotationMatrix();
    const Eigen::Matrix3d vehicle_cov = rotation * camera_cov * rotation.transpose();

    CameraCone cone;
    cone.observation.position = in_vehicle.head<2>();
    cone.observation.cls = cls;
    cone.observation.covariance =
        vehicle_cov.topLeftCorner<2, 2>() + c.min_variance_m2 * Eigen::Matrix2d::Identity();
    cone.observation.track_id = -1;
    cone.box = {box.x, box.y, box.width, box.height};
    cone.disparity_px = point.disparity_px;
    cone.depth_m = depth;
    out.cones.push_back(cone);
  }
  return out;
}

}  // namespace conesim::slam::frontend
