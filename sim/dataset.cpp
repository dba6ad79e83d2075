#include "sim/dataset.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <ostream>
#include <stdexcept>

#include "core/clutter.hpp"
#include "core/cone_geometry.hpp"
#include "core/error.hpp"
#include "core/rng.hpp"
#include "sensors/lidar_config.hpp"
#include "sensors/png_writer.hpp"
#include "sim/interrupt.hpp"
#include "sim/json_text.hpp"
#include "sim/run.hpp"
#include "sim/scenario.hpp"
#include "tracks/scenery.hpp"
#include "vehicle_models/cone_meshes.hpp"

namespace conesim::sim {

namespace fs = std::filesystem;
using core::TimeUs;
using json = nlohmann::json;

namespace {

// the randomisation's own stream of the dataset seed, and the runs' seeds
constexpr uint64_t kWorldStream = 901;
constexpr uint64_t kRunSeedStream = 902;
constexpr uint64_t kContactSheetStream = 903;
// more runs than asked for may follow while frames are missing, up to this many times as many
constexpr int kMaxRunFactor = 4;
// a box is checked against the segmentation when no pixel of its cone's silhouette is hidden
// (on a grade or crown the level plate's downhill corners dip into the ground: a pixel or two
// hidden) and none lies outside the image; the check asks for this IoU
constexpr double kBoxIouTarget = 0.9;
// ... on boxes at least this many pixels wide and high: one column of a 6 px box is IoU 0.86,
// and the renderer and the silhouette may split a pixel whose centre lies on an edge apart
constexpr double kCheckedMinSidePx = 12.0;
// cones nearer than this to the camera's near plane get no silhouette
constexpr double kNearPlaneM = 0.1;
// the contact sheet: 4 x 4 frames, each at half size
constexpr int kSheetColumns = 4;
constexpr int kSheetFrames = 16;

json pose_json(const core::Pose3& p) {
  return {{"position", {p.position.x(), p.position.y(), p.position.z()}},
          {"quaternion_wxyz",
           {p.orientation.w(), p.orientation.x(), p.orientation.y(), p.orientation.z()}}};
}

double box_iou(double ax0, double ay0, double ax1, double ay1, double bx0, double by0, double bx1,
               double by1) {
  const double ix = std::max(0.0, std::min(ax1, bx1) - std::max(ax0, bx0));
  const double iy = std::max(0.0, std::min(ay1, by1) - std::max(ay0, by0));
  const double inter = ix * iy;
  const double uni = (ax1 - ax0) * (ay1 - ay0) + (bx1 - bx0) * (by1 - by0) - inter;
  return uni > 0.0 ? inter / uni : 0.0;
}

// the cone meshes by class, in the cone frame (base centre at the origin)
const std::vector<vehicle_models::TriangleMesh>& cone_meshes() {
  static const std::vector<vehicle_models::TriangleMesh> meshes = [] {
    std::vector<vehicle_models::TriangleMesh> m;
    for (auto c : {core::ConeClass::kBlue, core::ConeClass::kYellow, core::ConeClass::kOrangeSmall,
                   core::ConeClass::kOrangeBig, core::ConeClass::kUnknown})
      m.push_back(vehicle_models::cone_mesh(core::cone_geometry(c)));
    return m;
  }();
  return meshes;
}

uint8_t mask_class(int32_t object, const tracks::Track& track,
                   const std::vector<tracks::SceneryObject>& scenery) {
  using S = sensors::SegmentationImage;
  if (object >= 0)
    return static_cast<uint8_t>(MaskClass::kConeBase + yolo_class(track.cone(object).cls));
  if (object == S::kGround) return MaskClass::kGround;
  if (object == S::kCar) return MaskClass::kCar;
  if (object <= S::kSceneryBase) {
    const size_t index = static_cast<size_t>(S::kSceneryBase - object);
    if (index < scenery.size())
      return static_cast<uint8_t>(MaskClass::kClutterBase + static_cast<int>(scenery[index].cls));
  }
  return MaskClass::kNothing;
}

// draws a rectangle's outline, `thick` pixels wide
void draw_box(core::RgbImage& image, int x0, int y0, int x1, int y1, const uint8_t rgb[3],
              int thick) {
  auto put = [&](int x, int y) {
    if (x < 0 || y < 0 || x >= image.width_px || y >= image.height_px) return;
    uint8_t* p = image.rgb.data() + 3 * (static_cast<size_t>(y) * image.width_px + x);
    std::memcpy(p, rgb, 3);
  };
  for (int k = 0; k < thick; ++k) {
    for (int x = x0; x <= x1; ++x) put(x, y0 + k), put(x, y1 - k);
    for (int y = y0; y <= y1; ++y) put(x0 + k, y), put(x1 - k, y);
  }
}

const uint8_t kClassRgb[5][3] = {
    {40, 110, 255}, {255, 230, 0}, {255, 140, 0}, {255, 40, 200}, {255, 255, 255}};

// one run's recorder: frames at every_s, at most `quota`, each with its masks and labels, and
// the LiDAR sweep that ends nearest to it
class FrameWriter : public LabelledDataSink {
 public:
  FrameWriter(const DatasetOptions& options, const fs::path& root, const Scenario& scenario,
              const tracks::Track& track, int run_index, int first_index, int quota,
              double lidar_period_s, std::map<int, core::RgbImage>* thumbnails)
      : options_(options),
        root_(root),
        track_(track),
        ground_(track, scenario.ground, scenario.seed),
        scenery_(tracks::place_scenery(track, scenario.clutter, scenario.seed)),
        run_index_(run_index),
        next_index_(first_index),
        quota_(quota),
        half_sweep_us_(core::from_seconds(0.5 * lidar_period_s)),
        // the first frame one period after the go signal: the car stands still before it
        next_capture_us_(core::from_seconds(scenario.start_delay_s + options.every_s)),
        thumbnails_(thumbnails) {}

