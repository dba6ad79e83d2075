#include "sim/json_text.hpp"
#include "sim/report.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace conesim::sim {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// arrays longer than this show their first entries and how many more there are
constexpr size_t kMaxListed = 12;

// a number field of `j`, NaN when absent or not a number
double number(const json& j, const char* key) {
  if (!j.is_object() || !j.contains(key) || !j[key].is_number()) return NAN;
  return j[key].get<double>();
}

std::string text(const json& j, const char* key) {
  if (!j.is_object() || !j.contains(key) || !j[key].is_string()) return "";
  return j[key].get<std::string>();
}

// one table row: a header cell and a value cell (already HTML)
std::string row(const std::string& name, const std::string& value_html) {
  return "<tr><th>" + html_escape(name) + "</th><td>" + value_html + "</td></tr>\n";
}

// an image when the run drew it
std::string image_if_present(const fs::path& dir, const std::string& file) {
  if (!fs::exists(dir / file)) return "";
  return "<img src=\"" + html_escape(file) + "\" width=\"900\" alt=\"" + html_escape(file) +
         "\">\n";
}

std::string with_unit(double v, const std::string& unit) {
  if (!std::isfinite(v)) return "-";
  return human_number(v) + (unit.empty() ? "" : " " + unit);
}

// the verdict: the banner, every pass failure with its threshold, the DNF reason
std::string verdict_section(const json& m) {
  std::ostringstream h;
  const bool passed = m.value("passed", false);
  h << "<div class=\"banner " << (passed ? "pass\">PASSED" : "fail\">FAILED") << "</div>\n";
  const json failures = m.value("pass_failures", json::array());
  if (!failures.empty()) {
    h << "<ul class=\"failures\">\n";
    for (const json& f : failures)
      h << "<li>" << html_escape(f.is_string() ? f.get<std::string>() : json_text(f)) << "</li>\n";
    h << "</ul>\n";
  }
  const std::string dnf = text(m, "dnf_reason");
  if (!dnf.empty()) h << "<p><b>DNF:</b> " << html_escape(dnf) << "</p>\n";
  return h.str();
}

// the run's figures: completion, times, penalties, speed
std::string run_section(const json& m) {
  std::ostringstream h;
  const json penalties = m.value("penalties", json::object());
  h << "<h2>Run</h2>\n<table>\n"
    << row("completed", m.value("completed", false) ? "yes" : "no")
    << row("laps", human_value(m.value("laps", json(0))))
    << row("raw time", with_unit(number(m, "raw_time_s"), "s"))
    << row("cones hit", human_value(penalties.value("cones_hit", json(0))))
    << row("off-course", human_value(penalties.value("off_course", json(0))))
    << row("penalty time", with_unit(number(penalties, "penalty_time_s"), "s"))
    << row("final time", with_unit(number(m, "final_time_s"), "s"));
  const json laps = m.value("lap_times_s", json::array());
  double best = NAN;
  for (const json& l : laps)
    if (l.is_number() && !(l.get<double>() >= best)) best = l.get<double>();
  if (std::isfinite(best)) h << row("best lap", with_unit(best, "s"));
  const double bound = number(m, "lap_time_bound_s");
  if (std::isfinite(bound)) {
    h << row("lap-time bound", with_unit(bound, "s"));
    if (std::isfinite(best) && bound > 0.0)
      h << row("best lap / bound", human_number(best / bound));
  }
  h << row("sim time", with_unit(number(m, "sim_time_s"), "s"))
    << row("wall time", with_unit(number(m, "wall_time_s"), "s"))
    << row("real-time factor", with_unit(number(m, "real_time_factor"), "x"))
    << row("perception", html_escape(text(m.value("perception", json::object()), "mode")))
    << row("SLAM", html_escape(text(m, "slam_driving"))) << "</table>\n";

  // the lap times
  if (!laps.empty()) {
    h << "<h3>Lap times</h3>\n<table>\n<tr><th>lap</th><th>time</th></tr>\n";
    for (size_t i = 0; i < laps.size(); ++i)
      h << "<tr><td>" << i + 1 << "</td><td>"
        << with_unit(laps[i].is_number() ? laps[i].get<double>() : NAN, "s") << "</td></tr>\n";
    h << "</table>\n";
  }
  return h.str();
}

