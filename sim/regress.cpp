#include "sim/regress.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cmath>
#include <ctime>
#include <fstream>
#include <limits>
#include <map>
#include <ostream>
#include <set>
#include <sstream>
#include <stdexcept>

#include "conesim_commit.hpp"
#include "core/error.hpp"
#include "core/files.hpp"
#include "sim/interrupt.hpp"
#include "sim/json_text.hpp"
#include "sim/process_pool.hpp"
#include "sim/report.hpp"
#include "sim/run.hpp"
#include "sim/scenario.hpp"
#include "tracks/io.hpp"
#include "tracks/rules.hpp"

namespace conesim::sim {

namespace fs = std::filesystem;
using core::EventType;
using core::InputError;
using nlohmann::json;

namespace {

// the shipped scenarios `conesim regress` runs without arguments, and their seeds: circuits vary
// with the seed, the FSG layouts do not
struct DefaultScenario {
  const char* name;
  std::vector<unsigned long long> seeds;
};
const std::vector<DefaultScenario>& default_scenarios() {
  static const std::vector<DefaultScenario> list = {
      {"skidpad", {1}},
      {"acceleration", {1}},
      {"autocross", {1, 2, 3}},
      {"trackdrive", {1, 2}},
      {"skidpad-graphslam", {1}},
      {"acceleration-graphslam", {1}},
      {"trackdrive-graphslam", {1}},
  };
  return list;
}

// a track the runs drive on, with the event its layout is for
struct PlannedTrack {
  std::string label;
  fs::path file;
  EventType event = EventType::kTrackdrive;
  /// the centre line's length (a closed circuit's lap), for the runs' expected cost
  double length_m = 0.0;
};

double centre_line_length(const tracks::Track& t) {
  double length = 0.0;
  const size_t n = t.centre_line.size();
  for (size_t i = 1; i < n; ++i) length += (t.centre_line[i] - t.centre_line[i - 1]).norm();
  if (t.closed && n > 2) length += (t.centre_line[0] - t.centre_line[n - 1]).norm();
  return length;
}

// a short log whole, its lines joined by " / " (at most 300 characters)
std::string log_text(const fs::path& file) {
  std::ifstream in(file);
  std::string line, all;
  while (std::getline(in, line))
    if (!line.empty()) all += (all.empty() ? "" : " / ") + line;
  return all.size() > 300 ? all.substr(0, 297) + "..." : all;
}

// a scenario may drive a layout made for its event, and autocross may also run on a circuit
bool events_match(EventType scenario, EventType track) {
  return scenario == track ||
         (scenario == EventType::kAutocross && track == EventType::kTrackdrive);
}

// a path without its extension, relative to `base`, with '/' separators
std::string label_of(const fs::path& file, const fs::path& base) {
  fs::path rel = file.lexically_relative(base);
  if (rel.empty() || rel.native().starts_with("..")) rel = file.filename();
  return (rel.parent_path() / rel.stem()).generic_string();
}

bool is_track_file(const fs::path& p) {
  const std::string ext = p.extension().string();
  return ext == ".yaml" || ext == ".yml" || ext == ".csv";
}

// a track of a folder or list: read it to learn its event, or say why it cannot be
std::optional<PlannedTrack> read_planned(const fs::path& file, const std::string& label,
                                         std::vector<SkippedTrack>* skipped) {
  try {
    const tracks::Track t = tracks::read_track(file);
    return PlannedTrack{label, file, tracks::infer_event(t), centre_line_length(t)};
  } catch (const std::exception& e) {
    if (!skipped) throw;
    skipped->push_back({label, e.what()});
    return std::nullopt;
  }
}

// the tracks of --tracks: a folder, a list file or `corpus`
void add_track_set(const std::string& set, std::vector<PlannedTrack>& tracks,
                   std::vector<SkippedTrack>& skipped) {
  const fs::path where = set == "corpus" ? shipped_corpus_dir() : fs::path(set);
  if (core::is_folder(where)) {
    // every track file under the folder, sorted
    std::vector<fs::path> files;
    for (const auto& e : fs::recursive_directory_iterator(where, fs::directory_options::skip_permission_denied))
      if (e.is_regular_file() && is_track_file(e.path())) files.push_back(e.path());
    std::sort(files.begin(), files.end());
    if (files.empty()) throw InputError(set, 0, "no track files (.yaml, .yml, .csv) in the folder");
    for (const fs::path& f : files)
      if (auto t = read_planned(f, label_of(f, where), &skipped)) tracks.push_back(*t);
    return;
  }
  if (!core::is_file(where))
    throw InputError(set, 0, "no such folder or list of tracks (or `corpus`)");
  // a list: one track path a line, relative to the list's folder; # starts a comment
  std::ifstream in(where);
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    line = line.substr(0, line.find('#'));
    while (!line.empty() && std::isspace(static_cast<unsigned char>(line.back()))) line.pop_back();
    const size_t start = line.find_first_not_of(" \t");
    if (start == std::string::npos) continue;
    fs::path file = line.substr(start);
    if (file.is_relative()) file = where.parent_path() / file;
    if (!core::is_file(file))
      throw InputError(where.string(), line_number, "no such track file: " + file.string());
    tracks.push_back(*read_planned(file, label_of(file, where.parent_path()), nullptr));
  }
}

// the generated circuits, written by `conesim track generate` (a profile passes through as is)
void add_generated(const fs::path& self, const RegressOptions& o,
                   std::vector<PlannedTrack>& tracks) {
  if (o.generated <= 0) return;
  const fs::path dir = o.out_dir / "tracks";
  fs::create_directories(dir);
  const std::string kind = o.generated_profile.empty() ? "trackdrive" : o.generated_profile;
  for (int k = 1; k <= o.generated; ++k) {
    const std::string name = kind + "-s" + std::to_string(k);
    const fs::path file = dir / ("generated-" + name + ".csv");
    std::vector<std::string> argv = {self.string(), "track",  "generate",       "--event",
                                     "trackdrive",  "--seed", std::to_string(k)};
    if (!o.generated_profile.empty()) argv.insert(argv.end(), {"--profile", o.generated_profile});
    argv.insert(argv.end(), {"--out", file.string()});
    const fs::path log = dir / ("generated-" + name + ".log");
    int status = 0;
    run_processes({{argv, log}}, 1, nullptr, [&](size_t, int code) { status = code; });
    if (status != 0)
      throw InputError(
          "--generated", 0,
          "`conesim track generate` failed for seed " + std::to_string(k) + ": " + log_text(log));
    fs::remove(log);
    tracks.push_back(*read_planned(file, "generated/" + name, nullptr));
  }
}

// a run's folder name part: no '/' inside
std::string flat(std::string s) {
  std::replace(s.begin(), s.end(), '/', '_');
  return s;
}

double number_or_nan(const json& j, const char* key) {
  if (!j.is_object() || !j.contains(key) || !j[key].is_number()) return NAN;
  return j[key].get<double>();
}

// a run's metrics.json read defensively: a value of another type than conesim writes (an older
// or damaged file) counts as absent, so that one odd file gives a failed row, not a dead regress
std::string text_or_empty(const json& j, const char* key) {
  if (!j.is_object() || !j.contains(key) || !j[key].is_string()) return {};
  return j[key].get<std::string>();
}

double number_or(const json& j, const char* key, double fallback) {
  const double v = number_or_nan(j, key);
  return std::isfinite(v) ? v : fallback;
}

bool flag_or_false(const json& j, const char* key) {
  return j.is_object() && j.contains(key) && j[key].is_boolean() && j[key].get<bool>();
}

int count_or_zero(const json& j, const char* key) {
  const double v = number_or_nan(j, key);
  return std::isfinite(v) && std::abs(v) < 1e9 ? static_cast<int>(v) : 0;
}

json section_or_empty(const json& j, const char* key) {
  if (!j.is_object() || !j.contains(key)) return json::object();
  return j[key];
}

json finite_or_null(double v) {
  return std::isfinite(v) ? json(v) : json(nullptr);
}

// HTML's escaping serves XML attributes and text; XML 1.0 allows no control characters but tab,
// newline and carriage return
std::string xml_escape(std::string text) {
  for (char& c : text)
    if (static_cast<unsigned char>(c) < 0x20 && c != '\t' && c != '\n' && c != '\r') c = ' ';
  return html_escape(text);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::string join(const std::vector<std::string>& parts, const std::string& sep) {
  std::string out;
  for (size_t i = 0; i < parts.size(); ++i) out += (i ? sep : "") + parts[i];
  return out;
}

std::string fixed(double v, int decimals) {
  if (!std::isfinite(v)) return "-";
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, v);
  return buf;
}

// where the penalties happened, one short phrase each
std::string events_text(const RunRow& r) {
  std::vector<std::string> parts;
  for (const RunEvent& e : r.events) {
    if (e.kind == "dnf") continue;  // the DNF reason says it
    parts.push_back(e.kind + " lap " + std::to_string(e.lap) + " t " + fixed(e.t_s, 1) + " s at (" +
                    fixed(e.x_m, 1) + ", " + fixed(e.y_m, 1) + ")" +
                    (e.reason.empty() ? "" : ": " + e.reason));
  }
  return join(parts, "; ");
}

// the commit the binary was built from ("-dirty" with uncommitted changes; empty when the sources
// were not a git checkout), stamped at build time (cmake/commit_stamp.cmake): asking git when the
// run starts would name whatever the checkout holds by then
std::string source_commit() {
  return CONESIM_BUILD_COMMIT;
}

std::string utc_now() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char stamp[32];
  std::strftime(stamp, sizeof(stamp), "%Y-%m-%dT%H:%M:%SZ", &utc);
  return stamp;
}

}  // namespace