  bool wants_camera(TimeUs t) override {
    return written_ < quota_ && t >= next_capture_us_;
  }

  void on_camera(TimeUs t, const core::StereoFrame& frame, const core::StereoLabels& poses,
                 const sensors::SegmentationImage& seg) override {
    next_capture_us_ = t + core::from_seconds(options_.every_s);
    const int index = next_index_++;
    ++written_;
    char stem_buf[16];
    std::snprintf(stem_buf, sizeof(stem_buf), "%06d", index);
    const std::string stem = stem_buf;
    const int w = seg.width_px, h = seg.height_px;

    // the image, its masks, its boxes
    check(sensors::write_png((root_ / "images" / (stem + ".png")).string(), frame.left));
    std::vector<uint8_t> cls(static_cast<size_t>(w) * h), inst(2 * static_cast<size_t>(w) * h, 0);
    for (size_t i = 0; i < seg.object.size(); ++i) {
      cls[i] = mask_class(seg.object[i], track_, scenery_);
      if (seg.object[i] >= 0) {
        const int v = seg.object[i] + 1;  // 0: no cone
        inst[2 * i] = static_cast<uint8_t>(v >> 8);
        inst[2 * i + 1] = static_cast<uint8_t>(v & 0xff);
      }
    }
    check(sensors::write_file_bytes((root_ / "masks" / (stem + "_class.png")).string(),
                                    sensors::encode_grey_png(w, h, 8, cls)));
    check(sensors::write_file_bytes((root_ / "masks" / (stem + "_instance.png")).string(),
                                    sensors::encode_grey_png(w, h, 16, inst)));
    const std::vector<ConeImageLabel> cones =
        label_cones(track_, ground_, frame.intrinsics, poses.left_in_track, seg,
                    options_.min_visible, options_.min_pixels);
    std::ofstream yolo(root_ / "labels" / (stem + ".txt"));
    json cones_json = json::array();
    for (const ConeImageLabel& c : cones) {
      if (c.boxed) {
        char line[160];
        std::snprintf(line, sizeof(line), "%d %.6f %.6f %.6f %.6f\n", yolo_class(c.cls),
                      0.5 * (c.x0 + c.x1) / w, 0.5 * (c.y0 + c.y1) / h, (c.x1 - c.x0) / w,
                      (c.y1 - c.y0) / h);
        yolo << line;
        ++summary_.boxes;
        if (c.occlusion == 0.0 && c.truncation == 0.0 &&
            std::min(c.x1 - c.x0, c.y1 - c.y0) >= kCheckedMinSidePx) {
          ++summary_.checked_boxes;
          summary_.min_box_iou = std::min(summary_.min_box_iou, c.box_iou);
          summary_.boxes_below_iou += c.box_iou < kBoxIouTarget;
        }
      }
      cones_json.push_back(
          {{"cone_id", c.cone_id},
           {"file_id", track_.file_id(c.cone_id)},
           {"class", yolo_class_names()[static_cast<size_t>(yolo_class(c.cls))]},
           {"range_m", c.range_m},
           {"boxed", c.boxed},
           {"too_near", c.too_near},
           {"box", {c.x0, c.y0, c.x1, c.y1}},
           {"seen_box", {c.seen_x0, c.seen_y0, c.seen_x1, c.seen_y1}},
           {"visible_px", c.visible_px},
           {"silhouette_px", c.silhouette_px},
           {"occlusion", c.occlusion},
           {"truncation", c.truncation},
           {"mask_iou", c.mask_iou},
           {"box_iou", c.box_iou}});
    }
    yolo.close();
    if (!yolo) throw std::runtime_error("cannot write " + (root_ / "labels" / stem).string());
    if (thumbnails_ && thumbnails_->count(index)) (*thumbnails_)[index] = thumbnail(frame.left, cones);

    json f = {{"index", index},
              {"run", run_index_},
              {"t_s", core::to_seconds(t)},
              {"image", "images/" + stem + ".png"},
              {"labels", "labels/" + stem + ".txt"},
              {"class_mask", "masks/" + stem + "_class.png"},
              {"instance_mask", "masks/" + stem + "_instance.png"},
              {"lidar", nullptr},
              {"left_camera_in_track", pose_json(poses.left_in_track)},
              {"right_camera_in_track", pose_json(poses.right_in_track)},
              {"cones", cones_json}};
    frames_.push_back(std::move(f));
    pending_.push_back({t, frames_.size() - 1});
  }