// where each penalty happened
std::string events_section(const json& m) {
  if (!m.contains("events")) return "";
  const json& events = m["events"];
  std::ostringstream h;
  h << "<h2>Penalties and DNF</h2>\n";
  if (!events.is_array() || events.empty()) return h.str() + "<p>none</p>\n";
  h << "<table>\n<tr><th>kind</th><th>time</th><th>lap</th><th>car at (x, y)</th>"
       "<th>penalty</th><th>reason</th></tr>\n";
  for (const json& e : events) {
    std::string place =
        "(" + human_number(number(e, "x_m")) + ", " + human_number(number(e, "y_m")) + ") m";
    if (e.contains("cone_x_m"))
      place += "; cone at (" + human_number(number(e, "cone_x_m")) + ", " +
               human_number(number(e, "cone_y_m")) + ") m";
    std::string reason = text(e, "reason");
    if (e.contains("duration_s"))
      reason += " (" + with_unit(number(e, "duration_s"), "s") + " outside)";
    h << "<tr><td>" << html_escape(text(e, "kind")) << "</td><td>"
      << with_unit(number(e, "t_s"), "s") << "</td><td>" << human_value(e.value("lap", json()))
      << "</td><td>" << html_escape(place) << "</td><td>" << with_unit(number(e, "penalty_s"), "s")
      << "</td><td>" << html_escape(reason) << "</td></tr>\n";
  }
  h << "</table>\n";
  return h.str();
}

// one SLAM backend's figures, its map per class and its pictures
// prefix: the figures' file prefix, slam_ for the driving back-end, slam_<name>_ for a shadow
std::string slam_section(const fs::path& dir, const std::string& name, const json& f,
                         bool driving) {
  std::ostringstream h;
  const std::string prefix = driving ? "slam_" : "slam_" + name + "_";
  h << "<h2>SLAM: " << html_escape(name)
    << (driving ? " (drives the car)" : " (shadow, scored only)") << "</h2>\n";
  if (f.value("ideal_association", false))
    h << "<p><b>Ideal association:</b> this back-end was paired with the cones by the "
         "ground-truth labels, an ablation no car can run; its figures show what the others "
         "lose to association errors.</p>\n";
  h << "<table>\n";
  struct Headline {
    const char* key;
    const char* label;
    const char* unit;
  };
  const Headline headlines[] = {
      {"map_rmse_m", "map RMSE", "m"},
      {"map_rmse_aligned_m", "map RMSE after alignment", "m"},
      {"ate_rmse_m", "trajectory RMSE (ATE)", "m"},
      {"ate_rmse_aligned_m", "trajectory RMSE after alignment", "m"},
      {"yaw_rmse_rad", "heading RMSE", "rad"},
      {"da_correct_fraction", "associations correct", ""},
      {"loop_closures", "loop closures", ""},
      {"false_loop_closures", "false loop closures", ""},
      {"update_ms_median", "update time, median", "ms"},
      {"update_ms_p99", "update time, p99", "ms"},
  };
  for (const Headline& hl : headlines)
    if (f.contains(hl.key)) h << row(hl.label, with_unit(number(f, hl.key), hl.unit));
  // the other figures, rounded
  for (const auto& [key, value] : f.items()) {
    bool shown = key == "by_class";
    for (const Headline& hl : headlines) shown = shown || key == hl.key;
    if (!shown) h << row(key, human_value(value));
  }
  h << "</table>\n";
  if (f.contains("by_class") && f["by_class"].is_object()) {
    h << "<h3>Map per class</h3>\n<table>\n<tr><th>class</th><th>matched</th><th>missed</th>"
         "<th>spurious</th><th>RMSE</th></tr>\n";
    for (const auto& [cls, c] : f["by_class"].items())
      h << "<tr><th>" << html_escape(cls) << "</th><td>" << human_value(c.value("matched", json()))
        << "</td><td>" << human_value(c.value("missed", json())) << "</td><td>"
        << human_value(c.value("spurious", json())) << "</td><td>"
        << with_unit(number(c, "rmse_m"), "m") << "</td></tr>\n";
    h << "</table>\n";
  }
  h << image_if_present(dir, prefix + "map.png") << image_if_present(dir, prefix + "map_error.png")
    << image_if_present(dir, prefix + "trajectory.png")
    << image_if_present(dir, prefix + "error.png");
  return h.str();
}