std::string RegressionRun::id() const {
  return scenario + " | " + (track_label.empty() ? "scenario track" : track_label) + " | seed " +
         std::to_string(seed);
}

std::string Shard::text() const { return std::to_string(index) + "/" + std::to_string(count); }

Shard parse_shard(const std::string& text, const std::string& option) {
  auto bad = [&](const std::string& why) {
    return InputError(option, 0,
                      "expected I/N, shard I of N with 1 <= I <= N (e.g. 2/4), got '" + text +
                          "'" + (why.empty() ? "" : ": " + why));
  };
  const size_t slash = text.find('/');
  if (slash == std::string::npos) throw bad("");
  auto number = [&](const std::string& s) {
    if (s.empty() || s.size() > 6 || s.find_first_not_of("0123456789") != std::string::npos)
      throw bad("");
    return std::stoi(s);
  };
  Shard shard{number(text.substr(0, slash)), number(text.substr(slash + 1))};
  if (shard.count < 1) throw bad("N must be at least 1");
  if (shard.index < 1) throw bad("shards count from 1");
  if (shard.index > shard.count) throw bad("there are only " + std::to_string(shard.count) + " shards");
  return shard;
}

double run_cost(EventType event, double lap_length_m, bool slam_driving, int slam_shadows,
                bool raw_perception, int trackdrive_laps, bool plot) {
  // per event: laps, the usual lap, and the cost of a lap of 300 m against one trackdrive lap
  // (exploring at autocross speed costs more per metre; skidpad and acceleration are short)
  double laps = 1.0, usual_m = 300.0, per_lap = 1.0;
  switch (event) {
    case EventType::kAcceleration: usual_m = 75.0; per_lap = kAccelerationPer300m; break;
    case EventType::kSkidpad: laps = 4.0; usual_m = 60.0; per_lap = kSkidpadPer300m; break;
    case EventType::kAutocross: per_lap = kAutocrossPer300m; break;
    case EventType::kTrackdrive: laps = trackdrive_laps > 0 ? trackdrive_laps : 10.0; break;
  }
  const double length = lap_length_m > 1.0 ? lap_length_m : usual_m;
  double cost = laps * length / 300.0 * per_lap * (slam_driving ? 1.5 : 1.0) + 0.5 * slam_shadows;
  if (raw_perception) cost *= 3.0;
  // what every run costs besides driving: its process, its track, its outputs (run.png)
  cost += kRunStartCost + (plot ? kRunPlotCost : 0.0);
  return std::max(0.001, std::round(cost * 1000.0) / 1000.0);
}

std::vector<std::vector<size_t>> shard_runs(const std::vector<double>& costs, int count) {
  if (count < 1) throw std::invalid_argument("shard_runs: count must be at least 1");
  std::vector<size_t> order(costs.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return costs[a] > costs[b]; });
  std::vector<std::vector<size_t>> shards(static_cast<size_t>(count));
  std::vector<double> load(shards.size(), 0.0);
  for (size_t i : order) {
    const size_t k =
        static_cast<size_t>(std::min_element(load.begin(), load.end()) - load.begin());
    shards[k].push_back(i);
    load[k] += costs[i];
  }
  for (auto& s : shards) std::sort(s.begin(), s.end());
  return shards;
}

double scenario_run_cost(const Scenario& s, double lap_length_m, bool plot) {
  const bool raw = s.perception == "lidar" || s.perception == "stereo" || s.perception == "fused";
  return run_cost(s.event, lap_length_m, s.slam != "none", static_cast<int>(s.slam_shadows.size()),
                  raw, s.driver.trackdrive_laps, plot);
}

double scenario_lap_length_m(const fs::path& scenario_file, const std::vector<std::string>& sets,
                             unsigned long long seed) {
  try {
    // as `conesim run SCENARIO --seed SEED` loads it: a generated circuit follows the seed
    const Scenario s = load_scenario(scenario_file, sets, seed);
    if (s.event == EventType::kSkidpad || s.event == EventType::kAcceleration) return 0.0;
    return centre_line_length(scenario_track(s));
  } catch (const std::exception&) {
    return 0.0;  // the run says why it cannot drive
  }
}

double track_lap_length_m(const fs::path& file) {
  return centre_line_length(tracks::read_track(file));
}

std::vector<int> shard_of_runs(const std::vector<double>& costs, int count) {
  std::vector<int> shard(costs.size(), 0);
  const auto shards = shard_runs(costs, count);
  for (size_t k = 0; k < shards.size(); ++k)
    for (size_t i : shards[k]) shard[i] = static_cast<int>(k) + 1;
  return shard;
}

std::vector<size_t> select_runs(const std::vector<std::string>& ids,
                                const std::vector<double>& costs, const Shard& shard,
                                const std::vector<std::string>& only_ids,
                                const std::string& what) {
  std::vector<size_t> picked;
  if (!only_ids.empty()) {
    const std::set<std::string> known(ids.begin(), ids.end());
    for (const std::string& id : only_ids)
      if (!known.count(id))
        throw InputError("--only-missing", 0,
                         "the run '" + id + "' is not in this run list: give the " + what +
                             " the shards were given");
    const std::set<std::string> wanted(only_ids.begin(), only_ids.end());
    for (size_t i = 0; i < ids.size(); ++i)
      if (wanted.count(ids[i])) picked.push_back(i);
    return picked;
  }
  if (!shard.active()) {
    for (size_t i = 0; i < ids.size(); ++i) picked.push_back(i);
    return picked;
  }
  return shard_runs(costs, shard.count)[static_cast<size_t>(shard.index - 1)];
}

void print_shard_scaling(const std::vector<double>& costs, std::ostream& out) {
  double total = 0.0;
  for (double c : costs) total += c;
  out << "expected cost by shards (the costliest shard sets the wall time; a perfect split is "
         "total / shards):\n  shards  costliest  total/shards  of perfect  runs in it\n";
  for (int n : {1, 2, 4, 8, 16, 32}) {
    double worst = 0.0;
    size_t runs = 0;
    for (const auto& s : shard_runs(costs, n)) {
      double c = 0.0;
      for (size_t i : s) c += costs[i];
      if (c > worst || (c == worst && s.size() > runs)) {
        worst = c;
        runs = s.size();
      }
    }
    char line[128];
    std::snprintf(line, sizeof(line), "  %6d  %9.1f  %12.1f  %9.0f%%  %10zu\n", n, worst, total / n,
                  worst > 0 ? 100.0 * total / n / worst : 100.0, runs);
    out << line;
  }
}

std::vector<unsigned long long> parse_seeds(const std::string& text) {
  std::vector<unsigned long long> seeds;
  std::stringstream in(text);
  std::string part;
  auto bad = [&] {
    return InputError("--seeds", 0,
                      "expected seeds like 1,2,3 or 1-5 (or a mix: 1-3,7), got '" + text + "'");
  };
  auto number = [&](const std::string& s) {
    if (s.empty() || s.find_first_not_of("0123456789") != std::string::npos) throw bad();
    return std::stoull(s);
  };
  while (std::getline(in, part, ',')) {
    const size_t dash = part.find('-');
    if (dash == std::string::npos) {
      seeds.push_back(number(part));
      continue;
    }
    const unsigned long long from = number(part.substr(0, dash));
    const unsigned long long to = number(part.substr(dash + 1));
    if (to < from || to - from > 100000) throw bad();
    for (unsigned long long s = from; s <= to; ++s) seeds.push_back(s);
  }
  if (seeds.empty()) throw bad();
  return seeds;
}

fs::path shipped_corpus_dir() {
  if (const char* env = std::getenv("CONESIM_CORPUS")) return env;
#ifdef CONESIM_SOURCE_DIR
  return fs::path(CONESIM_SOURCE_DIR) / "tests" / "data" / "tracks";
#else
  return "tests/data/tracks";
#endif
}