  bool wants_lidar() const override { return options_.lidar; }

  void on_lidar(TimeUs end_us, const sensors::LidarScan& scan) override {
    // the frame this sweep ends nearest to (within half a sweep), if any is waiting
    for (auto it = pending_.begin(); it != pending_.end();) {
      if (it->first + half_sweep_us_ < end_us) {
        it = pending_.erase(it);  // its sweep has passed (lost)
        continue;
      }
      if (std::llabs(end_us - it->first) > half_sweep_us_) {
        ++it;
        continue;
      }
      json& f = frames_[it->second];
      const std::string stem = f["image"].get<std::string>().substr(7, 6);
      write_pcd(root_ / "lidar" / (stem + ".pcd"), scan);
      f["lidar"] = "lidar/" + stem + ".pcd";
      f["lidar_end_s"] = core::to_seconds(end_us);
      f["lidar_sensor_in_track_start"] = pose_json(scan.labels.sensor_pose_start);
      f["lidar_sensor_in_track_end"] = pose_json(scan.labels.sensor_pose_end);
      ++summary_.lidar_sweeps;
      pending_.erase(it);
      return;
    }
  }

  int written() const { return written_; }
  std::vector<json>& frames() { return frames_; }
  const DatasetSummary& summary() const { return summary_; }

 private:
  // the image with the boxes drawn in their class colour, at half size
  static core::RgbImage thumbnail(const core::RgbImage& image,
                                  const std::vector<ConeImageLabel>& cones) {
    core::RgbImage boxed = image;
    for (const ConeImageLabel& c : cones)
      if (c.boxed)
        draw_box(boxed, static_cast<int>(c.x0), static_cast<int>(c.y0),
                 static_cast<int>(c.x1) - 1, static_cast<int>(c.y1) - 1,
                 kClassRgb[yolo_class(c.cls)], 2);
    core::RgbImage half{boxed.width_px / 2, boxed.height_px / 2, {}};
    half.rgb.resize(3 * static_cast<size_t>(half.width_px) * half.height_px);
    for (int y = 0; y < half.height_px; ++y)
      for (int x = 0; x < half.width_px; ++x)
        for (int ch = 0; ch < 3; ++ch) {
          int sum = 0;
          for (int dy = 0; dy < 2; ++dy)
            for (int dx = 0; dx < 2; ++dx)
              sum += boxed.rgb[3 * ((static_cast<size_t>(2 * y + dy)) * boxed.width_px + 2 * x + dx) + ch];
          half.rgb[3 * (static_cast<size_t>(y) * half.width_px + x) + ch] = static_cast<uint8_t>(sum / 4);
        }
    return half;
  }

  static void check(const std::string& error) {
    if (!error.empty()) throw std::runtime_error(error);
  }

