#include "sim/replay_video.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

#include "core/error.hpp"
#include "vehicle_models/vehicle_params.hpp"

namespace conesim::sim {

namespace fs = std::filesystem;

namespace {

using Rgb = std::array<uint8_t, 3>;

constexpr Rgb kBackground{30, 32, 36};
constexpr Rgb kTruePath{235, 235, 235};
constexpr Rgb kEstimatedPath{230, 40, 230};
constexpr Rgb kCar{230, 30, 30};
constexpr Rgb kEvent{255, 60, 60};
constexpr Rgb kLidar{90, 200, 120};
constexpr Rgb kTimelineBack{70, 72, 78};
constexpr Rgb kTimelineDone{150, 155, 165};
constexpr Rgb kSky{120, 150, 185};
constexpr Rgb kGround{64, 78, 62};
// the strip under the map: the run's time line, events as ticks
constexpr int kTimelinePx = 28;

Rgb cone_colour(int cls) {
  switch (cls) {
    case 0:
      return {40, 90, 255};  // blue
    case 1:
      return {245, 215, 0};  // yellow
    case 2:
      return {255, 140, 0};  // small orange
    case 3:
      return {200, 70, 0};  // big orange
    default:
      return {200, 200, 200};
  }
}

// an RGB picture with the few primitives the frames need
struct Canvas {
  int w, h;
  std::vector<uint8_t> rgb;
  Canvas(int width, int height) : w(width), h(height), rgb(3 * size_t(width) * height) {}

  void fill(const Rgb& c) {
    for (size_t i = 0; i < rgb.size(); i += 3) rgb[i] = c[0], rgb[i + 1] = c[1], rgb[i + 2] = c[2];
  }
  void put(int x, int y, const Rgb& c) {
    if (x < 0 || y < 0 || x >= w || y >= h) return;
    const size_t i = 3 * (size_t(y) * w + x);
    rgb[i] = c[0], rgb[i + 1] = c[1], rgb[i + 2] = c[2];
  }
  void rect(int x0, int y0, int x1, int y1, const Rgb& c) {
    for (int y = std::max(0, y0); y < std::min(h, y1); ++y)
      for (int x = std::max(0, x0); x < std::min(w, x1); ++x) put(x, y, c);
  }
  void disc(double cx, double cy, double r, const Rgb& c) {
    const int r_px = static_cast<int>(std::ceil(r));
    for (int dy = -r_px; dy <= r_px; ++dy)
      for (int dx = -r_px; dx <= r_px; ++dx)
        if (dx * dx + dy * dy <= r * r) put(int(std::lround(cx)) + dx, int(std::lround(cy)) + dy, c);
  }
  void ring(double cx, double cy, double r, const Rgb& c) {
    for (int k = 0; k < 64; ++k) {
      const double a = k * 2.0 * M_PI / 64.0;
      disc(cx + r * std::cos(a), cy + r * std::sin(a), 1.0, c);
    }
  }
  // a line `width` pixels wide (a disc stamped along it)
  void line(double x0, double y0, double x1, double y1, const Rgb& c, double width = 1.0) {
    const int steps = std::max(1, int(std::ceil(std::hypot(x1 - x0, y1 - y0))));
    for (int k = 0; k <= steps; ++k) {
      const double s = double(k) / steps;
      if (width <= 1.0)
        put(int(std::lround(x0 + s * (x1 - x0))), int(std::lround(y0 + s * (y1 - y0))), c);
      else
        disc(x0 + s * (x1 - x0), y0 + s * (y1 - y0), 0.5 * width, c);
    }
  }
  // a convex polygon, filled
  void polygon(const std::vector<std::array<double, 2>>& p, const Rgb& c) {
    double x_lo = 1e9, x_hi = -1e9, y_lo = 1e9, y_hi = -1e9;
    for (const auto& v : p)
      x_lo = std::min(x_lo, v[0]), x_hi = std::max(x_hi, v[0]), y_lo = std::min(y_lo, v[1]),
      y_hi = std::max(y_hi, v[1]);
    for (int y = int(std::floor(y_lo)); y <= int(std::ceil(y_hi)); ++y)
      for (int x = int(std::floor(x_lo)); x <= int(std::ceil(x_hi)); ++x) {
        // inside: on the same side of every edge, whichever way the corners go round
        bool left = true, right = true;
        for (size_t i = 0; i < p.size(); ++i) {
          const auto& a = p[i];
          const auto& b = p[(i + 1) % p.size()];
          const double cross = (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]);
          left = left && cross >= 0.0, right = right && cross <= 0.0;
        }
        if (left || right) put(x, y, c);
      }
  }
};

// track metres to pixels: the whole run fitted into the map area, north up
struct View {
  double x0 = 0, y0 = 0, scale = 1;
  int w = 0, h = 0;
  std::array<double, 2> px(double x, double y) const {
    return {0.5 * w + (x - x0) * scale, 0.5 * h - (y - y0) * scale};
  }
};

View fit(const RunFolder& run, int w, int h) {
  double x_lo = 1e300, x_hi = -1e300, y_lo = 1e300, y_hi = -1e300;
  auto take = [&](double x, double y) {
    x_lo = std::min(x_lo, x), x_hi = std::max(x_hi, x), y_lo = std::min(y_lo, y),
    y_hi = std::max(y_hi, y);
  };
  for (const tracks::Cone& c : run.track.cones) take(c.position.x(), c.position.y());
  const RunTrajectory& t = run.trajectory;
  for (size_t r = 0; r < t.count; ++r) take(t.rows[r * t.width + 1], t.rows[r * t.width + 2]);
  View v;
  v.w = w, v.h = h;
  v.x0 = 0.5 * (x_lo + x_hi), v.y0 = 0.5 * (y_lo + y_hi);
  const double margin_m = 4.0;
  v.scale = std::min(w / (x_hi - x_lo + 2 * margin_m), h / (y_hi - y_lo + 2 * margin_m));
  return v;
}

// the latest LiDAR sweep of the second before t, null when none (or no replay.bin)
const ReplayLog::Sweep* latest_sweep(const RunFolder& run, double t) {
  const ReplayLog::Sweep* latest = nullptr;
  if (run.log)
    for (const ReplayLog::Sweep& sw : run.log->sweeps)
      if (sw.t_s <= t && sw.t_s > t - 1.0) latest = &sw;
  return latest;
}

// ---- the chase view: a pinhole camera 7 m behind and 3.5 m above the car, looking at the ground
// 5 m ahead of it, 70 degrees across
struct Chase {
  std::array<double, 3> eye{}, fwd{}, right{}, up{};
  double f_px = 1, cx = 0, cy = 0;
  static constexpr double kNear = 0.3;