RegressionPlan plan_regression(const fs::path& self, const RegressOptions& o) {
  RegressionPlan plan;
  // the scenarios and overrides first: a typo stops here, before tracks are made
  const std::vector<std::string> check =
      o.scenarios.empty()
          ? std::vector<std::string>{"skidpad", "acceleration", "autocross", "trackdrive"}
          : o.scenarios;
  for (const std::string& name : check) load_scenario(find_scenario(name), o.sets);

  // the tracks, read now so that a bad one stops everything before any run
  std::vector<PlannedTrack> tracks;
  for (const fs::path& f : o.track_files) {
    if (!core::is_file(f)) throw InputError(f.string(), 0, "no such track file");
    tracks.push_back(*read_planned(f, label_of(f, f.parent_path()), nullptr));
  }
  for (const std::string& set : o.track_sets) add_track_set(set, tracks, plan.skipped);
  add_generated(self, o, tracks);
  const bool on_given_tracks = !o.track_files.empty() || !o.track_sets.empty() || o.generated > 0;
  if (on_given_tracks && tracks.empty())
    throw InputError("--tracks", 0, "not one readable track to run on");
  // labels name the run folders: the same label twice gets a number
  std::map<std::string, int> label_count;
  for (PlannedTrack& t : tracks)
    if (const int n = ++label_count[t.label]; n > 1) t.label += "-" + std::to_string(n);

  // the scenarios: as given, or the defaults (on given tracks: each track's own event)
  std::vector<std::string> names = o.scenarios;
  if (names.empty()) {
    if (on_given_tracks) {
      std::set<EventType> events;
      for (const PlannedTrack& t : tracks) events.insert(t.event);
      for (const char* n : {"skidpad", "acceleration", "autocross", "trackdrive"})
        if (events.count(*core::event_from_string(n))) names.push_back(n);
    } else {
      for (const DefaultScenario& d : default_scenarios()) names.push_back(d.name);
    }
  }

  for (const std::string& name : names) {
    // every scenario loads with the overrides: a typo stops here, not in every run
    const Scenario s = load_scenario(find_scenario(name), o.sets);
    const std::string stem = fs::path(name).stem().string();
    auto cost = [&](double length_m) { return scenario_run_cost(s, length_m, o.plot); };
    std::vector<unsigned long long> seeds = o.seeds;
    if (seeds.empty()) {
      seeds = {1};
      if (!on_given_tracks)
        for (const DefaultScenario& d : default_scenarios())
          if (stem == d.name) seeds = d.seeds;
    }
    if (!on_given_tracks) {
      for (unsigned long long seed : seeds)
        plan.runs.push_back({stem, "", "", seed, stem + "-s" + std::to_string(seed),
                             cost(scenario_lap_length_m(find_scenario(name), o.sets, seed))});
      continue;
    }
    // without scenarios named, each track runs its own event only
    for (const PlannedTrack& t : tracks) {
      const bool match = o.scenarios.empty() ? s.event == t.event : events_match(s.event, t.event);
      if (!match) {
        ++plan.event_mismatches;
        continue;
      }
      for (unsigned long long seed : seeds)
        plan.runs.push_back({stem, t.label, t.file, seed,
                             fs::path(stem) / (flat(t.label) + "-s" + std::to_string(seed)),
                             cost(t.length_m)});
    }
  }
  if (plan.runs.empty())
    throw InputError("regress", 0,
                     "nothing to run: no scenario's event matches a track's (" +
                         std::to_string(plan.event_mismatches) + " pairs left out)");
  return plan;
}

// what `conesim run` says when its pre-run check refuses a layout
constexpr const char* kNotDrivable = "not drivable by this car";

// a row's verdict as the summaries spell it
const char* verdict_name(const RunRow& r) {
  return r.passed ? "pass" : r.refused ? "refused" : "fail";
}

RunRow make_row(const RegressionRun& run, const json& m, int exit_code,
                const std::string& log_tail) {
  RunRow r;
  r.id = run.id();
  r.scenario = run.scenario;
  r.track = run.track_label;
  r.seed = run.seed;
  r.dir = run.dir.generic_string();
  r.exit_code = exit_code;
  if (!m.is_object()) {
    // no metrics.json: the run stopped before its verdict
    r.reasons.push_back(
        "no metrics.json: exit " + std::to_string(exit_code) +
        (exit_code > 128 ? " (signal " + std::to_string(exit_code - 128) + ")" : "") +
        (log_tail.empty() ? "" : ": " + log_tail));
    r.refused = log_tail.find(kNotDrivable) != std::string::npos;
    return r;
  }
  if (r.track.empty()) r.track = text_or_empty(m, "track");
  r.event = text_or_empty(m, "event");
  r.passed = flag_or_false(m, "passed") && exit_code == 0;
  for (const json& f : section_or_empty(m, "pass_failures"))
    r.reasons.push_back(f.is_string() ? f.get<std::string>() : json_text(f));
  if (flag_or_false(m, "passed") && exit_code != 0)
    r.reasons.push_back("exit " + std::to_string(exit_code) +
                        (log_tail.empty() ? "" : ": " + log_tail));
  r.dnf_reason = text_or_empty(m, "dnf_reason");
  const json penalties = section_or_empty(m, "penalties");
  r.cones_hit = count_or_zero(penalties, "cones_hit");
  r.off_course = count_or_zero(penalties, "off_course");
  for (const json& e : section_or_empty(m, "events")) {
    if (!e.is_object()) continue;
    RunEvent ev;
    ev.kind = text_or_empty(e, "kind");
    ev.t_s = number_or(e, "t_s", 0.0);
    ev.lap = count_or_zero(e, "lap");
    ev.x_m = number_or(e, "x_m", 0.0);
    ev.y_m = number_or(e, "y_m", 0.0);
    ev.penalty_s = number_or(e, "penalty_s", 0.0);
    ev.reason = text_or_empty(e, "reason");
    r.events.push_back(ev);
  }
  r.laps = count_or_zero(m, "laps");
  for (const json& l : section_or_empty(m, "lap_times_s"))
    if (l.is_number() && !(l.get<double>() >= r.best_lap_s)) r.best_lap_s = l.get<double>();
  // a DNF has no final time (metrics.json gives 0)
  if (flag_or_false(m, "completed")) r.final_time_s = number_or_nan(m, "final_time_s");
  r.lap_time_bound_s = number_or_nan(m, "lap_time_bound_s");
  if (std::isfinite(r.best_lap_s) && r.lap_time_bound_s > 0.0)
    r.bound_ratio = r.best_lap_s / r.lap_time_bound_s;
  // the driving SLAM back-end's figures (shadow back-ends are beside it under slam)
  if (m.contains("slam") && m["slam"].is_object() && !m["slam"].empty()) {
    const std::string driving = text_or_empty(m, "slam_driving");
    const json& f = m["slam"].contains(driving) ? m["slam"][driving] : m["slam"].begin().value();
    r.map_rmse_m = number_or_nan(f, "map_rmse_m");
    r.ate_rmse_m = number_or_nan(f, "ate_rmse_m");
    r.da_correct_fraction = number_or_nan(f, "da_correct_fraction");
  }
  // raw-data perception: within 15 m, where the driver looks
  const json p = section_or_empty(m, "perception");
  r.perception_recall = number_or_nan(p, p.contains("recall_15m") ? "recall_15m" : "recall");
  r.perception_precision =
      number_or_nan(p, p.contains("precision_15m") ? "precision_15m" : "precision");
  r.wall_time_s = number_or_nan(m, "wall_time_s");
  r.real_time_factor = number_or_nan(m, "real_time_factor");
  return r;
}

json row_to_json(const RunRow& r) {
  json events = json::array();
  for (const RunEvent& e : r.events)
    events.push_back({{"kind", e.kind},
                      {"t_s", e.t_s},
                      {"lap", e.lap},
                      {"x_m", e.x_m},
                      {"y_m", e.y_m},
                      {"penalty_s", e.penalty_s},
                      {"reason", e.reason}});
  return {{"id", r.id},
          {"scenario", r.scenario},
          {"track", r.track},
          {"seed", r.seed},
          {"dir", r.dir},
          {"verdict", verdict_name(r)},
          {"reasons", r.reasons},
          {"dnf_reason", r.dnf_reason},
          {"exit_code", r.exit_code},
          {"event", r.event},
          {"cones_hit", r.cones_hit},
          {"off_course", r.off_course},
          {"events", events},
          {"laps", r.laps},
          {"best_lap_s", finite_or_null(r.best_lap_s)},
          {"final_time_s", finite_or_null(r.final_time_s)},
          {"lap_time_bound_s", finite_or_null(r.lap_time_bound_s)},
          {"lap_time_bound_ratio", finite_or_null(r.bound_ratio)},
          {"slam_map_rmse_m", finite_or_null(r.map_rmse_m)},
          {"slam_ate_rmse_m", finite_or_null(r.ate_rmse_m)},
          {"slam_da_correct_fraction", finite_or_null(r.da_correct_fraction)},
          {"perception_recall", finite_or_null(r.perception_recall)},
          {"perception_precision", finite_or_null(r.perception_precision)},
          {"wall_time_s", finite_or_null(r.wall_time_s)},
          {"real_time_factor", finite_or_null(r.real_time_factor)},
          {"regressions", r.regressions}};
}

// a field of a stored summary that is not what conesim writes there; parse_baseline names the
// file and the run
struct BadField : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// a whole number in [lo, hi] (a summary's counts, seeds, exit codes); a fraction, a number out
// of range or another type is named rather than cast (a cast of 4e97 to int is undefined)
long long whole_or(const json& j, const char* key, long long fallback, long long lo,
                   long long hi) {
  if (!j.is_object() || !j.contains(key) || j[key].is_null()) return fallback;
  const json& v = j[key];
  if (v.is_number_integer()) {
    if (v.is_number_unsigned() ? v.get<unsigned long long>() <= static_cast<unsigned long long>(hi)
                               : v.get<long long>() >= lo && v.get<long long>() <= hi)
      return v.get<long long>();
  } else if (v.is_number_float()) {
    const double d = v.get<double>();
    if (std::isfinite(d) && d == std::floor(d) && d >= static_cast<double>(lo) &&
        d <= static_cast<double>(hi))
      return static_cast<long long>(d);
  }
  throw BadField(std::string(key) + ": expected a whole number from " + std::to_string(lo) +
                 " to " + std::to_string(hi) + ", found " + v.dump());
}