  void write_pcd(const fs::path& file, const sensors::LidarScan& scan) const {
    // binary PCD 0.7: x y z intensity (float), ring (uint16), label (int32), class (uint8)
    const auto& points = scan.cloud.points;
    std::string header =
        "# .PCD v0.7 - conesim LiDAR sweep, sensor frame (docs/dataset.md)\n"
        "VERSION 0.7\nFIELDS x y z intensity ring label class\nSIZE 4 4 4 4 2 4 1\n"
        "TYPE F F F F U I U\nCOUNT 1 1 1 1 1 1 1\nWIDTH " +
        std::to_string(points.size()) + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " +
        std::to_string(points.size()) + "\nDATA binary\n";
    std::vector<char> data(points.size() * 23);
    char* p = data.data();
    for (size_t i = 0; i < points.size(); ++i) {
      const core::LidarPoint& q = points[i];
      const int32_t label = i < scan.labels.cone_id.size() ? scan.labels.cone_id[i] : -1;
      uint8_t cls = MaskClass::kGround;
      if (label >= 0)
        cls = static_cast<uint8_t>(MaskClass::kConeBase + yolo_class(track_.cone(label).cls));
      else if (const auto c = core::clutter_of_label(label))
        cls = static_cast<uint8_t>(MaskClass::kClutterBase + static_cast<int>(*c));
      std::memcpy(p, &q.x, 4), p += 4;
      std::memcpy(p, &q.y, 4), p += 4;
      std::memcpy(p, &q.z, 4), p += 4;
      std::memcpy(p, &q.intensity, 4), p += 4;
      std::memcpy(p, &q.ring, 2), p += 2;
      std::memcpy(p, &label, 4), p += 4;
      std::memcpy(p, &cls, 1), p += 1;
    }
    std::ofstream out(file, std::ios::binary);
    out << header;
    out.write(data.data(), static_cast<std::streamsize>(data.size()));
    if (!out) throw std::runtime_error("cannot write " + file.string());
  }

  const DatasetOptions& options_;
  fs::path root_;
  const tracks::Track& track_;
  tracks::GroundModel ground_;
  std::vector<tracks::SceneryObject> scenery_;
  int run_index_ = 0;
  int next_index_ = 0;
  int quota_ = 0;
  int written_ = 0;
  TimeUs half_sweep_us_ = 0;
  TimeUs next_capture_us_ = 0;
  std::vector<json> frames_;
  std::vector<std::pair<TimeUs, size_t>> pending_;
  DatasetSummary summary_;
  // the contact sheet's frames: those whose index is a key get their thumbnail
  std::map<int, core::RgbImage>* thumbnails_ = nullptr;
};

}  // namespace

int yolo_class(core::ConeClass c) {
  switch (c) {
    case core::ConeClass::kBlue:
      return 0;
    case core::ConeClass::kYellow:
      return 1;
    case core::ConeClass::kOrangeSmall:
      return 2;
    case core::ConeClass::kOrangeBig:
      return 3;
    case core::ConeClass::kUnknown:
      break;
  }
  return 4;
}

const std::vector<std::string>& yolo_class_names() {
  static const std::vector<std::string> names = {"blue_cone", "yellow_cone", "orange_cone",
                                                 "large_orange_cone", "unknown_cone"};
  return names;
}

namespace {

// true when q lies in the triangle (a, b, d) whose signed doubled area is `area` (its edges
// included)
bool covers(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& d,
            double area, const Eigen::Vector2d& q) {
  auto edge = [&](const Eigen::Vector2d& p0, const Eigen::Vector2d& p1) {
    return ((p1 - p0).x() * (q - p0).y() - (p1 - p0).y() * (q - p0).x()) * area;
  };
  return edge(a, b) >= 0 && edge(b, d) >= 0 && edge(d, a) >= 0;
}

}  // namespace

std::vector<ConeImageLabel> label_cones(const tracks::Track& track,
                                        const tracks::GroundModel& ground,
                                        const core::CameraIntrinsics& k,
                                        const core::Pose3& left_in_track,
                                        const sensors::SegmentationImage& seg, double min_visible,
                                        int min_pixels) {
  const int w = seg.width_px, h = seg.height_px;
  // the seen pixels of each cone and their box
  struct Seen {
    int n = 0;
    int x0 = 1 << 30, y0 = 1 << 30, x1 = -1, y1 = -1;
  };
  std::map<int, Seen> seen;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const int32_t id = seg.at(x, y);
      if (id < 0) continue;
      Seen& s = seen[id];
      ++s.n;
      s.x0 = std::min(s.x0, x), s.x1 = std::max(s.x1, x);
      s.y0 = std::min(s.y0, y), s.y1 = std::max(s.y1, y);
    }

