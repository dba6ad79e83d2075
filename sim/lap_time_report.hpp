#pragma once
// The lap-time bound in a run's results: lap_time_bound_s and lap_time_ratio in metrics.json,
// and speed.png, the driven speed over distance against the bound's speed profile.

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "core/geometry.hpp"
#include "laptime/lap_time.hpp"

namespace conesim::sim {

/// Speed over distance from the timing line: (s_m, speed_mps) pairs of one lap.
using SpeedSeries = std::vector<std::pair<double, double>>;

/// Adds lap_time_bound_s (null when the layout gives no bound) and lap_time_ratio (the best
/// timed lap over the bound; null without a lap or a bound) to a run's metrics.
void add_lap_time_bound(nlohmann::json& metrics, const laptime::LapTimeBound& bound,
                        const std::vector<double>& lap_times_s);

/// The driven path cut into laps of distance along the bound's line from the timing line (each
/// sample projected onto the line near the last one); samples before the first crossing of the
/// timing line on a circuit are left out.
std::vector<SpeedSeries> driven_laps(const laptime::LapTimeBound& bound,
                                     const std::vector<core::Vec2>& path,
                                     const std::vector<double>& speed_mps, bool closed);

/// Plots the driven laps' speed over distance against the bound's profile (gnuplot).
void plot_speed(const laptime::LapTimeBound& bound, const std::vector<SpeedSeries>& driven,
                const std::string& title, const std::filesystem::path& out_png);

}  // namespace conesim::sim