RunRow row_from_json(const json& j) {
  constexpr long long kCount = 1'000'000'000;
  auto num = [&](const char* key) { return number_or_nan(j, key); };
  RunRow r;
  r.id = j.value("id", std::string());
  r.scenario = j.value("scenario", std::string());
  r.track = j.value("track", std::string());
  r.seed = static_cast<unsigned long long>(
      whole_or(j, "seed", 1, 0, std::numeric_limits<long long>::max()));
  r.dir = j.value("dir", std::string());
  r.passed = j.value("verdict", std::string()) == "pass";
  r.refused = j.value("verdict", std::string()) == "refused";
  r.reasons = j.value("reasons", std::vector<std::string>());
  r.dnf_reason = j.value("dnf_reason", std::string());
  r.exit_code = static_cast<int>(whole_or(j, "exit_code", 0, -kCount, kCount));
  r.event = j.value("event", std::string());
  r.cones_hit = static_cast<int>(whole_or(j, "cones_hit", 0, 0, kCount));
  r.off_course = static_cast<int>(whole_or(j, "off_course", 0, 0, kCount));
  for (const json& e : j.value("events", json::array()))
    r.events.push_back({e.value("kind", std::string()), e.value("t_s", 0.0), static_cast<int>(whole_or(e, "lap", 0, 0, kCount)),
                        e.value("x_m", 0.0), e.value("y_m", 0.0), e.value("penalty_s", 0.0),
                        e.value("reason", std::string())});
  r.laps = static_cast<int>(whole_or(j, "laps", 0, 0, kCount));
  r.best_lap_s = num("best_lap_s");
  r.final_time_s = num("final_time_s");
  r.lap_time_bound_s = num("lap_time_bound_s");
  r.bound_ratio = num("lap_time_bound_ratio");
  r.map_rmse_m = num("slam_map_rmse_m");
  r.ate_rmse_m = num("slam_ate_rmse_m");
  r.da_correct_fraction = num("slam_da_correct_fraction");
  r.perception_recall = num("perception_recall");
  r.perception_precision = num("perception_precision");
  r.wall_time_s = num("wall_time_s");
  r.real_time_factor = num("real_time_factor");
  r.regressions = j.value("regressions", std::vector<std::string>());
  return r;
}

void sort_failures_first(std::vector<RunRow>& rows) {
  std::stable_sort(rows.begin(), rows.end(), [](const RunRow& a, const RunRow& b) {
    // failures, regressions, refusals, then the runs that passed
    auto rank = [](const RunRow& r) {
      return r.passed ? (r.regressions.empty() ? 3 : 1) : r.refused ? 2 : 0;
    };
    const int ra = rank(a);
    const int rb = rank(b);
    return ra < rb;
  });
}

BaselineComparison compare_to_baseline(std::vector<RunRow>& rows,
                                       const std::vector<RunRow>& baseline,
                                       const BaselineNoise& noise) {
  BaselineComparison c;
  std::map<std::string, const RunRow*> before;
  for (const RunRow& b : baseline) before[b.id] = &b;
  std::set<std::string> now;
  for (RunRow& r : rows) {
    now.insert(r.id);
    const auto it = before.find(r.id);
    if (it == before.end()) {
      c.added.push_back(r.id);
      continue;
    }
    const RunRow& b = *it->second;
    std::vector<std::string>& found = r.regressions;
    found.clear();
    if (b.passed && !r.passed)
      found.push_back("passed in the baseline, fails now" +
                      (r.reasons.empty() ? "" : ": " + join(r.reasons, "; ")));
    // a figure worse than before by more than the noise; both must be known
    auto worse = [&](const char* what, double was, double is, double allowed, const char* unit) {
      if (!std::isfinite(was) || !std::isfinite(is) || is - was <= allowed) return;
      found.push_back(std::string(what) + " " + human_number(was) + " -> " + human_number(is) +
                      " " + unit + " (noise " + human_number(allowed) + " " + unit + ")");
    };
    auto time_noise = [&](double was) {
      return std::max(noise.time_relative * was, noise.time_absolute_s);
    };
    auto rmse_noise = [&](double was) {
      return std::max(noise.rmse_relative * was, noise.rmse_absolute_m);
    };
    worse("best lap", b.best_lap_s, r.best_lap_s, time_noise(b.best_lap_s), "s");
    // summaries before DNF rows had no final time gave 0 for it: no time to compare with
    if (b.final_time_s > 0.0)
      worse("final time", b.final_time_s, r.final_time_s, time_noise(b.final_time_s), "s");
    worse("cones hit", b.cones_hit, r.cones_hit, 0.0, "");
    worse("off-course", b.off_course, r.off_course, 0.0, "");
    worse("SLAM map RMSE", b.map_rmse_m, r.map_rmse_m, rmse_noise(b.map_rmse_m), "m");
    worse("SLAM trajectory RMSE", b.ate_rmse_m, r.ate_rmse_m, rmse_noise(b.ate_rmse_m), "m");
    // fractions: lower is worse
    worse("SLAM associations wrong (1 - correct fraction)", 1.0 - b.da_correct_fraction,
          1.0 - r.da_correct_fraction, noise.association_fraction_absolute, "");
    worse("perception misses (1 - recall)", 1.0 - b.perception_recall, 1.0 - r.perception_recall,
          noise.fraction_absolute, "");
    worse("perception false detections (1 - precision)", 1.0 - b.perception_precision,
          1.0 - r.perception_precision, noise.fraction_absolute, "");
    for (const std::string& f : found) c.regressions.push_back(r.id + ": " + f);
  }
  for (const RunRow& b : baseline)
    if (!now.count(b.id)) c.missing.push_back(b.id);

  // per scenario, the median SLAM figures over the runs both summaries have
  std::map<std::string, std::vector<std::pair<const RunRow*, const RunRow*>>> pairs;
  for (const RunRow& r : rows)
    if (const auto it = before.find(r.id); it != before.end())
      pairs[r.scenario].push_back({it->second, &r});
  for (const auto& entry : pairs) {
    // named, not bound: clang 14 cannot capture structured bindings in a lambda
    const std::string& scenario = entry.first;
    const auto& list = entry.second;
    auto median_worse = [&](const char* what, double RunRow::*figure) {
      std::vector<double> was, is;
      for (const auto& [b, r] : list)
        if (std::isfinite(b->*figure) && std::isfinite(r->*figure)) {
          was.push_back(b->*figure);
          is.push_back(r->*figure);
        }
      if (static_cast<int>(was.size()) < noise.median_min_runs) return;
      const double m0 = median(was), m1 = median(is);
      const double allowed =
          std::max(noise.median_rmse_relative * m0, noise.median_rmse_absolute_m);
      if (m1 - m0 <= allowed) return;
      const std::string text = scenario + ": median " + what + " over " +
                               std::to_string(was.size()) + " runs " + human_number(m0) + " -> " +
                               human_number(m1) + " m (noise " + human_number(allowed) + " m)";
      c.median_regressions.push_back(text);
      c.regressions.push_back(text);
    };
    median_worse("SLAM map RMSE", &RunRow::map_rmse_m);
    median_worse("SLAM trajectory RMSE", &RunRow::ate_rmse_m);
  }
  return c;
}

std::string describe_noise(const BaselineNoise& n) {
  char buf[1200];
  std::snprintf(buf, sizeof(buf),
                "A run that passed in the baseline and fails now is a regression. So is a figure "
                "worse than the baseline's by more than its noise: best lap and final time by "
                "more than max(%.0f %%, %.1f s); SLAM map and trajectory RMSE by more than "
                "max(%.0f %%, %.2f m) in a run, or their median over a scenario's runs (%d or "
                "more) by more than max(%.0f %%, %.3f m); the fraction of correct SLAM "
                "associations lower by more "
                "than %.3f; perception recall or precision lower by more than %.2f; any more cones "
                "hit or off-course "
                "(a penalty is never noise). Runs are deterministic per seed on one build; the "
                "noise is what a different machine, compiler or library build changes.",
                n.time_relative * 100.0, n.time_absolute_s, n.rmse_relative * 100.0,
                n.rmse_absolute_m, n.median_min_runs, n.median_rmse_relative * 100.0,
                n.median_rmse_absolute_m, n.association_fraction_absolute, n.fraction_absolute);
  return buf;
}