  const core::Pose3 to_camera = left_in_track.inverse();
  std::vector<ConeImageLabel> out;
  for (const auto& [id, s] : seen) {
    const tracks::Cone& cone = track.cone(id);
    ConeImageLabel c;
    c.cone_id = id;
    c.cls = cone.cls;
    c.range_m = (cone.position - left_in_track.position.head<2>()).norm();
    c.visible_px = s.n;
    c.seen_x0 = s.x0, c.seen_y0 = s.y0, c.seen_x1 = s.x1 + 1.0, c.seen_y1 = s.y1 + 1.0;

    // the mesh where the camera draws it: on the ground under the cone's centre, plate edges
    // along the track's axes, through the camera's lens model (pixel centres at integers)
    const vehicle_models::TriangleMesh& mesh = cone_meshes()[static_cast<size_t>(cone.cls)];
    const Eigen::Vector3d base(cone.position.x(), cone.position.y(),
                               ground.height(cone.position.x(), cone.position.y()));
    std::vector<Eigen::Vector2d> uv(static_cast<size_t>(mesh.vertex_count()));
    // with a lens: the same vertices in the pinhole view, where the segmentation was decided
    const std::vector<Eigen::Vector2d>* pinhole_point = seg.pinhole_point.get();
    std::vector<Eigen::Vector2d> uv_pinhole(pinhole_point ? uv.size() : 0);
    double u0 = 1e18, v0 = 1e18, u1 = -1e18, v1 = -1e18;
    for (int i = 0; i < mesh.vertex_count() && !c.too_near; ++i) {
      const Eigen::Vector3d p =
          to_camera.transform(base + Eigen::Vector3d(mesh.vertices[3 * i], mesh.vertices[3 * i + 1],
                                                     mesh.vertices[3 * i + 2]));
      if (p.z() < kNearPlaneM) {
        c.too_near = true;
        break;
      }
      uv[static_cast<size_t>(i)] = k.pixel_of({p.x() / p.z(), p.y() / p.z()});  // the lens too
      if (pinhole_point)
        uv_pinhole[static_cast<size_t>(i)] = {k.fx * p.x() / p.z() + k.cx, k.fy * p.y() / p.z() + k.cy};
      u0 = std::min(u0, uv[i].x()), u1 = std::max(u1, uv[i].x());
      v0 = std::min(v0, uv[i].y()), v1 = std::max(v1, uv[i].y());
    }
    if (c.too_near) {
      out.push_back(c);
      continue;
    }

    // rasterise: a pixel belongs to the silhouette when its centre lies in a triangle; through
    // a lens, when the pinhole point it shows does (the rule the segmentation was drawn by), so
    // a pixel may join from one further out (the triangles' edges bend a little in the image)
    const int grow = pinhole_point ? 1 : 0;
    const int bx0 = static_cast<int>(std::ceil(u0 - 0.5)) - grow,
              bx1 = static_cast<int>(std::floor(u1 + 0.5)) + grow;
    const int by0 = static_cast<int>(std::ceil(v0 - 0.5)) - grow,
              by1 = static_cast<int>(std::floor(v1 + 0.5)) + grow;
    const int bw = std::max(0, bx1 - bx0 + 1), bh = std::max(0, by1 - by0 + 1);
    std::vector<uint8_t> cover(static_cast<size_t>(bw) * bh, 0);
    for (size_t f = 0; f + 2 < mesh.faces.size(); f += 3) {
      const Eigen::Vector2d& a = uv[static_cast<size_t>(mesh.faces[f])];
      const Eigen::Vector2d& b = uv[static_cast<size_t>(mesh.faces[f + 1])];
      const Eigen::Vector2d& d = uv[static_cast<size_t>(mesh.faces[f + 2])];
      const double area = (b - a).x() * (d - a).y() - (b - a).y() * (d - a).x();
      if (std::abs(area) < 1e-12) continue;
      const int tx0 = std::max(bx0, static_cast<int>(std::ceil(std::min({a.x(), b.x(), d.x()}))) - grow);
      const int tx1 = std::min(bx1, static_cast<int>(std::floor(std::max({a.x(), b.x(), d.x()}))) + grow);
      const int ty0 = std::max(by0, static_cast<int>(std::ceil(std::min({a.y(), b.y(), d.y()}))) - grow);
      const int ty1 = std::min(by1, static_cast<int>(std::floor(std::max({a.y(), b.y(), d.y()}))) + grow);
      // the triangle in the view its test points are in
      const bool in_pinhole = pinhole_point != nullptr;
      const Eigen::Vector2d& pa = in_pinhole ? uv_pinhole[static_cast<size_t>(mesh.faces[f])] : a;
      const Eigen::Vector2d& pb = in_pinhole ? uv_pinhole[static_cast<size_t>(mesh.faces[f + 1])] : b;
      const Eigen::Vector2d& pd = in_pinhole ? uv_pinhole[static_cast<size_t>(mesh.faces[f + 2])] : d;
      const double pinhole_area =
          (pb - pa).x() * (pd - pa).y() - (pb - pa).y() * (pd - pa).x();
      for (int y = ty0; y <= ty1; ++y)
        for (int x = tx0; x <= tx1; ++x) {
          // inside the image through a lens: the pinhole point the segmentation decided this
          // pixel at, against the triangle in the pinhole view
          const bool through_lens = in_pinhole && x >= 0 && y >= 0 && x < w && y < h;
          const bool in = through_lens
                              ? covers(pa, pb, pd, pinhole_area,
                                       (*pinhole_point)[static_cast<size_t>(y) * w + x])
                              : covers(a, b, d, area, Eigen::Vector2d(x, y));
          if (in) cover[static_cast<size_t>(y - by0) * bw + (x - bx0)] = 1;
        }
    }

    // the silhouette inside and outside the image, and against the seen pixels
    int inside = 0, total = 0, both = 0;
    int ix0 = 1 << 30, iy0 = 1 << 30, ix1 = -1, iy1 = -1;
    for (int y = by0; y <= by1; ++y)
      for (int x = bx0; x <= bx1; ++x) {
        if (!cover[static_cast<size_t>(y - by0) * bw + (x - bx0)]) continue;
        ++total;
        if (x < 0 || y < 0 || x >= w || y >= h) continue;
        ++inside;
        both += seg.at(x, y) == id;
        ix0 = std::min(ix0, x), ix1 = std::max(ix1, x);
        iy0 = std::min(iy0, y), iy1 = std::max(iy1, y);
      }
    c.silhouette_px = inside;
    c.silhouette_total_px = total;
    if (inside == 0) {
      out.push_back(c);
      continue;
    }
    c.x0 = ix0, c.y0 = iy0, c.x1 = ix1 + 1.0, c.y1 = iy1 + 1.0;
    c.occlusion = std::clamp(1.0 - static_cast<double>(both) / inside, 0.0, 1.0);
    c.truncation = total > 0 ? 1.0 - static_cast<double>(inside) / total : 0.0;
    c.mask_iou = static_cast<double>(both) / (inside + s.n - both);
    c.box_iou = box_iou(c.x0, c.y0, c.x1, c.y1, c.seen_x0, c.seen_y0, c.seen_x1, c.seen_y1);
    const double visible = static_cast<double>(both) / std::max(total, 1);
    c.boxed = s.n >= min_pixels && visible >= min_visible;
    out.push_back(c);
  }
  return out;
}

