#include "sim/lap_time_report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "sim/gnuplot.hpp"

namespace conesim::sim {

namespace fs = std::filesystem;

namespace {

// how far along the line the projection of the next sample is searched, metres
constexpr double kSearchWindowM = 40.0;

double round_mm(double v) {
  return std::round(v * 1000.0) / 1000.0;
}

}  // namespace

void add_lap_time_bound(nlohmann::json& metrics, const laptime::LapTimeBound& bound,
                        const std::vector<double>& lap_times_s) {
  if (!bound.usable || !(bound.lap_time_s > 0.0)) {
    metrics["lap_time_bound_s"] = nullptr;
    metrics["lap_time_ratio"] = nullptr;
    return;
  }
  metrics["lap_time_bound_s"] = round_mm(bound.lap_time_s);
  if (lap_times_s.empty()) {
    metrics["lap_time_ratio"] = nullptr;
    return;
  }
  const double best = *std::min_element(lap_times_s.begin(), lap_times_s.end());
  metrics["lap_time_ratio"] = round_mm(best / bound.lap_time_s);
}

std::vector<SpeedSeries> driven_laps(const laptime::LapTimeBound& bound,
                                     const std::vector<core::Vec2>& path,
                                     const std::vector<double>& speed_mps, bool closed) {
  std::vector<SpeedSeries> laps;
  const size_t n = bound.line.size();
  if (n < 2 || path.empty()) return laps;
  const double lap_m = closed ? bound.line_length_m : 0.0;
  const double step = bound.s_m.size() > 1 ? bound.s_m[1] - bound.s_m[0] : 1.0;
  const long window = static_cast<long>(std::ceil(kSearchWindowM / std::max(step, 1e-3)));

  // each sample onto the line: everywhere for the first one, then near the last projection
  long last = -1;
  bool started = !closed;
  SpeedSeries current;
  double previous_s = 0.0;
  for (size_t k = 0; k < path.size() && k < speed_mps.size(); ++k) {
    long best = 0;
    double best_d2 = INFINITY;
    const long from = last < 0 ? 0 : last - window,
               to = last < 0 ? static_cast<long>(n) - 1 : last + window;
    for (long j = from; j <= to; ++j) {
      long i = j;
      if (closed)
        i = ((j % static_cast<long>(n)) + static_cast<long>(n)) % static_cast<long>(n);
      else if (j < 0 || j >= static_cast<long>(n))
        continue;
      const double d2 = (bound.line[i] - path[k]).squaredNorm();
      if (d2 < best_d2) {
        best_d2 = d2;
        best = i;
      }
    }
    last = best;
    const double s = bound.s_m[best];

    // a new lap where the distance wraps round (circuits); the run-up is left out
    if (closed && k > 0 && s < previous_s - 0.5 * lap_m) {
      if (started && !current.empty()) laps.push_back(std::move(current));
      current.clear();
      started = true;
    }
    if (started) current.emplace_back(s, speed_mps[k]);
    previous_s = s;
  }
  if (started && !current.empty()) laps.push_back(std::move(current));
  return laps;
}

void plot_speed(const laptime::LapTimeBound& bound, const std::vector<SpeedSeries>& driven,
                const std::string& title, const fs::path& out_png) {
  std::vector<PlotData> data;
  std::ostringstream plots;
  PlotData b{"bound", {}};
  for (size_t i = 0; i < bound.s_m.size(); ++i)
    b.rows.push_back({bound.s_m[i], bound.speed_mps[i]});
  data.push_back(std::move(b));
  char bound_title[120];
  std::snprintf(bound_title, sizeof(bound_title), "lap-time bound (%.2f s)", bound.lap_time_s);
  plots << "$bound using 1:2 with lines lw 2 lc rgb '#000000' title '" << bound_title << "'";
  for (size_t lap = 0; lap < driven.size(); ++lap) {
    if (driven[lap].empty()) continue;
    const std::string name = "lap" + std::to_string(lap + 1);
    PlotData d{name, {}};
    for (const auto& [s, v] : driven[lap]) d.rows.push_back({s, v});
    data.push_back(std::move(d));
    plots << ", $" << name << " using 1:2 with lines lw 1 title 'lap " << lap + 1 << "'";
  }
  std::string clean = title;
  for (char& ch : clean)
    if (ch == '"' || ch == '\\') ch = ' ';
  std::ostringstream script;
  script << "set title \"" << clean << "\" noenhanced\n"
         << "set grid\nset key outside right top\n"
         << "set xlabel 'distance from the timing line [m]'\nset ylabel 'speed [m/s]'\n"
         << "set yrange [0:*]\n"
         << "plot " << plots.str() << "\n";
  render_png(script.str(), data, out_png, 1400, 700);
}

}  // namespace conesim::sim
