#include "sim/track_commands.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <ostream>
#include <sstream>
#include <stdexcept>
#include <tuple>

#include "core/error.hpp"
#include "sim/gnuplot.hpp"
#include "sim/json_text.hpp"
#include "tracks/fsg_layouts.hpp"
#include "tracks/generator.hpp"
#include "tracks/io.hpp"
#include "tracks/rules.hpp"

namespace conesim::sim {

namespace fs = std::filesystem;
using tracks::EventType;
using tracks::Track;

namespace {

// rounds a figure for JSON output (millimetres are plenty for layout figures)
double round_mm(double v) {
  return std::round(v * 1000.0) / 1000.0;
}

}  // namespace

int track_validate(const std::vector<fs::path>& files, std::optional<EventType> event, bool strict,
                   std::ostream& out, std::ostream& err) {
  int status = kExitOk;
  for (const fs::path& file : files) {
    // read: a malformed file is reported and the others are still checked
    Track track;
    try {
      track = tracks::read_track(file);
    } catch (const core::InputError& e) {
      err << e.what() << "\n";
      status = kExitBadInput;
      continue;
    }
    for (const std::string& w : track.warnings) err << file.string() << ": warning: " << w << "\n";

    // check the rules of the event
    const EventType ev = event.value_or(tracks::infer_event(track));
    const auto violations = tracks::check_rules(track, ev);
    out << file.string() << ": " << track.cones.size() << " cones, " << tracks::to_string(ev)
        << ", " << violations.size() << " rule violation" << (violations.size() == 1 ? "" : "s")
        << "\n";
    for (const auto& v : violations) out << file.string() << ": " << v.to_string() << "\n";
    if (strict && !violations.empty() && status == kExitOk) status = kExitViolations;
  }
  return status;
}

nlohmann::json track_info(const Track& track, std::optional<EventType> event) {
  const EventType ev = event.value_or(tracks::infer_event(track));
  const tracks::TrackStats stats = tracks::compute_stats(track);
  nlohmann::json cones = nlohmann::json::object();
  for (core::ConeClass c :
       {core::ConeClass::kBlue, core::ConeClass::kYellow, core::ConeClass::kOrangeSmall,
        core::ConeClass::kOrangeBig, core::ConeClass::kUnknown}) {
    cones[std::string(core::to_string(c))] = track.count(c);
  }
  nlohmann::json violations = nlohmann::json::array();
  for (const auto& v : tracks::check_rules(track, ev)) violations.push_back(v.to_string());
  return {
      {"name", track.name},
      {"event", std::string(tracks::to_string(ev))},
      {"closed", track.closed},
      {"cones", cones},
      {"length_m", round_mm(stats.length_m)},
      {"min_width_m", round_mm(stats.min_width_m)},
      {"max_spacing_m", round_mm(stats.max_spacing_m)},
      {"min_radius_m", round_mm(stats.min_radius_m)},
      {"start",
       {{"x", round_mm(track.start.x)},
        {"y", round_mm(track.start.y)},
        {"yaw", round_mm(track.start.yaw)}}},
      {"violations", violations},
      {"warnings", track.warnings},
  };
}

Track make_event_track(EventType event, uint64_t seed, tracks::GeneratorParams circuit) {
  switch (event) {
    case EventType::kSkidpad:
      return tracks::make_skidpad();
    case EventType::kAcceleration:
      return tracks::make_acceleration();
    case EventType::kAutocross:
    case EventType::kTrackdrive:
      break;
  }
  circuit.event = event;
  return tracks::generate_circuit(seed, circuit);
}

int track_corpus(const CorpusOptions& options, std::ostream& out, std::ostream& err) {
  fs::create_directories(options.out_dir);
  nlohmann::json entries = nlohmann::json::array();
  int status = kExitOk;
  for (int i = 0; i < options.count; ++i) {
    const tracks::GeneratorProfile profile = options.profiles[i % options.profiles.size()];
    const EventType event = options.events[i % options.events.size()];
    const uint64_t seed = options.seed + static_cast<uint64_t>(i);
    const std::string stem = std::string(tracks::to_string(profile)) + "-" +
                             std::string(tracks::to_string(event)) + "-" + std::to_string(seed);

    // generate; a seed without a compliant layout is reported and skipped
    tracks::GeneratorParams params;
    params.event = event;
    params.profile = profile;
    params.direction = options.direction;
    params.hairpin_outer_diameter_m = options.hairpin_outer_diameter_m;
    tracks::GenerationReport report;
    Track track;
    try {
      track = tracks::generate_circuit(seed, params, &report);
    } catch (const std::exception& e) {
      err << stem << ": " << e.what() << "\n";
      status = kExitViolations;
      continue;
    }
    track.name = stem;
    const fs::path file = options.out_dir / (stem + "." + options.format);
    write_track_atomically(track, file);

    // what the index says of it: the rules (strictly), the figures and the bound
    const auto violations = tracks::check_rules(track, event);
    if (!violations.empty()) status = kExitViolations;
    nlohmann::json listed = nlohmann::json::array();
    for (const auto& v : violations) listed.push_back(v.to_string());
    const tracks::TrackStats stats = tracks::compute_stats(track);
    const laptime::LapTimeBound bound = laptime::lap_time_bound(track, options.vehicle);
    entries.push_back({
        {"file", file.filename().string()},
        {"profile", std::string(tracks::to_string(profile))},
        {"event", std::string(tracks::to_string(event))},
        {"seed", seed},
        {"direction", report.clockwise ? "clockwise" : "counter-clockwise"},
        {"cones", track.cones.size()},
        {"length_m", round_mm(stats.length_m)},
        {"min_width_m", round_mm(stats.min_width_m)},
        {"max_spacing_m", round_mm(stats.max_spacing_m)},
        {"hairpins", report.hairpins},
        {"min_hairpin_outer_diameter_m", round_mm(report.min_hairpin_outer_diameter_m)},
        {"chicanes", report.chicanes},
        {"slaloms", report.slaloms},
        {"longest_straight_m", round_mm(report.longest_straight_m)},
        {"attempts", report.attempts},
        {"violations", listed},
        {"lap_time_bound_s",
         bound.usable ? nlohmann::json(round_mm(bound.lap_time_s)) : nlohmann::json(nullptr)},
    });
    out << file.string() << "\n";
  }
  const nlohmann::json index = {{"count", entries.size()},
                                {"seed", options.seed},
                                {"vehicle", options.vehicle.name},
                                {"tracks", entries}};
  const fs::path index_file = options.out_dir / "index.json";
  const fs::path partial = options.out_dir / ".partial-index.json";
  {
    std::ofstream f(partial);
    f << json_text(index, 2) << "\n";
    if (!f) throw std::runtime_error(partial.string() + ": cannot write");
  }
  fs::rename(partial, index_file);
  return status;
}

nlohmann::json lap_time_json(const Track& track, const laptime::LapTimeBound& bound,
                             const vehicle_models::VehicleParams& vehicle, double grip_fraction) {
  nlohmann::json j = {{"track", track.name},
                      {"event", std::string(tracks::to_string(bound.event))},
                      {"vehicle", vehicle.name},
                      {"grip_fraction", grip_fraction}};
  if (!bound.usable) {
    j["lap_time_s"] = nullptr;
    j["message"] = bound.message;
    return j;
  }
  j["lap_time_s"] = round_mm(bound.lap_time_s);
  j["line_length_m"] = round_mm(bound.line_length_m);
  j["top_speed_mps"] = round_mm(bound.top_speed_mps);
  j["min_speed_mps"] = round_mm(bound.min_speed_mps);
  j["mean_speed_mps"] = round_mm(bound.line_length_m / bound.lap_time_s);
  return j;
}

void write_speed_profile_csv(const laptime::LapTimeBound& bound, const fs::path& out) {
  std::ostringstream text;
  text << "s_m,speed_mps,x_m,y_m\n";
  char row[120];
  for (size_t i = 0; i < bound.s_m.size(); ++i) {
    const core::Vec2 p = i < bound.line.size() ? bound.line[i] : core::Vec2::Zero();
    std::snprintf(row, sizeof(row), "%.3f,%.4f,%.4f,%.4f\n", bound.s_m[i], bound.speed_mps[i],
                  p.x(), p.y());
    text << row;
  }
  const fs::path partial = out.parent_path() / (".partial-" + out.filename().string());
  {
    std::ofstream f(partial);
    f << text.str();
    if (!f) throw std::runtime_error(partial.string() + ": cannot write");
  }
  fs::rename(partial, out);
}

void write_track_atomically(const Track& track, const fs::path& out) {
  // same extension, so the writer picks the same format; errors name the target, not the
  // temporary file
  const fs::path partial = out.parent_path() / (".partial-" + out.filename().string());
  std::string ext = out.extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext != ".csv" && ext != ".yaml" && ext != ".yml")
    throw core::InputError(
        out.string(), 0,
        "unknown extension '" + ext + "' for writing (expected .yaml, .yml or .csv)");
  std::error_code ec;
  if (!out.parent_path().empty() && !fs::is_directory(out.parent_path(), ec))
    throw core::InputError(out.string(), 0,
                           "cannot write: no folder " + out.parent_path().string());
  try {
    tracks::write_track(track, partial);
    fs::rename(partial, out);
  } catch (const fs::filesystem_error& e) {
    fs::remove(partial, ec);
    throw core::InputError(out.string(), 0, "cannot write: " + e.code().message());
  } catch (const core::InputError&) {
    fs::remove(partial, ec);
    throw core::InputError(out.string(), 0,
                           "cannot write (the temporary file " + partial.filename().string() +
                               " beside it could not be written)");
  }
}