void check_dataset_options(const DatasetOptions& o) {
  if (o.frames < 1 || o.frames > 1000000)
    throw core::InputError("--frames", 0, "expected 1 to 1000000 frames, got " + std::to_string(o.frames));
  if (o.runs < 1 || o.runs > o.frames)
    throw core::InputError("--runs", 0,
                           "expected 1 to --frames runs, got " + std::to_string(o.runs));
  if (!(o.every_s >= 0.05 && o.every_s <= 60.0))
    throw core::InputError("--every", 0, "expected 0.05 to 60 s between frames");
  if (!(o.min_visible >= 0.0 && o.min_visible <= 1.0))
    throw core::InputError("--min-visible", 0, "expected a fraction from 0 to 1");
  if (o.min_pixels < 1) throw core::InputError("--min-pixels", 0, "expected at least 1 pixel");
  std::error_code ec;
  if (fs::exists(o.out_dir, ec) && !fs::is_empty(o.out_dir, ec))
    throw core::InputError(o.out_dir.string(), 0,
                           "the dataset folder exists and is not empty: give a new one");
}

DatasetSummary write_dataset(const DatasetOptions& o, std::ostream& log) {
  check_dataset_options(o);
  const auto wall_start = std::chrono::steady_clock::now();
  const fs::path scenario_file = find_scenario(o.scenario);
  // every override is checked before a folder is made: the base scenario with them
  load_scenario(scenario_file, o.sets);

  fs::create_directories(o.out_dir);
  for (const char* sub : {"images", "labels", "masks", "lidar", "runs"})
    fs::create_directories(o.out_dir / sub);
  std::ofstream(o.out_dir / kIncompleteFile)
      << "conesim dataset is writing this folder: it is not complete until manifest.json is\n";

  core::Rng world(core::derive_seed(o.seed, kWorldStream));
  // the contact sheet's frames, drawn from the seed before any run
  std::map<int, core::RgbImage> thumbnails;
  {
    core::Rng pick(core::derive_seed(o.seed, kContactSheetStream));
    std::vector<int> order(static_cast<size_t>(o.frames));
    for (int i = 0; i < o.frames; ++i) order[static_cast<size_t>(i)] = i;
    for (size_t i = order.size(); i > 1; --i)
      std::swap(order[i - 1],
                order[static_cast<size_t>(core::uniform_int(pick, 0, static_cast<int64_t>(i) - 1))]);
    for (size_t i = 0; i < std::min<size_t>(order.size(), kSheetFrames); ++i)
      thumbnails[order[i]] = core::RgbImage{};
  }
  const int quota = (o.frames + o.runs - 1) / o.runs;
  std::vector<json> frames, runs;
  DatasetSummary summary;
  int run = 0;
  json camera_json, lidar_json;
  for (; static_cast<int>(frames.size()) < o.frames && run < kMaxRunFactor * o.runs; ++run) {
    if (interrupt_signal() != 0) break;
    // this run's seed and world
    const uint64_t seed = core::derive_seed(o.seed, kRunSeedStream + 1000 * static_cast<uint64_t>(run)) %
                          1000000 + 1;
    std::vector<std::string> sets;
    json world_json = json::object();
    if (o.randomise) {
      const double density = std::round(10.0 * core::uniform(world, 0.0, 8.0)) / 10.0;
      const bool grass = core::uniform(world, 0.0, 1.0) < 0.5;
      const double grade = std::round(10.0 * core::uniform(world, 0.0, 2.0)) / 10.0;
      const double crown = std::round(10.0 * core::uniform(world, 0.0, 1.5)) / 10.0;
      char buf[64];
      std::snprintf(buf, sizeof(buf), "%.1f", density);
      sets.push_back("world.clutter.objects_per_100m=" + std::string(buf));
      sets.push_back(std::string("world.clutter.grass_edge=") + (grass ? "true" : "false"));
      std::snprintf(buf, sizeof(buf), "%.1f", grade);
      sets.push_back("world.ground.grade_percent=" + std::string(buf));
      std::snprintf(buf, sizeof(buf), "%.1f", crown);
      sets.push_back("world.ground.crown_percent=" + std::string(buf));
      world_json = {{"clutter_objects_per_100m", density},
                    {"grass_edge", grass},
                    {"grade_percent", grade},
                    {"crown_percent", crown}};
      // and the sensors' look (light, exposure, noise) from the run's own seed
      sets.push_back("world.randomise=on");
    }
    sets.push_back("sensors.camera.enabled=true");
    if (o.lidar) sets.push_back("sensors.lidar.enabled=true");
    sets.insert(sets.end(), o.sets.begin(), o.sets.end());
    Scenario s = load_scenario(scenario_file, sets, seed);
    // a camera that only the dataset needs renders at the frames' rate, not the scenario's
    const bool camera_drives = s.perception == "stereo" || s.perception == "fused" ||
                               (s.perception_plugin && s.perception_plugin->camera);
    if (!camera_drives && core::whole_physics_steps(1.0 / o.every_s)) {
      char rate[64];
      std::snprintf(rate, sizeof(rate), "sensors.camera.rate_hz=%.9g", 1.0 / o.every_s);
      sets.insert(sets.end() - static_cast<std::ptrdiff_t>(o.sets.size()), rate);
      s = load_scenario(scenario_file, sets, seed);
    }
    const tracks::Track track = scenario_track(s);
    if (s.randomise) world_json["look"] = s.look;

    char name[32];
    std::snprintf(name, sizeof(name), "%03d", run);
    RunOptions options;
    options.out_dir = o.out_dir / "runs" / name;
    options.plot = false;
    // the sweep period of the scenario's LiDAR (its model is checked with the scenario)
    const auto preset = sensors::lidar_preset(s.sensors.lidar_model);
    const double lidar_period_s = preset ? 1.0 / preset->rate_hz : 0.1;
    FrameWriter writer(o, o.out_dir, s, track, run, static_cast<int>(frames.size()),
                       std::min(quota, o.frames - static_cast<int>(frames.size())), lidar_period_s,
                       &thumbnails);
    options.labelled = &writer;
    const RunResult r = run_scenario(s, track, options);
    if (r.interrupted_by != 0) break;
    for (json& f : writer.frames()) frames.push_back(std::move(f));
    const DatasetSummary& ws = writer.summary();
    summary.boxes += ws.boxes;
    summary.lidar_sweeps += ws.lidar_sweeps;
    summary.checked_boxes += ws.checked_boxes;
    summary.min_box_iou = std::min(summary.min_box_iou, ws.min_box_iou);
    summary.boxes_below_iou += ws.boxes_below_iou;
    runs.push_back({{"run", run},
                    {"seed", seed},
                    {"track", track.name},
                    {"folder", "runs/" + std::string(name)},
                    {"frames", writer.written()},
                    {"world", world_json},
                    {"completed", r.referee.completed},
                    {"sim_time_s", r.sim_time_s}});
    if (camera_json.is_null()) {
      const core::CameraIntrinsics k = sensors::stereo_intrinsics(s.sensors.camera);
      camera_json = {{"width_px", k.width_px}, {"height_px", k.height_px}, {"fx", k.fx},
                     {"fy", k.fy},             {"cx", k.cx},               {"cy", k.cy},
                     {"baseline_m", s.sensors.camera.baseline_m},
                     {"left_in_vehicle", pose_json(sensors::stereo_camera_in_vehicle(s.sensors.camera, true))},
                     {"distortion", k.distortion}};
      lidar_json = {{"model", s.sensors.lidar_model}, {"mount", s.sensors.lidar_mount}};
    }
    log << "run " << run << " (seed " << seed << ", " << track.name << "): " << writer.written()
        << " frames, " << frames.size() << " of " << o.frames << "\n";
  }
  if (interrupt_signal() != 0) {
    std::ofstream(o.out_dir / kIncompleteFile)
        << "conesim dataset was interrupted after " << frames.size()
        << " frames: this folder has no manifest.json and is not a dataset\n";
    summary.frames = static_cast<int>(frames.size());
    return summary;
  }
  if (static_cast<int>(frames.size()) < o.frames)
    throw std::runtime_error("only " + std::to_string(frames.size()) + " frames from " +
                             std::to_string(run) + " runs: the runs end too soon for --every " +
                             std::to_string(o.every_s) + " s; ask for more runs or a shorter --every");

  // the contact sheet: the picked frames, four to a row
  if (!thumbnails.empty()) {
    const core::RgbImage& first = thumbnails.begin()->second;
    const int tw = first.width_px, th = first.height_px;
    const int rows = (static_cast<int>(thumbnails.size()) + kSheetColumns - 1) / kSheetColumns;
    core::RgbImage sheet{kSheetColumns * tw, rows * th, {}};
    sheet.rgb.assign(3 * static_cast<size_t>(sheet.width_px) * sheet.height_px, 0);
    int k = 0;
    for (const auto& [index, thumb] : thumbnails) {
      const int col = k % kSheetColumns, row = k / kSheetColumns;
      ++k;
      if (thumb.width_px != tw || thumb.height_px != th) continue;
      for (int y = 0; y < th; ++y)
        std::memcpy(sheet.rgb.data() + 3 * (static_cast<size_t>(row * th + y) * sheet.width_px + col * tw),
                    thumb.rgb.data() + 3 * static_cast<size_t>(y) * tw, 3 * static_cast<size_t>(tw));
    }
    const std::string error = sensors::write_png((o.out_dir / "contact_sheet.png").string(), sheet);
    if (!error.empty()) throw std::runtime_error(error);
  }

  // data.yaml for YOLO trainers, then the manifest, last
  {
    std::ofstream yaml(o.out_dir / "data.yaml");
    yaml << "# conesim dataset: YOLO boxes of the left camera (docs/dataset.md); split as you wish\n"
         << "path: .\ntrain: images\nval: images\nnames:\n";
    for (size_t i = 0; i < yolo_class_names().size(); ++i)
      yaml << "  " << i << ": " << yolo_class_names()[i] << "\n";
  }
  summary.frames = static_cast<int>(frames.size());
  summary.runs = static_cast<int>(runs.size());
  summary.wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  json mask_classes = {{"0", "nothing (sky)"}, {"1", "ground"}, {"2", "car"}};
  for (size_t i = 0; i < yolo_class_names().size(); ++i)
    mask_classes[std::to_string(MaskClass::kConeBase + i)] = yolo_class_names()[i];
  for (core::ClutterClass c : core::kClutterClasses)
    mask_classes[std::to_string(MaskClass::kClutterBase + static_cast<int>(c))] =
        std::string(core::to_string(c));
  json manifest = {{"schema", "conesim-dataset/1"},
                   {"seed", o.seed},
                   {"scenario", o.scenario},
                   {"sets", o.sets},
                   {"every_s", o.every_s},
                   {"min_visible", o.min_visible},
                   {"min_pixels", o.min_pixels},
                   {"randomised", o.randomise},
                   {"yolo_classes", yolo_class_names()},
                   {"mask_classes", mask_classes},
                   {"camera", camera_json},
                   {"lidar", lidar_json},
                   {"summary",
                    {{"frames", summary.frames},
                     {"runs", summary.runs},
                     {"boxes", summary.boxes},
                     {"lidar_sweeps", summary.lidar_sweeps},
                     {"checked_boxes", summary.checked_boxes},
                     {"min_box_iou", summary.min_box_iou},
                     {"boxes_below_iou_0_9", summary.boxes_below_iou},
                     {"wall_s", summary.wall_s}}},
                   {"runs", runs},
                   {"frames", frames}};
  {
    const fs::path tmp = o.out_dir / "manifest.json.tmp";
    std::ofstream out(tmp);
    out << json_text(manifest, 1) << "\n";
    out.close();
    if (!out) throw std::runtime_error("cannot write " + tmp.string());
    fs::rename(tmp, o.out_dir / "manifest.json");
  }
  fs::remove(o.out_dir / kIncompleteFile);
  return summary;
}

}  // namespace conesim::sim