json summary_json(const std::vector<RunRow>& rows, const RegressionPlan& plan,
                  const RegressOptions& o, double wall_s, const BaselineComparison* comparison) {
  const BaselineNoise n;
  int passed = 0, regressed = 0, refused = 0;
  json runs = json::array();
  for (const RunRow& r : rows) {
    passed += r.passed;
    refused += r.refused;
    regressed += !r.regressions.empty();
    runs.push_back(row_to_json(r));
  }
  json skipped = json::array();
  for (const SkippedTrack& s : plan.skipped)
    skipped.push_back({{"track", s.track}, {"reason", s.reason}});
  json baseline = nullptr;
  if (comparison)
    baseline = {{"file", o.baseline ? o.baseline->string() : ""},
                {"regressions", comparison->regressions},
                {"missing", comparison->missing},
                {"added", comparison->added}};
  return {{"tool", "conesim regress"},
          {"version", CONESIM_VERSION},
          {"commit", source_commit()},
          {"command", o.command_line},
          {"finished_utc", utc_now()},
          {"jobs", o.jobs},
          {"wall_time_s", std::round(wall_s * 10.0) / 10.0},
          {"totals",
           {{"runs", rows.size()},
            {"passed", passed},
            {"failed", static_cast<int>(rows.size()) - passed - refused},
            {"refused", refused},
            {"regressed", regressed},
            {"skipped_tracks", plan.skipped.size()},
            {"event_mismatches_left_out", plan.event_mismatches}}},
          {"noise", describe_noise()},
          {"noise_thresholds",
           {{"time_relative", n.time_relative},
            {"time_absolute_s", n.time_absolute_s},
            {"rmse_relative", n.rmse_relative},
            {"rmse_absolute_m", n.rmse_absolute_m},
            {"median_rmse_relative", n.median_rmse_relative},
            {"median_rmse_absolute_m", n.median_rmse_absolute_m},
            {"median_min_runs", n.median_min_runs},
            {"association_fraction_absolute", n.association_fraction_absolute},
            {"perception_fraction_absolute", n.fraction_absolute}}},
          {"baseline", baseline},
          {"skipped_tracks", skipped},
          {"runs", runs}};
}

std::string junit_xml(const std::vector<RunRow>& rows, double wall_s,
                      const BaselineComparison* comparison,
                      const std::vector<std::string>* missing) {
  int failures = 0;
  int skipped = 0;
  for (const RunRow& r : rows) {
    failures += (!r.passed && !r.refused) || !r.regressions.empty();
    skipped += r.refused && r.regressions.empty();
  }
  const bool medians_regressed = comparison && !comparison->median_regressions.empty();
  failures += medians_regressed;
  const size_t n_missing = missing ? missing->size() : 0;
  failures += static_cast<int>(n_missing);
  const size_t tests = rows.size() + (comparison ? 1 : 0) + n_missing;
  std::ostringstream x;
  x << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
    << "<testsuites name=\"conesim regress\" tests=\"" << tests << "\" failures=\"" << failures
    << "\" errors=\"0\" time=\"" << fixed(wall_s, 3) << "\">\n"
    << "  <testsuite name=\"conesim regress\" tests=\"" << tests << "\" failures=\"" << failures
    << "\" errors=\"0\" skipped=\"" << skipped << "\" time=\"" << fixed(wall_s, 3)
    << "\" timestamp=\"" << utc_now().substr(0, 19) << "\">\n";
  for (const RunRow& r : rows) {
    const std::string track = r.track.empty() ? "scenario track" : r.track;
    x << "    <testcase classname=\"" << xml_escape(r.scenario) << "\" name=\""
      << xml_escape(track + " seed " + std::to_string(r.seed)) << "\" time=\""
      << fixed(std::isfinite(r.wall_time_s) ? r.wall_time_s : 0.0, 3) << "\"";
    if (r.passed && r.regressions.empty()) {
      x << "/>\n";
      continue;
    }
    if (r.refused && r.regressions.empty()) {
      x << ">\n      <skipped message=\"" << xml_escape(join(r.reasons, "; ")) << "\"/>\n"
        << "    </testcase>\n";
      continue;
    }
    std::vector<std::string> why = r.passed ? std::vector<std::string>{} : r.reasons;
    for (const std::string& g : r.regressions) why.push_back("regression: " + g);
    if (why.empty()) why.push_back("failed");
    x << ">\n      <failure type=\"" << (r.passed ? "regression" : "fail") << "\" message=\""
      << xml_escape(join(why, "; ")) << "\">" << xml_escape(join(why, "\n"));
    const std::string where = events_text(r);
    if (!where.empty()) x << xml_escape("\npenalties: " + where);
    if (!r.dnf_reason.empty()) x << xml_escape("\nDNF: " + r.dnf_reason);
    x << xml_escape("\nrun folder: " + r.dir) << "</failure>\n    </testcase>\n";
  }
  for (size_t k = 0; k < n_missing; ++k)
    x << "    <testcase classname=\"missing\" name=\"" << xml_escape((*missing)[k])
      << "\" time=\"0\">\n      <failure type=\"missing\" message=\"no result: its shard "
         "wrote no summary\">"
      << xml_escape((*missing)[k]) << ": no result: its shard wrote no summary</failure>\n"
      << "    </testcase>\n";
  if (comparison) {
    x << "    <testcase classname=\"baseline\" name=\"medians\" time=\"0\"";
    if (medians_regressed) {
      const std::string why = join(comparison->median_regressions, "; ");
      x << ">\n      <failure type=\"regression\" message=\"" << xml_escape(why) << "\">"
        << xml_escape(join(comparison->median_regressions, "\n"))
        << "</failure>\n    </testcase>\n";
    } else {
      x << "/>\n";
    }
  }
  x << "  </testsuite>\n</testsuites>\n";
  return x.str();
}

std::string summary_html(const std::vector<RunRow>& rows, const RegressionPlan& plan,
                         const RegressOptions& o, double wall_s,
                         const BaselineComparison* comparison,
                         const std::vector<std::string>* missing,
                         const std::map<std::string, std::string>* run_folders) {
  int passed = 0, refused = 0;
  for (const RunRow& r : rows) {
    passed += r.passed;
    refused += r.refused;
  }
  const bool all_good = passed + refused == static_cast<int>(rows.size()) &&
                        (!comparison || comparison->regressions.empty()) &&
                        (!missing || missing->empty());
  std::ostringstream h;
  h << "<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>conesim regress</title>\n"
    << "<style>" << report_css() << "</style></head><body>\n<h1>conesim regress</h1>\n"
    << "<div class=\"banner " << (all_good ? "pass" : "fail") << "\">" << passed << " of "
    << rows.size() << " passed"
    << (refused ? ", " + std::to_string(refused) + " refused (not drivable by this car)" : "")
    << (comparison ? ", " + std::to_string(comparison->regressions.size()) + " regressions" : "")
    << (missing && !missing->empty() ? ", " + std::to_string(missing->size()) + " missing" : "")
    << "</div>\n<p><code>" << html_escape(o.command_line) << "</code><br>" << fixed(wall_s, 0)
    << " s wall time with " << o.jobs << " jobs, conesim " << CONESIM_VERSION << "</p>\n";
  if (missing && !missing->empty()) {
    h << "<h2>Runs missing (" << missing->size()
      << "): their shard wrote no summary</h2>\n<ul>\n";
    for (const std::string& m : *missing) h << "<li>" << html_escape(m) << "</li>\n";
    h << "</ul>\n";
  }
  if (!plan.skipped.empty()) {
    h << "<h2>Tracks skipped</h2>\n<ul>\n";
    for (const SkippedTrack& s : plan.skipped)
      h << "<li>" << html_escape(s.track) << ": " << html_escape(s.reason) << "</li>\n";
    h << "</ul>\n";
  }
  if (comparison) {
    h << "<h2>Against the baseline " << html_escape(o.baseline ? o.baseline->string() : "")
      << "</h2>\n<p>" << html_escape(describe_noise()) << "</p>\n";
    auto list = [&](const char* title, const std::vector<std::string>& items) {
      if (items.empty()) return;
      h << "<h3>" << title << " (" << items.size() << ")</h3>\n<ul>\n";
      for (const std::string& i : items) h << "<li>" << html_escape(i) << "</li>\n";
      h << "</ul>\n";
    };
    list("Regressions", comparison->regressions);
    list("Runs in the baseline not run now", comparison->missing);
    list("Runs not in the baseline", comparison->added);
    if (comparison->regressions.empty()) h << "<p>No regression.</p>\n";
  }
  h << "<h2>Runs</h2>\n<table>\n<tr><th>verdict</th><th>scenario</th><th>track</th><th>seed</th>"
       "<th>reason</th><th>penalties (where)</th><th>laps</th><th>best lap [s]</th>"
       "<th>final [s]</th><th>best lap / bound</th><th>map RMSE [m]</th><th>ATE [m]</th>"
       "<th>DA correct</th><th>recall</th><th>precision</th><th>wall [s]</th><th>RTF</th>"
       "<th>report</th></tr>\n";
  for (const RunRow& r : rows) {
    const bool regressed = !r.regressions.empty();
    std::vector<std::string> why = r.passed ? std::vector<std::string>{} : r.reasons;
    for (const std::string& g : r.regressions) why.push_back("regression: " + g);
    std::string penalties =
        std::to_string(r.cones_hit) + " hit, " + std::to_string(r.off_course) + " off";
    const std::string where = events_text(r);
    if (!where.empty()) penalties += ": " + where;
    fs::path report = fs::path(r.dir) / "report.html";
    if (run_folders)
      if (const auto it = run_folders->find(r.id); it != run_folders->end())
        report = fs::path(it->second) / "report.html";
    h << "<tr"
      << (r.refused   ? " class=\"regressed\""
          : !r.passed ? " class=\"failed\""
          : regressed ? " class=\"regressed\""
                      : "")
      << "><td>"
      << (r.passed    ? (regressed ? "pass (regressed)" : "pass")
          : r.refused ? "refused"
                      : "<b>FAIL</b>")
      << "</td><td>" << html_escape(r.scenario) << "</td><td>"
      << html_escape(r.track.empty() ? "scenario track" : r.track) << "</td><td>" << r.seed
      << "</td><td>" << html_escape(join(why, "; ")) << "</td><td>" << html_escape(penalties)
      << "</td><td>" << r.laps << "</td><td>" << fixed(r.best_lap_s, 2) << "</td><td>"
      << fixed(r.final_time_s, 2) << "</td><td>" << fixed(r.bound_ratio, 3) << "</td><td>"
      << fixed(r.map_rmse_m, 3) << "</td><td>" << fixed(r.ate_rmse_m, 3) << "</td><td>"
      << fixed(r.da_correct_fraction, 3) << "</td><td>" << fixed(r.perception_recall, 3)
      << "</td><td>" << fixed(r.perception_precision, 3) << "</td><td>" << fixed(r.wall_time_s, 1)
      << "</td><td>" << fixed(r.real_time_factor, 0) << "</td><td>";
    if (core::path_exists(o.out_dir / report))
      h << "<a href=\"" << html_escape(report.generic_string()) << "\">report</a>";
    h << "</td></tr>\n";
  }
  h << "</table>\n</body></html>\n";
  return h.str();
}