  Chase(double x, double y, double yaw, int w, int h) {
    const double c = std::cos(yaw), s = std::sin(yaw);
    eye = {x - 7.0 * c, y - 7.0 * s, 3.5};
    const std::array<double, 3> target{x + 5.0 * c, y + 5.0 * s, 0.0};
    fwd = unit({target[0] - eye[0], target[1] - eye[1], target[2] - eye[2]});
    right = unit({fwd[1], -fwd[0], 0.0});  // fwd x (0, 0, 1)
    up = {right[1] * fwd[2] - right[2] * fwd[1], right[2] * fwd[0] - right[0] * fwd[2],
          right[0] * fwd[1] - right[1] * fwd[0]};
    f_px = 0.5 * w / std::tan(35.0 * M_PI / 180.0);
    cx = 0.5 * w, cy = 0.5 * h;
  }
  static std::array<double, 3> unit(const std::array<double, 3>& v) {
    const double n = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    return {v[0] / n, v[1] / n, v[2] / n};
  }
  // depth along the view axis (< kNear: not drawable)
  double depth(double x, double y, double z) const {
    return (x - eye[0]) * fwd[0] + (y - eye[1]) * fwd[1] + (z - eye[2]) * fwd[2];
  }
  std::array<double, 2> px(double x, double y, double z) const {
    const double dx = x - eye[0], dy = y - eye[1], dz = z - eye[2];
    const double d = std::max(kNear, dx * fwd[0] + dy * fwd[1] + dz * fwd[2]);
    return {cx + f_px * (dx * right[0] + dy * right[1] + dz * right[2]) / d,
            cy - f_px * (dx * up[0] + dy * up[1] + dz * up[2]) / d};
  }
  // the image row of the horizon in the direction the car heads
  double horizon(double yaw) const {
    const double hx = std::cos(yaw), hy = std::sin(yaw);
    const double d = hx * fwd[0] + hy * fwd[1];
    return cy - f_px * (hx * up[0] + hy * up[1]) / std::max(1e-6, d);
  }
};

// a cone's size by its class (core::ConeClass order), base width and height, m
std::array<double, 2> cone_size_m(int cls) {
  return cls == 3 ? std::array<double, 2>{0.285, 0.505} : std::array<double, 2>{0.228, 0.325};
}

// ---- the camera view: the recorded frames decoded, scaled into the frame, boxes drawn on them

// a dashed rectangle outline on an RGB image
void dashed_rect(cv::Mat& img, const cv::Point& a, const cv::Point& b, const cv::Scalar& colour) {
  const std::array<std::pair<cv::Point, cv::Point>, 4> edges{
      {{a, {b.x, a.y}}, {{b.x, a.y}, b}, {b, {a.x, b.y}}, {{a.x, b.y}, a}}};
  for (const auto& e : edges) {
    const double len = std::hypot(e.second.x - e.first.x, e.second.y - e.first.y);
    for (double d = 0.0; d < len; d += 8.0) {
      const double s0 = d / std::max(1.0, len), s1 = std::min(1.0, (d + 4.0) / std::max(1.0, len));
      cv::line(img,
               {int(e.first.x + s0 * (e.second.x - e.first.x)),
                int(e.first.y + s0 * (e.second.y - e.first.y))},
               {int(e.first.x + s1 * (e.second.x - e.first.x)),
                int(e.first.y + s1 * (e.second.y - e.first.y))},
               colour, 1, cv::LINE_AA);
    }
  }
}

const char* class_label(int code) {
  static const char* names[] = {"ground", "blue", "yellow", "orange", "big orange", "unknown"};
  return code >= 0 && code <= 5 ? names[code] : "unknown";
}

// draws camera frame `f` of the log (nullptr: none within the last second) into the top `map_h`
// rows of `frame`, scaled to fit and centred
void draw_camera_frame(Canvas& frame, int map_h, const ReplayLog::CameraFrame* f,
                       const fs::path& log_file) {
  cv::Mat out(map_h, frame.w, CV_8UC3, frame.rgb.data());
  if (!f) {
    cv::putText(out, "no camera frame in the last second", {20, map_h / 2},
                cv::FONT_HERSHEY_SIMPLEX, 0.8, {200, 200, 200}, 1, cv::LINE_AA);
    return;
  }
  const cv::Mat bgr = cv::imdecode(
      cv::Mat(1, static_cast<int>(f->jpeg.size()), CV_8UC1, const_cast<char*>(f->jpeg.data())),
      cv::IMREAD_COLOR);
  if (bgr.empty())
    throw core::InputError(
        log_file.string(), 0,
        "a camera frame (at " + std::to_string(f->t_s) + " s) whose JPEG does not decode");
  const double scale = std::min(double(frame.w) / bgr.cols, double(map_h) / bgr.rows);
  const int w = std::max(1, int(bgr.cols * scale)), h = std::max(1, int(bgr.rows * scale));
  const int ox = (frame.w - w) / 2, oy = (map_h - h) / 2;
  cv::Mat scaled, rgb;
  cv::resize(bgr, scaled, cv::Size(w, h), 0, 0, cv::INTER_LINEAR);
  cv::cvtColor(scaled, rgb, cv::COLOR_BGR2RGB);
  rgb.copyTo(out(cv::Rect(ox, oy, w, h)));
  const double sx = double(w) / f->width, sy = double(h) / f->height;
  auto corner = [&](double x, double y) {
    return cv::Point(ox + int(std::lround(x * sx)), oy + int(std::lround(y * sy)));
  };
  char text[96];
  for (const ReplayLog::CameraFrame::Box& b : f->truth) {
    const cv::Point a = corner(b.x0, b.y0), c = corner(b.x1, b.y1);
    dashed_rect(out, a, c, {255, 64, 255});
    if (b.range_m > 12.f) continue;  // far boxes are small and crowd each other
    std::snprintf(text, sizeof(text), "%.1f m", b.range_m);
    cv::putText(out, text, {a.x, c.y + 14}, cv::FONT_HERSHEY_SIMPLEX, 0.4, {255, 64, 255}, 1,
                cv::LINE_AA);
  }
  for (const ReplayLog::CameraFrame::Box& b : f->detected) {
    const Rgb rgb_c = cone_colour(int(b.cls) - 1);
    const cv::Scalar colour(rgb_c[0], rgb_c[1], rgb_c[2]);
    const cv::Point a = corner(b.x0, b.y0), c = corner(b.x1, b.y1);
    cv::rectangle(out, a, c, colour, 2, cv::LINE_AA);
    if (b.range_m > 20.f) continue;
    if (b.id >= 0)
      std::snprintf(text, sizeof(text), "%s #%d %.1f m", class_label(b.cls), b.id, b.range_m);
    else
      std::snprintf(text, sizeof(text), "%s %.1f m", class_label(b.cls), b.range_m);
    cv::putText(out, text, {a.x, a.y - 4}, cv::FONT_HERSHEY_SIMPLEX, 0.45, colour, 1, cv::LINE_AA);
  }
  std::snprintf(text, sizeof(text), "left camera %.2f s: %zu detected (solid), %zu true (dashed)",
                f->t_s, f->detected.size(), f->truth.size());
  cv::putText(out, text, {10, 22}, cv::FONT_HERSHEY_SIMPLEX, 0.55, {255, 255, 255}, 1, cv::LINE_AA);
}

// ffmpeg on PATH (CONESIM_FFMPEG names another); empty when there is none
std::string find_ffmpeg() {
  if (const char* env = std::getenv("CONESIM_FFMPEG"); env && *env)
    return ::access(env, X_OK) == 0 ? env : "";
  const char* path = std::getenv("PATH");
  std::istringstream dirs(path ? path : "/usr/bin:/bin");
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    const fs::path candidate = fs::path(dir.empty() ? "." : dir) / "ffmpeg";
    if (::access(candidate.c_str(), X_OK) == 0) return candidate.string();
  }
  return "";
}

