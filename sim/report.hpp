#pragma once
// report.html of one run, read from its metrics.json alone: the verdict first (passed, every pass
// failure with its threshold, the DNF reason), then the penalties with their places, the lap
// times, and the SLAM and perception sections where the run has them. Numbers are rounded for
// people; pictures the run drew (run.png, slam_*.png, perception_bands.png) are shown when they
// exist.

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

namespace conesim::sim {

/// A number as a person reads it: integers as they are, others to 3 decimals under 1, 2 under
/// 100 and 1 above; non-finite as "-".
std::string human_number(double v);

/// Any metrics.json value for a table cell: numbers by human_number, booleans as yes/no, arrays
/// and objects as short comma-separated lists. HTML-escaped.
std::string human_value(const nlohmann::json& v);

/// Escapes &, <, >, " for HTML text and attributes.
std::string html_escape(const std::string& text);

/// The style sheet the run report and the regress summary share (inline, no network).
const char* report_css();

/// The page for `metrics` (a run's metrics.json) with pictures looked up in `dir`.
std::string run_report_html(const std::filesystem::path& dir, const nlohmann::json& metrics);

/// Writes `dir`/report.html. Throws std::runtime_error when the file cannot be written.
void write_run_report(const std::filesystem::path& dir, const nlohmann::json& metrics);

}  // namespace conesim::sim