void print_table(const std::vector<RunRow>& rows, std::ostream& out) {
  // widths from the content, so long track names line up
  std::vector<std::vector<std::string>> cells = {{"verdict", "scenario", "track", "seed", "laps",
                                                  "best_lap", "final_s", "hit", "off", "map_rmse",
                                                  "rtf"}};
  for (const RunRow& r : rows)
    cells.push_back({r.passed    ? (r.regressions.empty() ? "ok" : "REGRESSED")
                     : r.refused ? "refused"
                                 : "FAIL",
                     r.scenario, r.track.empty() ? "-" : r.track, std::to_string(r.seed),
                     std::to_string(r.laps), fixed(r.best_lap_s, 2), fixed(r.final_time_s, 2),
                     std::to_string(r.cones_hit), std::to_string(r.off_course),
                     fixed(r.map_rmse_m, 3), fixed(r.real_time_factor, 0) + "x"});
  std::vector<size_t> widths(cells[0].size(), 0);
  for (const auto& c : cells)
    for (size_t i = 0; i < c.size(); ++i) widths[i] = std::max(widths[i], c[i].size());
  for (size_t k = 0; k < cells.size(); ++k) {
    std::string line;
    for (size_t i = 0; i < cells[k].size(); ++i) {
      std::string c = cells[k][i];
      c.resize(std::max(widths[i], c.size()), ' ');
      line += (i ? "  " : "") + c;
    }
    while (!line.empty() && line.back() == ' ') line.pop_back();
    out << line << "\n";
    if (k == 0) continue;
    // why, under the row
    const RunRow& r = rows[k - 1];
    if (!r.passed)
      for (const std::string& why : r.reasons) out << "    " << why << "\n";
    const std::string where = events_text(r);
    if (!r.passed && !where.empty()) out << "    penalties: " << where << "\n";
    for (const std::string& g : r.regressions) out << "    regression: " << g << "\n";
  }
}

std::vector<RunRow> parse_baseline(const std::string& text, const std::string& name) {
  std::vector<RunRow> rows;
  try {
    const json b = json::parse(text);
    const json& runs = b.at("runs");
    if (!runs.is_array()) throw BadField("runs: expected a list of runs, found " + runs.dump());
    for (size_t k = 0; k < runs.size(); ++k) {
      try {
        rows.push_back(row_from_json(runs[k]));
      } catch (const BadField& e) {
        throw BadField("runs[" + std::to_string(k) + "]." + e.what());
      }
    }
  } catch (const BadField& e) {
    throw InputError(name, 0, std::string("not a conesim regress summary.json: ") + e.what());
  } catch (const json::exception& e) {
    throw InputError(name, 0, std::string("not a conesim regress summary.json: ") + e.what());
  }
  return rows;
}

std::vector<RegressionRun> selected_runs(const RegressionPlan& plan, const RegressOptions& o) {
  std::vector<std::string> ids;
  std::vector<double> costs;
  for (const RegressionRun& r : plan.runs) {
    ids.push_back(r.id());
    costs.push_back(r.cost);
  }
  std::vector<RegressionRun> runs;
  for (size_t i : select_runs(ids, costs, o.shard, o.only_ids,
                              "scenarios, tracks, seeds and --set values"))
    runs.push_back(plan.runs[i]);
  return runs;
}

json shard_plan_json(const std::string& tool, const fs::path& self,
                     const std::vector<std::string>& args, const std::vector<std::string>& ids,
                     const std::vector<std::string>& dirs, const std::vector<double>& costs,
                     const Shard& shard, const std::vector<size_t>& selected, int jobs) {
  const std::vector<int> shard_of =
      shard.active() ? shard_of_runs(costs, shard.count) : std::vector<int>(ids.size(), 0);
  json runs = json::array();
  for (size_t i = 0; i < ids.size(); ++i) {
    json r = {{"id", ids[i]}, {"dir", dirs[i]}, {"cost", costs[i]}};
    if (shard.active()) r["shard"] = shard_of[i];
    runs.push_back(r);
  }
  json picked = json::array();
  for (size_t i : selected) picked.push_back(ids[i]);
  return {{"tool", tool},
          {"version", CONESIM_VERSION},
          {"binary", self.string()},
          {"args", args},
          {"shard", shard.active() ? json{{"index", shard.index}, {"count", shard.count}}
                                   : json(nullptr)},
          {"jobs", jobs},
          {"selected", picked},
          {"runs", runs}};
}

namespace {

// plan.json: the whole run list (each run's shard), how this call was made, what it runs
json plan_json(const fs::path& self, const RegressionPlan& plan, const RegressOptions& o) {
  std::vector<std::string> ids, dirs;
  std::vector<double> costs;
  for (const RegressionRun& r : plan.runs) {
    ids.push_back(r.id());
    dirs.push_back(r.dir.generic_string());
    costs.push_back(r.cost);
  }
  const std::vector<size_t> selected =
      select_runs(ids, costs, o.shard, o.only_ids, "scenarios, tracks, seeds and --set values");
  json p = shard_plan_json("conesim regress plan", self, o.args, ids, dirs, costs, o.shard,
                           selected, o.jobs);
  json skipped = json::array();
  for (const SkippedTrack& s : plan.skipped)
    skipped.push_back({{"track", s.track}, {"reason", s.reason}});
  p["baseline"] = o.baseline ? json(fs::absolute(*o.baseline).string()) : json(nullptr);
  p["event_mismatches_left_out"] = plan.event_mismatches;
  p["skipped_tracks"] = skipped;
  return p;
}

}  // namespace

namespace {

// a merge's additions to the summaries: runs with no result, where each run's folder is, and
// summary.json's `shards`
struct MergeParts {
  const std::vector<std::string>* missing = nullptr;
  const std::map<std::string, std::string>* run_folders = nullptr;
  json shards;
  /// the commit the shards' runs were built from (not the merging checkout's)
  std::optional<std::string> commit;
};

// the verdicts against the baseline, the three summaries and the table; the exit status
int write_summaries(std::vector<RunRow>& rows, const RegressionPlan& plan, const RegressOptions& o,
                    double wall_s, const std::vector<RunRow>* baseline, const MergeParts& merge,
                    std::ostream& out) {
  std::optional<BaselineComparison> comparison;
  if (baseline) comparison = compare_to_baseline(rows, *baseline);
  sort_failures_first(rows);
  const BaselineComparison* c = comparison ? &*comparison : nullptr;
  json summary = summary_json(rows, plan, o, wall_s, c);
  if (!merge.shards.is_null()) summary["shards"] = merge.shards;
  if (merge.commit) summary["commit"] = *merge.commit;
  std::ofstream(o.out_dir / "summary.json") << json_text(summary, 2) << "\n";
  std::ofstream(o.out_dir / "junit.xml") << junit_xml(rows, wall_s, c, merge.missing);
  std::ofstream(o.out_dir / "summary.html")
      << summary_html(rows, plan, o, wall_s, c, merge.missing, merge.run_folders);
  print_table(rows, out);
  int failed = 0, refused = 0;
  for (const RunRow& r : rows) {
    failed += !r.passed && !r.refused;
    refused += r.refused;
  }
  const size_t missing = merge.missing ? merge.missing->size() : 0;
  out << rows.size() - failed - refused << " passed, " << failed << " failed";
  if (refused) out << ", " << refused << " refused (not drivable by this car)";
  if (missing) out << ", " << missing << " missing";
  if (c)
    out << ", " << c->regressions.size() << " regressions, " << c->missing.size()
        << " baseline runs missing, " << c->added.size() << " new";
  out << " (" << fixed(wall_s, 0) << " s)\n";
  if (c)
    for (const std::string& m : c->missing) out << "missing: " << m << "\n";
  return failed == 0 && missing == 0 && (!c || c->regressions.empty()) ? 0 : 1;
}

}  // namespace