void plot_track(const Track& track, std::optional<EventType> event, const fs::path& out_png,
                const PlotOverlay* overlay) {
  using core::ConeClass;
  const EventType ev = event.value_or(tracks::infer_event(track));

  // data blocks: cones per class, lanes, centre line, start arrow, gates, violations
  std::vector<PlotData> data;
  const std::pair<ConeClass, const char*> classes[] = {{ConeClass::kBlue, "blue"},
                                                       {ConeClass::kYellow, "yellow"},
                                                       {ConeClass::kOrangeSmall, "orange_small"},
                                                       {ConeClass::kOrangeBig, "orange_big"},
                                                       {ConeClass::kUnknown, "unknown"}};
  std::ostringstream plots;
  const char* colours[] = {"#1f4fd8", "#e6c200", "#ff7f0e", "#d94800", "#808080"};
  int i = 0;
  for (const auto& [cls, name] : classes) {
    PlotData d{name, {}};
    for (const auto& c : track.cones)
      if (c.cls == cls) d.rows.push_back({c.position.x(), c.position.y()});
    if (!d.rows.empty()) {
      plots << (plots.tellp() > 0 ? ", " : "") << "$" << name << " using 1:2 with points pt 7 ps "
            << (cls == ConeClass::kOrangeBig ? 1.6 : 1.0) << " lc rgb '" << colours[i]
            << "' title '" << name << " (" << d.rows.size() << ")'";
      data.push_back(std::move(d));
    }
    ++i;
  }
  auto add_line = [&](const std::string& name, std::vector<core::Vec2> pts, bool closed,
                      const std::string& style, const std::string& title) {
    if (pts.empty()) return;
    if (closed) pts.push_back(pts.front());
    PlotData d{name, {}};
    for (const auto& p : pts) d.rows.push_back({p.x(), p.y()});
    data.push_back(std::move(d));
    plots << (plots.tellp() > 0 ? ", " : "") << "$" << name << " using 1:2 with lines " << style
          << " title '" << title << "'";
  };
  add_line("left_lane", track.lane_points(track.left_lane), track.closed,
           "lw 1 dt 2 lc rgb '#1f4fd8'", "left lane");
  add_line("right_lane", track.lane_points(track.right_lane), track.closed,
           "lw 1 dt 2 lc rgb '#c9a800'", "right lane");
  add_line("centre", track.centre_line, track.closed, "lw 1.5 lc rgb '#404040'", "centre line");

  PlotData gates{"gates", {}};
  for (const auto& g : track.timing_gates)
    gates.rows.push_back(
        {g.left.x(), g.left.y(), g.right.x() - g.left.x(), g.right.y() - g.left.y()});
  if (!gates.rows.empty()) {
    data.push_back(gates);
    plots << ", $gates using 1:2:3:4 with vectors nohead lw 2 lc rgb '#2ca02c' title 'timing gate'";
  }
  const double arrow_m = 4.0;
  data.push_back({"start",
                  {{track.start.x, track.start.y, arrow_m * std::cos(track.start.yaw),
                    arrow_m * std::sin(track.start.yaw)}}});
  plots << ", $start using 1:2:3:4 with vectors filled head lw 3 lc rgb '#000000' title 'start'";

  // a run: the driven path and the knocked cones; a bare track: its rule violations
  if (overlay) {
    // the path in the colour of the speed when the speeds are there, with a colour bar
    const bool by_speed = overlay->driven_speed_mps.size() == overlay->driven_path.size();
    PlotData path{"driven", {}};
    for (size_t k = 0; k < overlay->driven_path.size(); ++k) {
      const auto& p = overlay->driven_path[k];
      path.rows.push_back({p.x(), p.y(), by_speed ? overlay->driven_speed_mps[k] : 0.0});
    }
    if (!path.rows.empty()) {
      data.push_back(path);
      plots << (by_speed ? ", $driven using 1:2:3 with lines lw 3 lc palette title 'driven path "
                           "(colour: speed)'"
                         : ", $driven using 1:2 with lines lw 2 lc rgb '#d62728' title 'driven "
                           "path'");
    }
    PlotData laps{"lap_ends", {}};
    for (const auto& [where, label] : overlay->lap_ends) laps.rows.push_back({where.x(), where.y()});
    if (!laps.rows.empty()) {
      data.push_back(laps);
      plots << ", $lap_ends using 1:2 with points pt 13 ps 2 lc rgb '#008000' title 'lap counted'";
    }
    PlotData knocked{"knocked", {}};
    for (int id : overlay->knocked_cones)
      knocked.rows.push_back({track.cone(id).position.x(), track.cone(id).position.y()});
    if (!knocked.rows.empty()) {
      data.push_back(knocked);
      plots << ", $knocked using 1:2 with points pt 2 ps 3 lw 3 lc rgb '#000000' title '"
            << knocked.rows.size() << " cone" << (knocked.rows.size() == 1 ? "" : "s")
            << " knocked over'";
    }
  }
  // the referee's events: a marker per kind, each with its label beside it
  std::ostringstream labels;
  if (overlay) {
    using Kind = PlotOverlay::Mark::Kind;
    const std::tuple<Kind, const char*, const char*, const char*> kinds[] = {
        {Kind::kOffCourse, "off_course", "pt 9 ps 2.5 lc rgb '#9400d3'", "off-course"},
        {Kind::kDnf, "dnf", "pt 5 ps 3 lc rgb '#e00000'", "DNF"},
        {Kind::kConeHit, "cone_hits", "pt 1 ps 0.1 lc rgb '#000000'", ""}};
    for (const auto& [kind, name, style, title] : kinds) {
      PlotData d{name, {}};
      for (const auto& m : overlay->marks)
        if (m.kind == kind) d.rows.push_back({m.where.x(), m.where.y()});
      if (d.rows.empty()) continue;
      data.push_back(std::move(d));
      plots << ", $" << name << " using 1:2 with points " << style << " title '" << title << "'";
    }
    auto cleaned = [](std::string text) {
      for (char& ch : text)
        if (ch == '"' || ch == '\\') ch = ' ';
      return text;
    };
    std::vector<std::pair<core::Vec2, std::string>> texts;
    for (const auto& m : overlay->marks) texts.push_back({m.where, cleaned(m.label)});
    // the laps end at the same gate: their labels go one under the other in a single text
    const size_t first_lap = texts.size();
    for (const auto& [where, label] : overlay->lap_ends) {
      // a copy to capture: clang before 16 cannot capture a structured binding
      const core::Vec2 at = where;
      auto same_place = std::find_if(texts.begin() + static_cast<std::ptrdiff_t>(first_lap),
                                     texts.end(), [&at](const auto& t) {
                                       return (t.first - at).norm() < 5.0;
                                     });
      if (same_place == texts.end())
        texts.push_back({where, cleaned(label)});
      else
        same_place->second += "\\n" + cleaned(label);
    }
    for (const auto& [where, text] : texts) {
      labels << "set label \"" << text << "\" at " << where.x() << "," << where.y()
             << " offset 1,1 font ',9' tc rgb '#303030' front noenhanced\n";
    }
  }
  const auto violations =
      overlay ? std::vector<tracks::Violation>{} : tracks::check_rules(track, ev);
  PlotData viol{"violations", {}};
  for (const auto& v : violations) viol.rows.push_back({v.where.x(), v.where.y()});
  if (!viol.rows.empty()) {
    data.push_back(viol);
    plots << ", $violations using 1:2 with points pt 6 ps 4 lw 2 lc rgb '#e00000' title '"
          << violations.size() << " rule violation" << (violations.size() == 1 ? "" : "s") << "'";
  }

  // the speed's colour bar, under the legend
  std::string speed_bar = "unset colorbox\n";
  if (overlay && !overlay->driven_path.empty() &&
      overlay->driven_speed_mps.size() == overlay->driven_path.size()) {
    const double top = *std::max_element(overlay->driven_speed_mps.begin(),
                                         overlay->driven_speed_mps.end());
    speed_bar = "set palette defined (0 '#2c1e8c', 0.35 '#1f9e89', 0.7 '#f2c81b', 1 '#d62728')\n"
                "set cbrange [0:" + std::to_string(std::max(1.0, std::ceil(top))) + "]\n"
                "set cblabel 'speed [m/s]'\n"
                "set colorbox vertical user origin screen 0.86, screen 0.08 size screen 0.025, "
                "screen 0.3\n";
  }
  // the figure: equal axis scales, legend outside
  std::ostringstream script;
  // title text goes inside double quotes: drop characters that would end or escape it
  auto clean = [](std::string text) {
    for (char& ch : text)
      if (ch == '"' || ch == '\\') ch = ' ';
    return text;
  };
  script << "set title \"" << clean(track.name) << " (" << tracks::to_string(ev) << ", "
         << track.cones.size() << " cones)"
         << (overlay && !overlay->subtitle.empty() ? "\\n" + clean(overlay->subtitle) : "")
         << "\" noenhanced\n"
         << "set size ratio -1\nset grid\nset key outside right top\n"
         << "set xlabel 'x [m]'\nset ylabel 'y [m]'\n"
         << labels.str() << speed_bar << "plot " << plots.str() << "\n";
  render_png(script.str(), data, out_png);
}

}  // namespace conesim::sim