// raw-data perception: its headline figures and the range bands
std::string perception_section(const fs::path& dir, const json& p) {
  if (!p.is_object() || p.size() <= 1) return "";  // only the mode
  std::ostringstream h;
  h << "<h2>Perception: " << html_escape(text(p, "mode")) << "</h2>\n<table>\n";
  for (const char* key : {"recall_15m", "precision_15m", "colour_accuracy_10m", "recall",
                          "precision", "colour_accuracy", "position_rmse_m", "frames"})
    if (p.contains(key)) h << row(key, human_value(p[key]));
  h << "</table>\n" << image_if_present(dir, "perception_bands.png");
  return h.str();
}

}  // namespace

std::string human_number(double v) {
  if (!std::isfinite(v)) return "-";
  char buf[64];
  if (v == std::round(v) && std::abs(v) < 1e15) {
    std::snprintf(buf, sizeof(buf), "%.0f", v);
  } else {
    const double a = std::abs(v);
    std::snprintf(buf, sizeof(buf), a < 1.0 ? "%.3f" : a < 100.0 ? "%.2f" : "%.1f", v);
  }
  std::string s = buf;
  if (s == "-0") s = "0";
  return s;
}

std::string human_value(const json& v) {
  if (v.is_null()) return "-";
  if (v.is_boolean()) return v.get<bool>() ? "yes" : "no";
  if (v.is_number()) return human_number(v.get<double>());
  if (v.is_string()) return html_escape(v.get<std::string>());
  std::string out;
  size_t n = 0;
  for (const auto& [key, value] : v.items()) {
    if (n == kMaxListed) {
      out += ", ... (" + std::to_string(v.size()) + " in all)";
      break;
    }
    if (n++) out += ", ";
    out += v.is_object() ? html_escape(key) + ": " + human_value(value) : human_value(value);
  }
  return v.is_array() ? "[" + out + "]" : out;
}

std::string html_escape(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

const char* report_css() {
  return "body{font-family:sans-serif;margin:2em}table{border-collapse:collapse;margin:0.5em 0}"
         "td,th{border:1px solid #ccc;padding:3px 8px;text-align:left;vertical-align:top}"
         ".banner{font-size:1.6em;font-weight:bold;padding:0.4em 0.8em;color:#fff;"
         "display:inline-block}.pass{background:#2e7d32}.fail{background:#c62828}"
         ".failures li{color:#c62828}tr.failed td{background:#fdecea}"
         "tr.regressed td{background:#fff4e5}";
}

std::string run_report_html(const fs::path& dir, const json& m) {
  std::ostringstream h;
  const std::string title = text(m, "event") + " on " + text(m, "track") + " (seed " +
                            human_value(m.value("seed", json())) + ")";
  h << "<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>conesim: " << html_escape(title)
    << "</title>\n<style>" << report_css() << "</style></head><body>\n"
    << "<h1>" << html_escape(title) << "</h1>\n<p>scenario " << html_escape(text(m, "scenario"))
    << "</p>\n"
    << verdict_section(m) << run_section(m) << events_section(m)
    << image_if_present(dir, "run.png");
  if (m.contains("slam") && m["slam"].is_object()) {
    // the driving back-end first, then the shadows, then every back-end's map error on one plot
    std::string driving = text(m, "slam_driving");
    if (!m["slam"].contains(driving) && !m["slam"].empty()) driving = m["slam"].begin().key();
    if (m["slam"].contains(driving)) h << slam_section(dir, driving, m["slam"][driving], true);
    for (const auto& [name, figures] : m["slam"].items())
      if (name != driving) h << slam_section(dir, name, figures, false);
    if (m["slam"].size() > 1)
      h << image_if_present(dir, "slam_lanes_map.png") << image_if_present(dir, "slam_lanes.png");
  }
  h << perception_section(dir, m.value("perception", json::object())) << "</body></html>\n";
  return h.str();
}

void write_run_report(const fs::path& dir, const json& metrics) {
  const std::string page = run_report_html(dir, metrics);
  const fs::path partial = dir / ".partial-report.html";
  {
    std::ofstream out(partial, std::ios::binary);
    out << page;
    if (!out) throw std::runtime_error(partial.string() + ": cannot write");
  }
  fs::rename(partial, dir / "report.html");
}

}  // namespace conesim::sim