int run_regression(const fs::path& self, const RegressOptions& o, std::ostream& out,
                   std::ostream& progress) {
  using clock = std::chrono::steady_clock;
  const auto start = clock::now();

  // the baseline is read first: a bad one stops everything before any run
  std::vector<RunRow> baseline;
  if (o.baseline) {
    std::ifstream in(*o.baseline, std::ios::binary);
    if (!in) throw InputError(o.baseline->string(), 0, "cannot read the baseline summary");
    const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    baseline = parse_baseline(text, o.baseline->string());
  }
  fs::create_directories(o.out_dir);
  check_output_writable(o.out_dir);
  const RegressionPlan plan = plan_regression(self, o);
  for (const SkippedTrack& s : plan.skipped)
    progress << "skipped track " << s.track << ": " << s.reason << "\n";
  // a shard or a rerun runs its part of the list; plan.json names the whole list for the merge
  const std::vector<RegressionRun> runs = selected_runs(plan, o);
  if (o.shard.active() || !o.only_ids.empty()) {
    std::ofstream(o.out_dir / "plan.json") << json_text(plan_json(self, plan, o), 1) << "\n";
    progress << (o.shard.active() ? "shard " + o.shard.text() : std::string("rerun")) << ": "
             << runs.size() << " of " << plan.runs.size() << " runs; ";
  }
  progress << runs.size() << " runs, " << o.jobs << " at once, into " << o.out_dir.string();
  if (plan.event_mismatches > 0)
    progress << " (" << plan.event_mismatches << " scenario-track pairs left out: events differ)";
  progress << "\n";

  // run them, at most `jobs` at once, each a `conesim run` process logging into its folder
  std::vector<int> exit_codes(runs.size(), -1);
  std::vector<RunRow> rows(runs.size());
  size_t done_count = 0;
  std::vector<ProcessJob> jobs;
  for (const RegressionRun& r : runs) {
    const fs::path dir = o.out_dir / r.dir;
    std::vector<std::string> argv = {self.string(),          "run",   r.scenario,  "--seed",
                                     std::to_string(r.seed), "--out", dir.string()};
    if (!r.track_file.empty()) argv.insert(argv.end(), {"--track", r.track_file.string()});
    for (const std::string& s : o.sets) argv.insert(argv.end(), {"--set", s});
    if (!o.plot) argv.push_back("--no-plot");
    // a scenario given as a file runs from that file
    for (const std::string& given : o.scenarios)
      if (fs::path(given).stem() == r.scenario && core::is_file(given)) argv[2] = given;
    jobs.push_back({argv, dir / "log.txt"});
  }
  // the runs' command lines in runs.json: --resume continues only the same runs
  json planned = json::array();
  for (const ProcessJob& j : jobs) planned.push_back(j.argv);
  const fs::path runs_file = o.out_dir / "runs.json";
  if (o.resume) {
    json before;
    std::ifstream in(runs_file);
    try {
      if (in) in >> before;
    } catch (const std::exception&) {
      before = json();
    }
    if (before != planned)
      throw InputError(
          "--resume", 0,
          !in ? runs_file.string() + " not found: --out must be the folder of an earlier regress"
              : o.out_dir.string() +
                    " holds the runs of another command (runs.json differs): resume with the "
                    "same scenarios, tracks, seeds and --set values");
  }
  std::ofstream(runs_file) << json_text(planned, 1) << "\n";

  // a run's metrics.json, or null when it has none (or only a broken one)
  const auto read_metrics = [&](size_t i) {
    json m;
    std::ifstream in(o.out_dir / runs[i].dir / "metrics.json");
    if (in) {
      try {
        in >> m;
      } catch (const std::exception&) {
        m = json();
      }
    }
    return m.is_object() ? m : json();
  };
  const auto take_in = [&](size_t i, int exit_code, const json& m) {
    exit_codes[i] = exit_code;
    const std::string tail =
        m.is_object() ? "" : last_log_line(o.out_dir / runs[i].dir / "log.txt");
    rows[i] = make_row(runs[i], m, exit_codes[i], tail);
    ++done_count;
    progress << "[" << done_count << "/" << runs.size() << "] " << runs[i].id() << ": "
             << (rows[i].passed    ? "pass"
                 : rows[i].refused ? "refused"
                                   : "FAIL")
             << "\n";
  };

  // with --resume, a run that finished before is read (its exit status from its verdict, as
  // `conesim run` gives it), the others run
  std::vector<ProcessJob> to_run;
  std::vector<size_t> job_run;
  size_t reused = 0;
  for (size_t i = 0; i < runs.size(); ++i) {
    if (o.resume) {
      if (const json m = read_metrics(i); m.is_object()) {
        take_in(i, m.value("passed", false) ? 0 : 1, m);
        ++reused;
        continue;
      }
    }
    to_run.push_back(jobs[i]);
    job_run.push_back(i);
  }
  if (reused > 0) progress << reused << " runs reused from " << o.out_dir.string() << "\n";
  run_processes(
      to_run, o.jobs, [&](size_t k) { fs::create_directories(o.out_dir / runs[job_run[k]].dir); },
      [&](size_t k, int exit_code) { take_in(job_run[k], exit_code, read_metrics(job_run[k])); });
  const double wall_s = std::chrono::duration<double>(clock::now() - start).count();

  // interrupted: no summary (it would look complete); the finished runs stay for --resume
  if (const int signal = interrupt_signal()) {
    progress << "interrupted by " << signal_name(signal) << ": " << done_count << " of "
             << runs.size()
             << " runs finished; no summary written. Continue with: conesim regress ... --out "
             << o.out_dir.string() << " --resume\n";
    return interrupted_exit_status(signal);
  }

  return write_summaries(rows, plan, o, wall_s, o.baseline ? &baseline : nullptr, {}, out);
}

namespace {

// a whole file's text; core::InputError naming `what` when it cannot be read
std::string read_whole(const fs::path& file, const std::string& what) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(file.string(), 0, "cannot read " + what);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}


// the regress arguments of a shard without what makes it that shard (--shard, --out, --resume,
// --only-missing): the same run list, whole
std::vector<std::string> study_args(const std::vector<std::string>& args) {
  return without_options(args, {"--shard", "--out", "--only-missing", "--jobs", "-j"},
                         {"--resume", "--reuse", "--list"});
}

}  // namespace

json read_json_file(const fs::path& file, const std::string& what) {
  try {
    return json::parse(read_whole(file, what));
  } catch (const json::exception& e) {
    throw InputError(file.string(), 0, "not " + what + ": " + e.what());
  }
}

std::vector<std::string> plan_run_ids(const json& plan, const fs::path& file) {
  std::vector<std::string> ids;
  try {
    for (const json& r : plan.at("runs")) ids.push_back(r.at("id").get<std::string>());
  } catch (const json::exception& e) {
    throw InputError(file.string(), 0, std::string("not a conesim plan.json: ") + e.what());
  }
  return ids;
}

std::string rerun_command(const json& plan, const std::string& command, const fs::path& merge_dir) {
  std::vector<std::string> words = {plan.value("binary", std::string("conesim")), command};
  for (const std::string& a : study_args(plan.value("args", std::vector<std::string>())))
    words.push_back(a);
  words.push_back("--only-missing");
  words.push_back(fs::absolute(merge_dir).lexically_normal().string());
  std::string line;
  for (const std::string& w : words) {
    if (!line.empty()) line += ' ';
    line += shell_word(w);
  }
  return line;
}

std::string shell_word(const std::string& w) {
  if (!w.empty() && w.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                        "0123456789-_./=:,+@%") == std::string::npos)
    return w;
  std::string q = "'";
  for (char c : w) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

std::vector<std::string> without_options(const std::vector<std::string>& args,
                                         const std::set<std::string>& with_value,
                                         const std::set<std::string>& flags) {
  std::vector<std::string> kept;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    const std::string name = a.substr(0, a.find('='));
    if (flags.count(a)) continue;
    if (with_value.count(name)) {
      if (name == a) ++i;  // the value is the next word
      continue;
    }
    kept.push_back(a);
  }
  return kept;
}

json summary_without_timing(json j) {
  if (!j.is_object()) return j;
  for (const char* key : {"command", "finished_utc", "wall_time_s", "jobs", "shards"}) j.erase(key);
  if (j.contains("runs") && j["runs"].is_array())
    for (json& r : j["runs"])
      if (r.is_object()) {
        r.erase("wall_time_s");
        r.erase("real_time_factor");
      }
  return j;
}

std::vector<std::string> summary_differences(const json& a, const json& b, size_t limit) {
  return json_differences(summary_without_timing(a), summary_without_timing(b), limit);
}

std::vector<std::string> json_differences(const json& a, const json& b, size_t limit) {
  std::vector<std::string> found;
  const json patch = json::diff(a, b);
  for (const json& op : patch) {
    if (found.size() >= limit) {
      found.push_back("... (" + std::to_string(patch.size() - limit) + " more)");
      break;
    }
    const std::string path = op.value("path", std::string());
    const std::string verb = op.value("op", std::string());
    std::string was = "(none)";
    if (verb != "add") {
      try {
        was = a.at(json::json_pointer(path)).dump();
      } catch (const json::exception&) {
      }
    }
    const std::string is = op.contains("value") ? op["value"].dump() : std::string("(none)");
    auto cut = [](std::string t) { return t.size() > 160 ? t.substr(0, 157) + "..." : t; };
    found.push_back(path + ": " + cut(was) + " -> " + cut(is));
  }
  return found;
}

