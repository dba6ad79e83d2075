#include "sim/replay_video.hpp"

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <stdexcept>
#include <sys/wait.h>
#include <unistd.h>

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
  const fs::path out = run_dir / kReplayVideoFile;
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
  const fs::path partial = run_dir / (std::string(".partial-") + kReplayVideoFile);
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
  Canvas trail(width, height);
  trail.fill(kBackground);
  Canvas frame(width, height);
  size_t next_row = 0;
  std::array<double, 2> last_true{}, last_est{};
  bool write_failed = false;
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
    frame.rgb = trail.rgb;
    // the latest LiDAR sweep of the last second, its points where they hit
    if (run.log) {
      const ReplayLog::Sweep* latest = nullptr;
      for (const ReplayLog::Sweep& s : run.log->sweeps)
        if (s.t_s <= t && s.t_s > t - 1.0) latest = &s;
      if (latest)
        for (size_t i = 0; i < latest->intensity.size(); ++i) {
          const auto p = view.px(latest->origin_x + 0.01 * latest->xyz_cm[3 * i],
                                 latest->origin_y + 0.01 * latest->xyz_cm[3 * i + 1]);
          frame.put(int(p[0]), int(p[1]), kLidar);
        }
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
    // the car: its footprint on the rear-axle pose interpolated at t
    size_t r1 = std::min(next_row, traj.count - 1);
    const size_t r0 = r1 > 0 ? r1 - 1 : 0;
    const double span = row(r1, 0) - row(r0, 0);
    const double s = span > 0.0 ? std::clamp((t - row(r0, 0)) / span, 0.0, 1.0) : 0.0;
    const double x = row(r0, 1) + s * (row(r1, 1) - row(r0, 1));
    const double y = row(r0, 2) + s * (row(r1, 2) - row(r0, 2));
    const double yaw =
        row(r0, 3) + s * std::remainder(row(r1, 3) - row(r0, 3), 2.0 * M_PI);
    const double front = vp.front_overhang_from_rear_axle_m, back = front - vp.length_m;
    std::vector<std::array<double, 2>> box;
    for (const auto& [lx, ly] : {std::pair{back, -0.5 * vp.width_m}, {front, -0.5 * vp.width_m},
                                 {front, 0.5 * vp.width_m}, {back, 0.5 * vp.width_m}})
      box.push_back(view.px(x + lx * std::cos(yaw) - ly * std::sin(yaw),
                            y + lx * std::sin(yaw) + ly * std::cos(yaw)));
    frame.polygon(box, kCar);
    const auto nose = view.px(x + front * std::cos(yaw), y + front * std::sin(yaw));
    frame.disc(nose[0], nose[1], std::max(2.0, 0.2 * view.scale), {255, 255, 255});
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