std::string shell_quote(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

}  // namespace

fs::path write_replay_video(const fs::path& run_dir, const VideoSettings& settings) {
  const RunFolder run = read_run_folder(run_dir);
  const fs::path out = run_dir / (settings.view == VideoView::kChase    ? kReplayChaseVideoFile
                                  : settings.view == VideoView::kCamera ? kReplayCameraVideoFile
                                                                        : kReplayVideoFile);
  const fs::path log_file = run_dir / kReplayLogFile;
  if (settings.view == VideoView::kCamera && (!run.log || run.log->camera.empty()))
    throw core::InputError(
        log_file.string(), 0,
        std::string(run.log ? "has no camera frames" : "missing") +
            ": the camera video needs the left camera's frames, which `conesim run --replay` "
            "records when the run has the stereo camera (e.g. autocross-stereo, "
            "autocross-fused); this run's replay.bin " +
            (run.log ? "holds only LiDAR sweeps, detections and maps" : "was never recorded"));
  const std::string ffmpeg = find_ffmpeg();
  if (ffmpeg.empty())
    throw core::InputError(out.string(), 0,
                           "cannot make: ffmpeg is not on PATH (Debian package ffmpeg, which "
                           "./conesim installs; CONESIM_FFMPEG names another)");
  if (settings.fps <= 0.0 || settings.width_px < 64 || settings.height_px < 64 ||
      settings.width_px % 2 || settings.height_px % 2)
    throw core::InputError("--mp4", 0, "expected a positive frame rate and an even size >= 64");

  const RunTrajectory& traj = run.trajectory;
  const size_t w = traj.width;
  auto row = [&](size_t r, size_t c) { return double(traj.rows[r * w + c]); };
  const double t_first = row(0, 0), t_last = row(traj.count - 1, 0);
  const int frames = 1 + static_cast<int>(std::floor((t_last - t_first) * settings.fps + 1e-9));

  const int width = settings.width_px, height = settings.height_px;
  const int map_h = height - kTimelinePx;
  const View view = fit(run, width, map_h);
  const double cone_r = std::max(2.0, 0.25 * view.scale);

  // the referee's events: time, and where when the event says
  struct Event {
    double t;
    bool placed;
    double x, y;
  };
  std::vector<Event> events;
  for (const auto& e : run.metrics["events"]) {
    Event ev{e["t_s"].get<double>(), false, 0.0, 0.0};
    for (const auto& [kx, ky] : {std::pair{"cone_x_m", "cone_y_m"}, {"x_m", "y_m"}})
      if (!ev.placed && e.contains(kx) && e.contains(ky) && e[kx].is_number() &&
          e[ky].is_number())
        ev = {ev.t, true, e[kx].get<double>(), e[ky].get<double>()};
    events.push_back(ev);
  }
  // a knocked cone (a cone_hit event at its place) is drawn hollow from then on
  std::vector<double> knocked_at(run.track.cones.size(), -1.0);
  for (const auto& e : run.metrics["events"]) {
    if (e["kind"] != "cone_hit" || !e.contains("cone_x_m") || !e.contains("cone_y_m")) continue;
    const core::Vec2 at(e["cone_x_m"].get<double>(), e["cone_y_m"].get<double>());
    for (size_t i = 0; i < run.track.cones.size(); ++i)
      if ((run.track.cones[i].position - at).norm() < 0.5 && knocked_at[i] < 0.0)
        knocked_at[i] = e["t_s"].get<double>();
  }

  // ffmpeg reads raw RGB frames on its input and writes a partial file, renamed when it
  // succeeded
  const fs::path partial = run_dir / (".partial-" + out.filename().string());
  std::error_code ec;
  fs::remove(partial, ec);
  char rate[32];
  std::snprintf(rate, sizeof(rate), "%g", settings.fps);
  const std::string command =
      shell_quote(ffmpeg) + " -hide_banner -loglevel error -nostdin -y -f rawvideo -pix_fmt rgb24 -s " +
      std::to_string(width) + "x" + std::to_string(height) + " -r " + rate +
      " -i - -c:v libx264 -preset veryfast -crf 23 -pix_fmt yuv420p -movflags +faststart -f mp4 " +
      shell_quote(partial.string());
  // a write to an ffmpeg that has died must fail, not end this process
  struct sigaction ignore {}, previous {};
  ignore.sa_handler = SIG_IGN;
  sigaction(SIGPIPE, &ignore, &previous);
  FILE* pipe = ::popen(command.c_str(), "w");
  if (!pipe) {
    sigaction(SIGPIPE, &previous, nullptr);
    throw core::InputError(out.string(), 0, "cannot start " + ffmpeg + ": " + std::strerror(errno));
  }

  const vehicle_models::VehicleParams vp;
  // the chase view of time t with the car at (cx_m, cy_m, yaw): sky and ground, the paths so
  // far, the latest LiDAR sweep, the cones far to near (a knocked one as a ring on the ground),
  // the car's body as a box
  auto draw_chase = [&](Canvas& img, int img_h, double t, double cx_m, double cy_m, double yaw) {
    const Chase cam(cx_m, cy_m, yaw, img.w, img_h);
    const int horizon = std::clamp(int(std::lround(cam.horizon(yaw))), 0, img_h);
    img.rect(0, 0, img.w, horizon, kSky);
    img.rect(0, horizon, img.w, img_h, kGround);
    const double longest_px = 2.0 * (img.w + img_h);
    auto visible = [&](double x, double y, double z) {
      const double d = cam.depth(x, y, z);
      return d >= Chase::kNear && d <= 90.0;
    };
    auto path = [&](size_t col_x, size_t col_y, const Rgb& colour, double line_px) {
      bool have = false;
      std::array<double, 2> last{};
      for (size_t r = 0; r < traj.count && row(r, 0) <= t + 1e-9; ++r) {
        const double px_x = row(r, col_x), px_y = row(r, col_y);
        if (!visible(px_x, px_y, 0.02)) {
          have = false;
          continue;
        }
        const auto p = cam.px(px_x, px_y, 0.02);
        if (have && std::hypot(p[0] - last[0], p[1] - last[1]) < longest_px)
          img.line(last[0], last[1], p[0], p[1], colour, line_px);
        last = p, have = true;
      }
    };
    path(5, 6, kEstimatedPath, 1.0);
    path(1, 2, kTruePath, 2.0);
    if (const ReplayLog::Sweep* latest = latest_sweep(run, t))
      for (size_t i = 0; i < latest->intensity.size(); ++i) {
        const double px_x = latest->origin_x + 0.01 * latest->xyz_cm[3 * i];
        const double px_y = latest->origin_y + 0.01 * latest->xyz_cm[3 * i + 1];
        const double px_z = 0.01 * latest->xyz_cm[3 * i + 2];
        if (!visible(px_x, px_y, px_z)) continue;
        const auto p = cam.px(px_x, px_y, px_z);
        img.rect(int(p[0]), int(p[1]), int(p[0]) + 2, int(p[1]) + 2, kLidar);
      }
    std::vector<std::pair<double, size_t>> order;
    for (size_t i = 0; i < run.track.cones.size(); ++i) {
      const core::Vec2& c = run.track.cones[i].position;
      if (visible(c.x(), c.y(), 0.0)) order.emplace_back(cam.depth(c.x(), c.y(), 0.0), i);
    }
    std::sort(order.begin(), order.end(),
              [](const auto& a, const auto& b) { return a.first > b.first; });
    for (const auto& entry : order) {
      const tracks::Cone& c = run.track.cones[entry.second];
      const std::array<double, 2> size = cone_size_m(static_cast<int>(c.cls));
      const auto base = cam.px(c.position.x(), c.position.y(), 0.0);
      const double half_px = cam.f_px * 0.5 * size[0] / entry.first;
      const Rgb colour = cone_colour(static_cast<int>(c.cls));
      const double knocked = knocked_at[entry.second];
      if (knocked >= 0.0 && knocked <= t) {
        img.ring(base[0], base[1], std::max(1.5, half_px), colour);
        continue;
      }
      const auto apex = cam.px(c.position.x(), c.position.y(), size[1]);
      img.polygon({{base[0] - half_px, base[1]}, {base[0] + half_px, base[1]}, apex}, colour);
    }
    // the car's body: a box on the rear-axle pose, its faces far to near
    const double front = vp.front_overhang_from_rear_axle_m, back = front - vp.length_m;
    const double c = std::cos(yaw), sn = std::sin(yaw), half_w = 0.5 * vp.width_m;
    std::array<std::array<double, 3>, 8> corner;
    for (int i = 0; i < 8; ++i) {
      const double lx = (i & 1) ? front : back, ly = (i & 2) ? half_w : -half_w;
      corner[i] = {cx_m + lx * c - ly * sn, cy_m + lx * sn + ly * c, (i & 4) ? 0.6 : 0.05};
    }
    // bottom, top, back, front, right, left; each face's shade
    const std::array<std::array<int, 4>, 6> faces{
        {{0, 1, 3, 2}, {4, 5, 7, 6}, {0, 2, 6, 4}, {1, 3, 7, 5}, {0, 1, 5, 4}, {2, 3, 7, 6}}};
    const std::array<Rgb, 6> shade{
        {{90, 10, 10}, kCar, {160, 20, 20}, {240, 240, 240}, {190, 25, 25}, {190, 25, 25}}};
    std::vector<std::pair<double, int>> face_order;
    for (int f = 0; f < 6; ++f) {
      double d = 0.0;
      bool in_front = true;
      for (int v : faces[f]) {
        d += cam.depth(corner[v][0], corner[v][1], corner[v][2]);
        in_front = in_front && cam.depth(corner[v][0], corner[v][1], corner[v][2]) >= Chase::kNear;
      }
      if (in_front) face_order.emplace_back(d, f);
    }
    std::sort(face_order.begin(), face_order.end(),
              [](const auto& a, const auto& b) { return a.first > b.first; });
    for (const auto& entry : face_order) {
      std::vector<std::array<double, 2>> poly;
      for (int v : faces[entry.second])
        poly.push_back(cam.px(corner[v][0], corner[v][1], corner[v][2]));
      img.polygon(poly, shade[entry.second]);
    }
  };
  size_t next_camera = 0;
  Canvas trail(width, height);
  trail.fill(kBackground);
  Canvas frame(width, height);
  size_t next_row = 0;
  std::array<double, 2> last_true{}, last_est{};
  bool write_failed = false;
  try {
    for (int k = 0; k < frames && !write_failed; ++k) {
      const double t = t_first + k / settings.fps;
      // the paths so far go onto the trail once
      for (; next_row < traj.count && row(next_row, 0) <= t + 1e-9; ++next_row) {
        const auto p = view.px(row(next_row, 1), row(next_row, 2));
        const auto e = view.px(row(next_row, 5), row(next_row, 6));
        if (next_row > 0) {
          trail.line(last_est[0], last_est[1], e[0], e[1], kEstimatedPath, 1.0);
          trail.line(last_true[0], last_true[1], p[0], p[1], kTruePath, 2.0);
        }
        last_true = p, last_est = e;
      }
      // the car's rear-axle pose interpolated at t
      size_t r1 = std::min(next_row, traj.count - 1);
      const size_t r0 = r1 > 0 ? r1 - 1 : 0;
      const double span = row(r1, 0) - row(r0, 0);
      const double s = span > 0.0 ? std::clamp((t - row(r0, 0)) / span, 0.0, 1.0) : 0.0;
      const double x = row(r0, 1) + s * (row(r1, 1) - row(r0, 1));
      const double y = row(r0, 2) + s * (row(r1, 2) - row(r0, 2));
      const double yaw = row(r0, 3) + s * std::remainder(row(r1, 3) - row(r0, 3), 2.0 * M_PI);
      if (settings.view == VideoView::kTop) {
        frame.rgb = trail.rgb;
        // the latest LiDAR sweep of the last second, its points where they hit
        if (const ReplayLog::Sweep* latest = latest_sweep(run, t))
          for (size_t i = 0; i < latest->intensity.size(); ++i) {
            const auto p = view.px(latest->origin_x + 0.01 * latest->xyz_cm[3 * i],
                                   latest->origin_y + 0.01 * latest->xyz_cm[3 * i + 1]);
            frame.put(int(p[0]), int(p[1]), kLidar);
          }
        for (size_t i = 0; i < run.track.cones.size(); ++i) {
          const tracks::Cone& c = run.track.cones[i];
          const auto p = view.px(c.position.x(), c.position.y());
          const double r = c.cls == core::ConeClass::kOrangeBig ? 1.4 * cone_r : cone_r;
          if (knocked_at[i] >= 0.0 && knocked_at[i] <= t)
            frame.ring(p[0], p[1], r, cone_colour(static_cast<int>(c.cls)));
          else
            frame.disc(p[0], p[1], r, cone_colour(static_cast<int>(c.cls)));
        }
        for (const Event& e : events)
          if (e.placed && e.t <= t) {
            const auto p = view.px(e.x, e.y);
            frame.ring(p[0], p[1], std::max(6.0, 0.8 * view.scale), kEvent);
          }
        // the car: its footprint
        const double front = vp.front_overhang_from_rear_axle_m, back = front - vp.length_m;
        std::vector<std::array<double, 2>> box;
        for (const auto& [lx, ly] : {std::pair{back, -0.5 * vp.width_m},
                                     {front, -0.5 * vp.width_m},
                                     {front, 0.5 * vp.width_m},
                                     {back, 0.5 * vp.width_m}})
          box.push_back(view.px(x + lx * std::cos(yaw) - ly * std::sin(yaw),
                                y + lx * std::sin(yaw) + ly * std::cos(yaw)));
        frame.polygon(box, kCar);
        const auto nose = view.px(x + front * std::cos(yaw), y + front * std::sin(yaw));
        frame.disc(nose[0], nose[1], std::max(2.0, 0.2 * view.scale), {255, 255, 255});
      } else if (settings.view == VideoView::kChase) {
        draw_chase(frame, map_h, t, x, y, yaw);
      } else {
        frame.fill(kBackground);
        const ReplayLog::CameraFrame* shown = nullptr;
        while (next_camera < run.log->camera.size() && run.log->camera[next_camera].t_s <= t + 1e-9)
          ++next_camera;
        if (next_camera > 0 && run.log->camera[next_camera - 1].t_s > t - 1.0)
          shown = &run.log->camera[next_camera - 1];
        draw_camera_frame(frame, map_h, shown, log_file);
      }
      // the time line: how far the run is, its events as red ticks
      const double duration = std::max(1e-9, t_last - t_first);
      frame.rect(0, map_h, width, height, kTimelineBack);
      frame.rect(0, map_h + 8, int(width * (t - t_first) / duration), height - 8, kTimelineDone);
      for (const Event& e : events) {
        const int ex = int(width * (e.t - t_first) / duration);
        frame.rect(ex - 1, map_h + 2, ex + 2, height - 2, kEvent);
      }
      write_failed = std::fwrite(frame.rgb.data(), 1, frame.rgb.size(), pipe) != frame.rgb.size();
    }
  } catch (...) {
    // a frame that cannot be drawn (a camera image that does not decode): no video
    ::pclose(pipe);
    sigaction(SIGPIPE, &previous, nullptr);
    fs::remove(partial, ec);
    throw;
  }
  const int status = ::pclose(pipe);
  sigaction(SIGPIPE, &previous, nullptr);
  if (write_failed || status == -1 || !WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    fs::remove(partial, ec);
    throw core::InputError(out.string(), 0,
                           "ffmpeg (" + ffmpeg + ") failed; its message is above, nothing was written");
  }
  fs::rename(partial, out);
  return out;
}

}  // namespace conesim::sim