int merge_regression(const MergeOptions& m, std::ostream& out, std::ostream& progress) {
  if (m.dirs.empty()) throw InputError("merge", 0, "no folders to merge");
  // each folder: its plan (the whole list) and, when its runs finished, its summary
  struct Part {
    fs::path dir;
    json plan;
    std::optional<std::vector<RunRow>> rows;
    double wall_s = 0.0;
    std::string commit;
  };
  std::vector<Part> parts;
  const json* whole = nullptr;
  std::vector<std::string> ids;
  for (const fs::path& dir : m.dirs) {
    Part p;
    p.dir = fs::absolute(dir).lexically_normal();
    if (core::is_file(dir / "plan.json"))
      p.plan = read_json_file(dir / "plan.json", "a conesim regress plan.json");
    if (core::is_file(dir / "summary.json")) {
      const std::string text = read_whole(dir / "summary.json", "the shard's summary.json");
      p.rows = parse_baseline(text, (dir / "summary.json").string());
      try {
        const json summary = json::parse(text);
        p.wall_s = summary.value("wall_time_s", 0.0);
        p.commit = summary.value("commit", std::string());
      } catch (const json::exception&) {
      }
    }
    if (!core::is_folder(dir))
      progress << dir.string() << ": no such folder (its shard never started?)\n";
    else if (p.plan.is_null())
      progress << dir.string() << ": no plan.json (its shard never started?)\n";
    else if (!p.rows)
      progress << dir.string() << ": no summary.json: the runs of this "
               << (p.plan["shard"].is_object()
                       ? "shard (" + std::to_string(p.plan["shard"].value("index", 0)) + "/" +
                             std::to_string(p.plan["shard"].value("count", 0)) + ")"
                       : std::string("rerun"))
               << " are missing unless another folder has them\n";
    parts.push_back(std::move(p));
  }
  // the whole list, the same in every plan
  for (const Part& p : parts) {
    if (p.plan.is_null()) continue;
    const std::vector<std::string> these = plan_run_ids(p.plan, p.dir / "plan.json");
    if (!whole) {
      whole = &p.plan;
      ids = these;
    } else if (these != ids) {
      throw InputError((p.dir / "plan.json").string(), 0,
                       "lists other runs than " + (parts.front().dir / "plan.json").string() +
                           ": these folders are shards of different regressions (the same "
                           "scenarios, tracks, seeds and --set values make the same list)");
    }
  }
  if (!whole)
    throw InputError(m.dirs.front().string(), 0,
                     "no plan.json in any of the folders: merge takes the --out folders of "
                     "`conesim regress ... --shard I/N`");

  // each run's row from the last folder that has it
  std::map<std::string, RunRow> found;
  std::map<std::string, std::string> folders;
  double wall_s = 0.0;
  for (const Part& p : parts) {
    if (!p.rows) continue;
    wall_s = std::max(wall_s, p.wall_s);
    for (const RunRow& r : *p.rows) {
      found[r.id] = r;
      folders[r.id] = (p.dir.lexically_relative(fs::absolute(m.out_dir).lexically_normal()) / r.dir)
                          .generic_string();
    }
  }
  std::vector<RunRow> rows;
  std::vector<std::string> missing;
  for (const std::string& id : ids) {
    const auto it = found.find(id);
    if (it == found.end()) {
      missing.push_back(id);
      continue;
    }
    rows.push_back(it->second);
    rows.back().regressions.clear();
  }

  // the plan and options as the shards had them
  RegressionPlan plan;
  plan.event_mismatches = whole->value("event_mismatches_left_out", 0);
  for (const json& t : whole->value("skipped_tracks", json::array()))
    plan.skipped.push_back({t.value("track", std::string()), t.value("reason", std::string())});
  RegressOptions o;
  o.out_dir = m.out_dir;
  o.command_line = m.command_line;
  o.jobs = whole->value("jobs", 1);
  o.baseline = m.baseline;
  if (!o.baseline && (*whole)["baseline"].is_string())
    o.baseline = fs::path((*whole)["baseline"].get<std::string>());
  std::vector<RunRow> baseline;
  if (o.baseline)
    baseline = parse_baseline(read_whole(*o.baseline, "the baseline summary"), o.baseline->string());
  json expected;
  if (m.expect) expected = read_json_file(*m.expect, "a conesim regress summary.json");

  // the command that runs only the missing runs and merges again
  json dirs = json::array();
  for (const Part& p : parts) dirs.push_back(p.dir.string());
  std::string rerun;
  if (!missing.empty()) rerun = rerun_command(*whole, "regress", m.out_dir);
  MergeParts merge;
  std::set<std::string> commits;
  for (const Part& p : parts)
    if (p.rows) commits.insert(p.commit);
  if (!commits.empty()) merge.commit = *commits.begin();
  if (commits.size() > 1)
    progress << "note: the folders' runs come from different builds (" << join({commits.begin(), commits.end()}, ", ")
             << "): summary.json names " << *merge.commit << "\n";
  merge.missing = &missing;
  merge.run_folders = &folders;
  merge.shards = {{"count", (*whole)["shard"].is_object() ? (*whole)["shard"].value("count", 0) : 0},
                  {"folders", dirs},
                  {"missing_runs", missing},
                  {"rerun", rerun.empty() ? json(nullptr) : json(rerun)}};
  fs::create_directories(m.out_dir);
  check_output_writable(m.out_dir);
  progress << "merged " << parts.size() << " folders: " << rows.size() << " of " << ids.size()
           << " runs\n";
  int status = write_summaries(rows, plan, o, wall_s, o.baseline ? &baseline : nullptr, merge, out);
  for (const std::string& id : missing) out << "missing (no result): " << id << "\n";
  if (!missing.empty())
    out << missing.size() << " runs missing; run only them and merge again with:\n  " << rerun
        << "\n";
  if (m.expect) {
    const json merged = read_json_file(m.out_dir / "summary.json", "the merged summary.json");
    const std::vector<std::string> diff = summary_differences(expected, merged);
    if (diff.empty()) {
      out << "same as " << m.expect->string() << " apart from timing\n";
    } else {
      out << "differs from " << m.expect->string() << " (apart from timing):\n";
      for (const std::string& d : diff) out << "  " << d << "\n";
      status = 1;
    }
  }
  return status;
}

int rerun_then_merge(const fs::path& merge_dir, const std::string& file_name,
                     const std::string& command_line,
                     const std::function<void(const std::vector<std::string>&, const fs::path&)>& run,
                     const std::function<int(const MergeOptions&)>& merge, std::ostream& out,
                     std::ostream& progress) {
  const fs::path file = merge_dir / file_name;
  const json merged = read_json_file(file, "a merged conesim " + file_name);
  if (!merged.contains("shards") || !merged["shards"].is_object())
    throw InputError("--only-missing", 0,
                     file.string() + " is not the " + file_name +
                         " of `conesim merge` (it has no shards section)");
  const json& shards = merged["shards"];
  const auto ids = shards.value("missing_runs", std::vector<std::string>());
  if (ids.empty()) {
    out << "no run is missing in " << merge_dir.string() << "\n";
    return 0;
  }
  // the rerun beside the merge, in a folder of its own
  fs::path rerun_dir;
  for (int k = 1; rerun_dir.empty() || core::path_exists(rerun_dir); ++k)
    rerun_dir = merge_dir / ("rerun-" + std::to_string(k));
  progress << "running the " << ids.size() << " missing runs into " << rerun_dir.string() << "\n";
  run(ids, rerun_dir);
  if (const int signal = interrupt_signal()) return interrupted_exit_status(signal);
  MergeOptions m;
  for (const std::string& d : shards.value("folders", std::vector<std::string>()))
    m.dirs.push_back(d);
  m.dirs.push_back(fs::absolute(rerun_dir));
  m.out_dir = merge_dir;
  m.command_line = command_line;
  return merge(m);
}

int rerun_missing(const fs::path& self, RegressOptions o, const fs::path& merge_dir,
                  std::ostream& out, std::ostream& progress) {
  return rerun_then_merge(
      merge_dir, "summary.json", o.command_line,
      [&](const std::vector<std::string>& ids, const fs::path& dir) {
        o.only_ids = ids;
        o.out_dir = dir;
        o.shard = {};
        o.resume = false;
        run_regression(self, o, out, progress);
      },
      [&](const MergeOptions& m) { return merge_regression(m, out, progress); }, out, progress);
}

fs::path make_run_dir(const fs::path& parent, const std::string& name) {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char stamp[32];
  std::strftime(stamp, sizeof(stamp), "%Y%m%d-%H%M%S", &utc);
  fs::create_directories(parent);
  for (int i = 1;; ++i) {
    std::string leaf = name;
    leaf.append("-").append(stamp);
    if (i > 1) leaf.append("-").append(std::to_string(i));
    const fs::path dir = parent / leaf;
    if (fs::create_directory(dir)) return dir;
  }
}

}  // namespace conesim::sim
