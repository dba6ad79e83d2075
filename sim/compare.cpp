#include "sim/compare.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <set>
#include <ostream>
#include <sstream>

#include "core/error.hpp"
#include "core/files.hpp"
#include "sim/gnuplot.hpp"
#include "sim/interrupt.hpp"
#include "sim/json_text.hpp"
#include "sim/process_pool.hpp"
#include "sim/regress.hpp"
#include "sim/report.hpp"
#include "sim/run.hpp"
#include "sim/scenario.hpp"

namespace conesim::sim {

namespace fs = std::filesystem;
using core::InputError;
using nlohmann::json;

namespace {

// every study drives GraphSLAM and runs the methods it compares in shadow
constexpr const char* kScenario = "trackdrive-graphslam";

// the FST thesis's Table 4.1 noise and mapping speed (range sigma 0.4 m, bearing 4 degrees,
// 3.5 m/s), with the perception's tracker on for tracking-aided association
const std::vector<std::string> kFstNoise = {
    "sensors.cone_sensor.range_sigma_m=0.4", "sensors.cone_sensor.bearing_sigma_rad=0.0698",
    "driver.explore_speed_mps=3.5", "sensors.cone_sensor.track=true"};

// one mapping lap, the loop closure 20 m into the second, then localisation to its end
const std::string kTwoLaps = "driver.trackdrive_laps=2";

// the methods the FST study compares, in shadow of GraphSLAM (tracking-aided)
const std::string kFstLanes =
    "slam.shadow=[fastslam1, fastslam2, ekf, odometry, graph:ml, graph:jcbb]";

// the shared competition circuits (tests/data/tracks), FSG first (the FST thesis's track)
const std::vector<std::string> kCircuits = {
    "fssim/FSG.yaml",       "fssim/FSI.yaml",    "pacsim/FSG19.yaml", "pacsim/FSG21.yaml",
    "pacsim/FSE22.yaml",    "pacsim/FSE23.yaml", "pacsim/FSE24.yaml", "pacsim/FSS19.yaml",
    "pacsim/FSS22_V2.yaml", "pacsim/FSCZ24.yaml"};

struct StudyDefinition {
  std::string name;
  std::vector<StudyCondition> conditions;
  std::vector<std::string> tracks;
  std::vector<unsigned long long> seeds;
};

std::vector<std::string> joined(std::vector<std::string> a, const std::vector<std::string>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

const std::vector<StudyDefinition>& studies() {
  static const std::vector<StudyDefinition> all = [] {
    std::vector<StudyDefinition> d;
    // FST Lisboa: FastSLAM 1.0 / 2.0 against GraphSLAM, and the association methods
    d.push_back(
        {"fst",
         {{"fst", "table-4.1", joined(kFstNoise, {kTwoLaps, kFstLanes}),
           "cone sensor at 10 Hz, 15 m, 180 deg, range sigma 0.4 m, bearing sigma 0.0698 rad (4 "
           "deg), tracker on; mapping lap at 3.5 m/s, second lap localising; GraphSLAM "
           "(tracking-aided) drives, FastSLAM 1.0 / 2.0 (50 particles), EKF SLAM, dead "
           "reckoning, GraphSLAM with ML+IC and with JCBB in shadow; fssim FSG and nine more "
           "competition circuits, seeds 1-5",
           "FSSIM on the 2018 FSG track (Table 4.2 simulation: 0.96 / 0.38 / 0.31 m); Table 4.1 "
           "noise R_r 0.4 m, R_theta 4 deg, 50 particles; association (Table 4.3) and mapping "
           "over distance (Figs 4.6-4.8) measured on the real car at 3.5 m/s; timing 0.0153 / "
           "0.027 / 0.00115 ms per iteration"},
          {"fst", "worse-odometry",
           joined(kFstNoise, {kTwoLaps, kFstLanes, "sensors.imu.gyro_noise_density_rps_rthz=1.2e-3",
                              "sensors.wheel_encoders.noise_rps=0.2"}),
           "as table-4.1 with ten times the gyro's white noise (1.2e-3 rad/s/sqrt(Hz)) and the "
           "wheel encoders' (0.2 rad/s): an odometry that drifts metres per lap, as the thesis's "
           "maps suggest its did",
           "the thesis does not give its odometry's noise; its FastSLAM motion noise (Table 4.1: "
           "P_x, P_y 0.5 m, P_phi 5 deg) is large"}},
         kCircuits,
         {1, 2, 3, 4, 5}});
    // RaceUp: the GraphSLAM ablations
    const std::string raceup_lanes =
        "slam.shadow=[graph:ideal+global_only, graph:ideal+global_only+no_icr, graph:ideal, "
        "graph:nn, graph:nn+global_only, graph+global_only, graph+no_icr, "
        "graph+no_landmark_edges, graph:none, odometry, odometry:none]";
    d.push_back(
        {"raceup",
         {{"raceup",
           "simulator",
           {kTwoLaps, raceup_lanes},
           "the shipped scenario's cone sensor (range sigma 0.05 m, bearing 0.007 rad, 10 Hz, 15 "
           "m), mapping lap at 9 m/s, second lap localising; the ablations in shadow of "
           "GraphSLAM",
           "Tonin's simulator: ideal association, ICR edge, loop closure on the big orange "
           "cones, global-only optimisation (EXP1, Fig. 7.8); no figures, maps only"},
          {"raceup", "fst-noise", joined(kFstNoise, {kTwoLaps, raceup_lanes}),
           "as 'simulator' with the FST thesis's noise (0.4 m, 4 deg) at 3.5 m/s: a front end "
           "as poor as RaceUp's real one",
           "the real car (Figs 7.9-7.13): no association, nearest neighbour, global "
           "optimisation, the graph without landmark edges; maps only"}},
         {"fssim/FSG.yaml", "pacsim/FSG19.yaml", "pacsim/FSE22.yaml"},
         {1, 2, 3}});
    // Monash: EKF SLAM's preliminary landmark list
    const std::string monash_lanes = "slam.shadow=[ekf, ekf+no_preliminary, odometry]";
    d.push_back(
        {"monash",
         {{"monash",
           "clutter",
           {kTwoLaps, monash_lanes, "sensors.cone_sensor.false_positives_per_frame=1"},
           "the shipped cone sensor with one false positive per frame on average (Poisson, "
           "anywhere in view), EKF SLAM with and without the preliminary list in shadow",
           "VLP-16 LiDAR cone detection with false positives from tall grass beside the track; "
           "246 landmarks without the list, 190 with it, just before loop closure (Figs 5.4, "
           "5.5)"},
          {"monash",
           "clean",
           {kTwoLaps, monash_lanes},
           "the shipped cone sensor (0.05 false positives per frame)",
           "(no such run)"}},
         {"fssim/FSG.yaml", "fssim/FSI.yaml", "pacsim/FSG19.yaml"},
         {1, 2, 3}});
    return d;
  }();
  return all;
}

// a run's folder name part: no '/' inside
std::string flat(std::string s) {
  std::replace(s.begin(), s.end(), '/', '_');
  return s;
}

// ---- reading the runs ----

double number_or_nan(const json& j, const char* key) {
  return j.is_object() && j.contains(key) && j[key].is_number() ? j[key].get<double>() : NAN;
}

json finite_or_null(double v) {
  return std::isfinite(v) ? json(v) : json();
}

double median(std::vector<double> v) {
  std::erase_if(v, [](double x) { return !std::isfinite(x); });
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// the map RMSE just before the first loop closure (the last 10 m snapshot before it)
double rmse_before_closure(const json& lane) {
  const json& events = lane.value("loop_closure_events", json::array());
  if (events.empty()) return NAN;
  const double closure_m = number_or_nan(events[0], "travel_m");
  double before = NAN;
  for (const json& row : lane.value("map_error_over_distance", json::array()))
    if (number_or_nan(row, "distance_m") <= closure_m && row["rmse_m"].is_number())
      before = row["rmse_m"].get<double>();
  return before;
}

// a run's lanes in the order the scenario gave them: the driving one, then the shadows (the
// lanes of metrics.json's slam object, which lists them by name)
std::vector<std::string> lane_order(const json& metrics) {
  std::vector<std::string> out;
  const json& slam = metrics["slam"];
  auto add = [&](const std::string& lane) {
    if (slam.contains(lane) && std::find(out.begin(), out.end(), lane) == out.end())
      out.push_back(lane);
  };
  if (metrics.contains("slam_driving") && metrics["slam_driving"].is_string())
    add(metrics["slam_driving"].get<std::string>());
  for (const json& lane : metrics.value("slam_shadows", json::array()))
    if (lane.is_string()) add(lane.get<std::string>());
  for (const auto& [lane, m] : slam.items()) add(lane);
  return out;
}

// the figures of one lane of one run that the comparison uses
json lane_figures(const json& lane) {
  json out;
  for (const char* key :
       {"role", "association", "ablations", "ideal_association", "map_rmse_m", "map_rmse_aligned_m",
        "map_matched", "map_spurious", "map_missed", "ate_rmse_m", "da_correct", "da_wrong",
        "da_rejected", "da_correct_fraction", "loop_closures", "false_loop_closures", "update_cpu_ms_median",
        "update_ms_median", "backend_stats"})
    if (lane.contains(key)) out[key] = lane[key];
  out["map_rmse_before_closure_m"] = finite_or_null(rmse_before_closure(lane));
  const json& events = lane.value("loop_closure_events", json::array());
  out["closure_travel_m"] = events.empty() ? json() : events[0].value("travel_m", json());
  // the landmarks a back-end made: its own count, else the map's size
  const json stats = lane.value("backend_stats", json::object());
  out["landmarks"] = stats.contains("landmarks")
                         ? stats["landmarks"]
                         : json(lane.value("map_matched", 0) + lane.value("map_spurious", 0));
  return out;
}

// ---- the theses' figures ----

// what a thesis reported for a lane of a study (null: nothing)
json thesis_for(const std::string& study, const std::string& lane) {
  if (study == "fst") {
    // Table 4.2 (simulation), the timing of Section 4.1, Table 4.3, Fig. 4.8
    if (lane == "fastslam1") return {{"map_rmse_m", 0.96}, {"update_ms", 0.0153}};
    if (lane == "fastslam2") return {{"map_rmse_m", 0.38}, {"update_ms", 0.027}};
    if (lane == "graph")
      return {{"map_rmse_m", 0.31},
              {"update_ms", 0.00115},
              {"da_correct", 2186},
              {"da_wrong", 44},
              {"map_rmse_before_closure_m", 1.23},
              {"map_rmse_after_closure_m", 0.35}};
    if (lane == "graph-ml") return {{"da_correct", 2029}, {"da_wrong", 201}};
    if (lane == "graph-jcbb") return {{"da_correct", 2118}, {"da_wrong", 112}};
  }
  if (study == "raceup") {
    static const std::map<std::string, std::string> notes = {
        {"graph-ideal+global_only",
         "EXP1 (simulator): ideal association, ICR, global-only; the loop closes, the shape "
         "holds (Fig. 7.8)"},
        {"graph-none", "real car, no association: noisy, many redundant cones (Fig. 7.9)"},
        {"graph-nn", "real car, nearest neighbour: the redundant cones go (Fig. 7.10)"},
        {"graph-nn+global_only",
         "real car, NN and global optimisation at the loop closure: loop closed, map off the "
         "truth through the front end (Fig. 7.11)"},
        {"graph+no_landmark_edges",
         "real car, poses and loop closure only: 'the loop is perfectly closed' (Fig. 7.12)"},
        {"graph-ideal+global_only+no_icr", "(not run: the ICR edge was always on)"},
        {"odometry-none", "(the map of Fig. 7.9 without any optimisation)"}};
    if (const auto it = notes.find(lane); it != notes.end()) return {{"note", it->second}};
  }
  if (study == "monash") {
    // Figs 5.4 and 5.5, just before the loop closure
    if (lane == "ekf") return {{"landmarks", 190}};
    if (lane == "ekf+no_preliminary") return {{"landmarks", 246}};
  }
  return nullptr;
}

// the method's name for people
std::string method_name(const std::string& lane) {
  static const std::map<std::string, std::string> names = {
      {"graph", "GraphSLAM (tracking-aided)"},
      {"graph-ml", "GraphSLAM, ML + IC"},
      {"graph-jcbb", "GraphSLAM, JCBB"},
      {"fastslam1", "FastSLAM 1.0"},
      {"fastslam2", "FastSLAM 2.0"},
      {"ekf", "EKF SLAM"},
      {"ekf+no_preliminary", "EKF SLAM, no preliminary list"},
      {"odometry", "dead reckoning (NN map)"},
      {"odometry-none", "dead reckoning, no association"}};
  const auto it = names.find(lane);
  return it == names.end() ? lane : it->second;
}

// ---- numbers as text ----

std::string fixed(double v, int decimals) {
  if (!std::isfinite(v)) return "-";
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, v);
  return buf;
}

std::string fixed(const json& v, int decimals) {
  return v.is_number() ? fixed(v.get<double>(), decimals) : "-";
}

// "median (min-max)" of a summary figure
std::string spread(const json& s, int decimals) {
  if (!s.is_object() || !s["median"].is_number()) return "-";
  if (s.value("n", 0) < 2) return fixed(s["median"], decimals);
  return fixed(s["median"], decimals) + " (" + fixed(s["min"], decimals) + "-" +
         fixed(s["max"], decimals) + ")";
}

json statistic(const std::vector<double>& values) {
  std::vector<double> v = values;
  std::erase_if(v, [](double x) { return !std::isfinite(x); });
  if (v.empty()) return {{"median", nullptr}, {"min", nullptr}, {"max", nullptr}, {"n", 0}};
  return {{"median", median(v)},
          {"min", *std::min_element(v.begin(), v.end())},
          {"max", *std::max_element(v.begin(), v.end())},
          {"n", v.size()}};
}

// ---- the tables ----

json table(const std::string& study, const std::string& title, const std::string& note,
           const std::vector<std::string>& header) {
  return {{"study", study},
          {"title", title},
          {"note", note},
          {"header", header},
          {"rows", json::array()}};
}

// the lanes of a study's condition in the order the runs gave them
std::vector<std::string> lanes_of(const json& summary, const std::string& study,
                                  const std::string& condition) {
  std::vector<std::string> out;
  for (const json& s : summary)
    if (s["study"] == study && s["condition"] == condition) out.push_back(s["lane"]);
  return out;
}

const json* summary_of(const json& summary, const std::string& study, const std::string& condition,
                       const std::string& lane) {
  for (const json& s : summary)
    if (s["study"] == study && s["condition"] == condition && s["lane"] == lane) return &s;
  return nullptr;
}

void add_fst_tables(const json& c, json& tables) {
  const json& summary = c["summary"];
  for (const json& cond : c["conditions"]) {
    if (cond["study"] != "fst") continue;
    const std::string name = cond["name"];
    const std::string where = "condition '" + name + "'";
    // map RMSE per track with the thesis's figure beside each method
    json t =
        table("fst", "Map RMSE per method and track [m], median (min-max) over seeds, " + where,
              "FST Table 4.2 (simulation, 2018 FSG track) in the 'thesis' columns. The "
              "ordering column counts the runs in which FastSLAM 1.0 > 2.0 > GraphSLAM.",
              {"track", "seeds", "FastSLAM 1.0", "thesis", "FastSLAM 2.0", "thesis", "GraphSLAM",
               "thesis", "EKF SLAM", "dead reckoning", "FS1 > FS2 > Graph"});
    for (const json& p : c["per_track"]) {
      if (p["study"] != "fst" || p["condition"] != name) continue;
      auto cell = [&](const char* lane) { return spread(p["lanes"].value(lane, json()), 3); };
      const json& o = p["ordering"];
      t["rows"].push_back(
          {p["track"], std::to_string(p.value("seeds", 0)), cell("fastslam1"), "0.96",
           cell("fastslam2"), "0.38", cell("graph"), "0.31", cell("ekf"), cell("odometry"),
           std::to_string(o.value("holds", 0)) + " of " + std::to_string(o.value("runs", 0))});
    }
    tables.push_back(t);
    json al =
        table("fst",
              "The same after the best rigid alignment of each map on the true cones [m], " + where,
              "map_rmse_aligned_m: what is left once an offset of the whole map against "
              "the start pose (the gauge, fixed by the first observations) is taken out.",
              {"track", "FastSLAM 1.0", "FastSLAM 2.0", "GraphSLAM", "EKF SLAM", "dead reckoning"});
    for (const json& p : c["per_track"]) {
      if (p["study"] != "fst" || p["condition"] != name) continue;
      auto cell = [&](const char* lane) {
        return spread(p["lanes_aligned"].value(lane, json()), 3);
      };
      al["rows"].push_back({p["track"], cell("fastslam1"), cell("fastslam2"), cell("graph"),
                            cell("ekf"), cell("odometry")});
    }
    tables.push_back(al);

    // associations (Table 4.3)
    json a =
        table("fst", "Correct and missed associations (FST Table 4.3), summed over runs, " + where,
              "Judged against the labels (docs/metrics.md, da_correct / da_wrong); 'rejected': "
              "observations of a cone left unpaired (da_rejected: duplicates, and for "
              "tracking-aided the ambiguous ones it holds back). The thesis counted one run of "
              "the real car; its accuracy is what compares.",
              {"method", "correct", "wrong", "rejected", "accuracy", "thesis correct",
               "thesis wrong", "thesis accuracy"});
    for (const std::string& lane : lanes_of(summary, "fst", name)) {
      const json& s = *summary_of(summary, "fst", name, lane);
      const json th = thesis_for("fst", lane);
      const bool has = th.is_object() && th.contains("da_correct");
      const double tc = has ? th["da_correct"].get<double>() : NAN;
      const double tw = has ? th["da_wrong"].get<double>() : NAN;
      a["rows"].push_back({method_name(lane), fixed(s["da_correct"], 0), fixed(s["da_wrong"], 0),
                           fixed(s.value("da_rejected", json()), 0),
                           fixed(s["da_correct_fraction"], 4), fixed(tc, 0), fixed(tw, 0),
                           fixed(tc / (tc + tw), 2)});
    }
    tables.push_back(a);

    // time per update
    json u =
        table("fst", "Time per update (CPU), median over runs of each run's median [ms], " + where,
              "The ratio is to GraphSLAM's. The thesis: GraphSLAM 0.00115 ms, FastSLAM 1.0 "
              "0.0153 ms, FastSLAM 2.0 0.027 ms per iteration (1 : 13 : 23).",
              {"method", "update [ms]", "ratio to GraphSLAM", "thesis [ms]", "thesis ratio"});
    const json* graph = summary_of(summary, "fst", name, "graph");
    const double graph_ms = graph ? number_or_nan(*graph, "update_cpu_ms_median") : NAN;
    for (const std::string& lane : lanes_of(summary, "fst", name)) {
      const json& s = *summary_of(summary, "fst", name, lane);
      const json th = thesis_for("fst", lane);
      const double tms = th.is_object() ? number_or_nan(th, "update_ms") : NAN;
      const double ms = number_or_nan(s, "update_cpu_ms_median");
      u["rows"].push_back({method_name(lane), fixed(ms, 3), fixed(ms / graph_ms, 1), fixed(tms, 5),
                           fixed(tms / 0.00115, 1)});
    }
    tables.push_back(u);

    // before and after the loop closure (Fig. 4.8)
    json l =
        table("fst", "Map RMSE before and after the loop closure [m], median over runs, " + where,
              "Before: the last 10 m snapshot before the first closure; after: the final "
              "map. FST Fig. 4.8 (GraphSLAM on the real car, track 1): 1.23 -> 0.35 m.",
              {"method", "runs closed", "before", "after", "thesis before", "thesis after"});
    for (const std::string& lane : lanes_of(summary, "fst", name)) {
      const json& s = *summary_of(summary, "fst", name, lane);
      const json th = thesis_for("fst", lane);
      l["rows"].push_back(
          {method_name(lane),
           std::to_string(s.value("runs_closed", 0)) + " of " + std::to_string(s.value("runs", 0)),
           fixed(s["map_rmse_before_closure_m"], 3), fixed(s["map_rmse_after_closure_m"], 3),
           fixed(th.is_object() ? number_or_nan(th, "map_rmse_before_closure_m") : NAN, 2),
           fixed(th.is_object() ? number_or_nan(th, "map_rmse_after_closure_m") : NAN, 2)});
    }
    tables.push_back(l);
  }
}

void add_raceup_tables(const json& c, json& tables) {
  const json& summary = c["summary"];
  for (const json& cond : c["conditions"]) {
    if (cond["study"] != "raceup") continue;
    const std::string name = cond["name"];
    json t = table("raceup",
                   "RaceUp ablations, condition '" + name +
                       "': map and trajectory error, median "
                       "(min-max) over runs",
                   "Landmarks: the map's size at the end. A map without association keeps every "
                   "observation: its RMSE is that of the closest placement per cone (read it with "
                   "the spurious count).",
                   {"lane", "ablations", "association", "map RMSE [m]", "ATE [m]", "landmarks",
                    "spurious", "loop closures", "RaceUp"});
    for (const std::string& lane : lanes_of(summary, "raceup", name)) {
      const json& s = *summary_of(summary, "raceup", name, lane);
      std::string ablations;
      for (const json& a : s.value("ablations", json::array()))
        ablations += (ablations.empty() ? "" : ", ") + a.get<std::string>();
      const json th = thesis_for("raceup", lane);
      t["rows"].push_back(
          {lane, ablations.empty() ? "-" : ablations, s.value("association", ""),
           spread(s["map_rmse_m"], 3), spread(s["ate_rmse_m"], 3), fixed(s["landmarks"], 0),
           fixed(s["map_spurious"], 0),
           std::to_string(s.value("runs_closed", 0)) + " of " + std::to_string(s.value("runs", 0)),
           th.is_object() ? th.value("note", "") : ""});
    }
    tables.push_back(t);
  }
}

void add_monash_tables(const json& c, json& tables) {
  const json& summary = c["summary"];
  json t = table("monash", "EKF SLAM's landmarks with and without the preliminary list",
                 "Medians over runs. 'kept out': candidates the list forgot before they were "
                 "confirmed (backend_stats.preliminary_dropped). Monash counted just before the "
                 "loop closure, conesim at the end (the map is fixed 20 m after the closure).",
                 {"condition", "method", "landmarks in the filter", "kept out by the list",
                  "spurious", "map RMSE [m]", "ATE [m]", "Monash landmarks"});
  for (const json& cond : c["conditions"]) {
    if (cond["study"] != "monash") continue;
    const std::string name = cond["name"];
    for (const std::string& lane : lanes_of(summary, "monash", name)) {
      const json& s = *summary_of(summary, "monash", name, lane);
      const json th = thesis_for("monash", lane);
      t["rows"].push_back(
          {name, method_name(lane), fixed(s["landmarks"], 0), fixed(s["preliminary_dropped"], 0),
           fixed(s["map_spurious"], 0), spread(s["map_rmse_m"], 3), spread(s["ate_rmse_m"], 3),
           name == "clutter" ? fixed(th.is_object() ? number_or_nan(th, "landmarks") : NAN, 0)
                             : "-"});
    }
  }
  tables.push_back(t);
}

// ---- the figures ----

// the map error over distance of every lane of one run: all classes, then per class
void draw_figures(const StudyPlan& plan, const std::vector<StudyResult>& results,
                  const fs::path& out_dir, json& figures, std::ostream& progress) {
  for (const StudyCondition& cond : plan.conditions) {
    // the first usable run of the condition (its first track and seed)
    size_t k = 0;
    while (k < plan.runs.size() && !(plan.runs[k].study == cond.study &&
                                     plan.runs[k].condition == cond.name && run_usable(results[k])))
      ++k;
    if (k == plan.runs.size()) continue;
    const json& lanes = results[k].metrics["slam"];
    std::vector<PlotData> data;
    std::vector<std::string> names;
    for (const std::string& lane : lane_order(results[k].metrics)) {
      const json& m = lanes[lane];
      PlotData d{"lane" + std::to_string(data.size()), {}};
      for (const json& row : m.value("map_error_over_distance", json::array())) {
        d.rows.push_back({number_or_nan(row, "distance_m"), number_or_nan(row, "rmse_m")});
        for (const char* cls : {"blue_m", "yellow_m", "orange_small_m", "orange_big_m"})
          d.rows.back().push_back(number_or_nan(row, cls));
      }
      if (d.rows.empty()) d.rows.push_back({NAN, NAN, NAN, NAN, NAN, NAN});
      data.push_back(d);
      names.push_back(lane);
    }
    auto plot_line = [&](int column) {
      std::string s;
      for (size_t i = 0; i < data.size(); ++i)
        s += std::string(i ? ", " : "") + "$" + data[i].name +
             " using 1:" + std::to_string(column) + " with lines lw 2 title '" + names[i] + "'";
      return s + "\n";
    };
    const std::string stem = "map_error_" + cond.study + "_" + cond.name;
    const std::string where =
        plan.runs[k].track_label + ", seed " + std::to_string(plan.runs[k].seed);
    try {
      render_png("set title 'Map RMSE over distance driven: " + cond.study + " / " + cond.name +
                     " (" + where +
                     ")'\nset xlabel 'distance driven [m]'\nset ylabel 'map RMSE "
                     "[m]'\nset key outside right\nset grid\n" +
                     ranges_if_nothing_to_plot(data) + "plot " + plot_line(2),
                 data, out_dir / (stem + ".png"), 1300, 700);
      figures.push_back({{"study", cond.study},
                         {"condition", cond.name},
                         {"file", stem + ".png"},
                         {"title", "map RMSE over distance, every method (" + where + ")"}});
      std::string by_class =
          "set multiplot layout 2,2 title 'Map RMSE per cone class: " + cond.study + " / " +
          cond.name + " (" + where + ")'\nset grid\n" + ranges_if_nothing_to_plot(data);
      const char* classes[] = {"blue", "yellow", "small orange", "big orange"};
      for (int c = 0; c < 4; ++c) {
        by_class += std::string("set title '") + classes[c] + "'\nset xlabel 'distance [m]'\n" +
                    (c == 0 ? "set key top right font ',8'\n" : "unset key\n");
        // a class the layout does not have: an empty panel that says so
        bool any = false;
        for (const PlotData& d : data)
          for (const auto& row : d.rows) any = any || std::isfinite(row[2 + c]);
        by_class += any ? "plot " + plot_line(3 + c)
                        : "set label 1 'no cone of this class mapped' at graph 0.5,0.5 center\n"
                          "plot [0:1] [0:1] -1 notitle\nunset label 1\n";
      }
      by_class += "unset multiplot\n";
      render_png(by_class, data, out_dir / (stem + "_by_class.png"), 1400, 1000);
      figures.push_back({{"study", cond.study},
                         {"condition", cond.name},
                         {"file", stem + "_by_class.png"},
                         {"title", "map RMSE over distance per cone class (" + where + ")"}});
    } catch (const std::exception& e) {
      progress << "warning: figure " << stem << " not drawn: " << e.what() << "\n";
    }
  }
}

}  // namespace

std::string StudyRun::id() const {
  return study + " | " + condition + " | " + track_label + " | seed " + std::to_string(seed);
}

const std::vector<std::string>& study_names() {
  static const std::vector<std::string> names = {"fst", "raceup", "monash", "all"};
  return names;
}

bool run_usable(const StudyResult& r) {
  return r.metrics.is_object() && r.metrics.contains("slam") &&
         (r.exit_code == 0 || r.exit_code == 1);
}

StudyPlan plan_study(const CompareOptions& o) {
  StudyPlan plan;
  if (o.study == "all") {
    plan.studies = {"fst", "raceup", "monash"};
  } else if (std::find(study_names().begin(), study_names().end(), o.study) !=
             study_names().end()) {
    plan.studies = {o.study};
  } else {
    std::string known;
    for (const std::string& n : study_names()) known += (known.empty() ? "" : ", ") + n;
    throw InputError("STUDY", 0, "expected one of " + known + ", got '" + o.study + "'");
  }
  for (const fs::path& f : o.track_files)
    if (!core::is_file(f)) throw InputError(f.string(), 0, "no such track file");
  const fs::path scenario = find_scenario(kScenario);
  for (const StudyDefinition& def : studies()) {
    if (std::find(plan.studies.begin(), plan.studies.end(), def.name) == plan.studies.end())
      continue;
    std::vector<std::pair<std::string, fs::path>> tracks;
    for (const fs::path& f : o.track_files)
      tracks.push_back({f.parent_path().filename().string() + "/" + f.stem().string(), f});
    if (tracks.empty())
      for (const std::string& t : def.tracks) {
        const fs::path file = shipped_corpus_dir() / t;
        if (!core::is_file(file))
          throw InputError(file.string(), 0, "the study's track is missing (CONESIM_CORPUS?)");
        tracks.push_back(
            {fs::path(t).parent_path().string() + "/" + fs::path(t).stem().string(), file});
      }
    const std::vector<unsigned long long> seeds = o.seeds.empty() ? def.seeds : o.seeds;
    // each track's lap for the runs' expected cost (one the reader refuses: the usual 300 m;
    // its run says why it cannot drive)
    std::vector<double> lap_m;
    for (const auto& track : tracks) {
      try {
        lap_m.push_back(track_lap_length_m(track.second));
      } catch (const std::exception&) {
        lap_m.push_back(0.0);
      }
    }
    for (const StudyCondition& cond : def.conditions) {
      // the condition's values with the command line's after them: a typo stops here
      const std::vector<std::string> sets = joined(cond.sets, o.sets);
      const Scenario s = load_scenario(scenario, sets);
      plan.conditions.push_back(cond);
      for (size_t t = 0; t < tracks.size(); ++t)
        for (const unsigned long long seed : seeds) {
          const auto& [label, file] = tracks[t];
          StudyRun r{def.name, cond.name, label, file, seed, sets, {}};
          r.dir = fs::path(def.name) / cond.name / (flat(label) + "-s" + std::to_string(seed));
          r.cost = scenario_run_cost(s, lap_m[t], false);  // its runs draw no run.png
          plan.runs.push_back(r);
        }
    }
  }
  return plan;
}

json compare_json(const StudyPlan& plan, const std::vector<StudyResult>& results,
                  const CompareOptions& o, double wall_s) {
  json c;
  c["schema"] = "conesim-compare/1";
  c["study"] = o.study;
  c["studies"] = plan.studies;
  c["command"] = o.command_line;
  c["wall_time_s"] = wall_s;
  c["jobs"] = o.jobs;
  c["scenario"] = kScenario;
  json conditions = json::array();
  for (const StudyCondition& cond : plan.conditions)
    conditions.push_back({{"study", cond.study},
                          {"name", cond.name},
                          {"sets", cond.sets},
                          {"conesim", cond.conesim},
                          {"thesis", cond.thesis}});
  c["conditions"] = conditions;

  // every run: its verdict and its lanes' figures
  json runs = json::array(), failed = json::array();
  for (size_t i = 0; i < plan.runs.size(); ++i) {
    const StudyRun& r = plan.runs[i];
    const StudyResult& res = results[i];
    json row = {{"id", r.id()},
                {"study", r.study},
                {"condition", r.condition},
                {"track", r.track_label},
                {"seed", r.seed},
                {"dir", r.dir.string()},
                {"exit_code", res.exit_code},
                {"usable", run_usable(res)}};
    if (run_usable(res)) {
      row["completed"] = res.metrics.value("completed", false);
      row["dnf_reason"] = res.metrics.value("dnf_reason", "");
      json lanes = json::object();
      json order = json::array();
      for (const auto& [lane, m] : res.metrics["slam"].items()) lanes[lane] = lane_figures(m);
      for (const std::string& lane : lane_order(res.metrics)) order.push_back(lane);
      row["lanes"] = lanes;
      row["lane_order"] = order;
    } else {
      const std::string reason =
          res.missing ? std::string("missing: no result, its shard did not run or finish it")
                      : "exit status " + std::to_string(res.exit_code) +
                            (res.metrics.is_object() ? "" : ", no metrics.json") +
                            (res.log_tail.empty() ? "" : ": " + res.log_tail);
      if (res.missing) row["missing"] = true;
      row["reason"] = reason;
      failed.push_back({{"id", r.id()}, {"dir", r.dir.string()}, {"reason", reason}});
    }
    runs.push_back(row);
  }
  c["runs"] = runs;
  c["failed_runs"] = failed;

  // per study, condition and lane over the usable runs
  json summary = json::array(), per_track = json::array();
  for (const StudyCondition& cond : plan.conditions) {
    std::vector<std::string> lane_order;
    std::map<std::string, std::vector<const json*>> by_lane;
    std::map<std::string, std::map<std::string, std::vector<double>>> rmse_by_track,
        aligned_by_track;
    std::vector<std::string> track_order;
    std::map<std::string, std::pair<int, int>> ordering;  // track: holds, runs
    for (const json& run : runs) {
      if (run["study"] != cond.study || run["condition"] != cond.name || !run["usable"]) continue;
      const std::string track = run["track"];
      if (std::find(track_order.begin(), track_order.end(), track) == track_order.end())
        track_order.push_back(track);
      for (const std::string lane : run["lane_order"]) {
        const json& f = run["lanes"][lane];
        if (!by_lane.count(lane)) lane_order.push_back(lane);
        by_lane[lane].push_back(&f);
        rmse_by_track[track][lane].push_back(number_or_nan(f, "map_rmse_m"));
        aligned_by_track[track][lane].push_back(number_or_nan(f, "map_rmse_aligned_m"));
      }
      const json& l = run["lanes"];
      if (l.contains("fastslam1") && l.contains("fastslam2") && l.contains("graph")) {
        const double a = number_or_nan(l["fastslam1"], "map_rmse_m"),
                     b = number_or_nan(l["fastslam2"], "map_rmse_m"),
                     g = number_or_nan(l["graph"], "map_rmse_m");
        ordering[track].second += 1;
        ordering[track].first += a > b && b > g;
      }
    }
    for (const std::string& lane : lane_order) {
      const std::vector<const json*>& fs_ = by_lane[lane];
      auto collect = [&](const char* key) {
        std::vector<double> v;
        for (const json* f : fs_) v.push_back(number_or_nan(*f, key));
        return v;
      };
      auto collect_stat = [&](const char* key) {
        std::vector<double> v;
        for (const json* f : fs_)
          v.push_back(number_or_nan((*f).value("backend_stats", json::object()), key));
        return v;
      };
      double correct = 0, wrong = 0, rejected = 0;
      int closed = 0;
      std::vector<double> after;
      for (const json* f : fs_) {
        correct += number_or_nan(*f, "da_correct");
        wrong += number_or_nan(*f, "da_wrong");
        rejected += f->value("da_rejected", 0.0);
        if (number_or_nan(*f, "loop_closures") > 0) {
          ++closed;
          after.push_back(number_or_nan(*f, "map_rmse_m"));
        }
      }
      const json& first = *fs_.front();
      summary.push_back(
          {{"study", cond.study},
           {"condition", cond.name},
           {"lane", lane},
           {"method", method_name(lane)},
           {"association", first.value("association", "")},
           {"ablations", first.value("ablations", json::array())},
           {"ideal_association", first.value("ideal_association", false)},
           {"runs", fs_.size()},
           {"runs_closed", closed},
           {"map_rmse_m", statistic(collect("map_rmse_m"))},
           {"map_rmse_aligned_m", statistic(collect("map_rmse_aligned_m"))},
           {"ate_rmse_m", statistic(collect("ate_rmse_m"))},
           {"map_matched", finite_or_null(median(collect("map_matched")))},
           {"map_spurious", finite_or_null(median(collect("map_spurious")))},
           {"landmarks", finite_or_null(median(collect("landmarks")))},
           {"preliminary_dropped", finite_or_null(median(collect_stat("preliminary_dropped")))},
           {"da_correct", correct},
           {"da_wrong", wrong},
           {"da_rejected", rejected},
           {"da_correct_fraction",
            correct + wrong > 0 ? json(correct / (correct + wrong)) : json()},
           {"update_cpu_ms_median", finite_or_null(median(collect("update_cpu_ms_median")))},
           {"map_rmse_before_closure_m",
            finite_or_null(median(collect("map_rmse_before_closure_m")))},
           {"map_rmse_after_closure_m", finite_or_null(median(after))},
           {"thesis", thesis_for(cond.study, lane)}});
    }
    for (const std::string& track : track_order) {
      json lanes = json::object(), aligned = json::object();
      int seeds = 0;
      for (const auto& [lane, values] : rmse_by_track[track]) {
        lanes[lane] = statistic(values);
        aligned[lane] = statistic(aligned_by_track[track][lane]);
        seeds = std::max(seeds, static_cast<int>(values.size()));
      }
      per_track.push_back(
          {{"study", cond.study},
           {"condition", cond.name},
           {"track", track},
           {"seeds", seeds},
           {"lanes", lanes},
           {"lanes_aligned", aligned},
           {"ordering", {{"holds", ordering[track].first}, {"runs", ordering[track].second}}}});
    }
  }
  c["summary"] = summary;
  c["per_track"] = per_track;
  json tables = json::array();
  add_fst_tables(c, tables);
  add_raceup_tables(c, tables);
  add_monash_tables(c, tables);
  json kept = json::array();
  for (const json& t : tables)
    if (!t["rows"].empty()) kept.push_back(t);
  c["tables"] = kept;
  c["figures"] = json::array();
  return c;
}

std::string compare_markdown(const json& c) {
  std::ostringstream md;
  md << "# conesim compare " << c.value("study", "") << "\n\n";
  md << "`" << c.value("command", "") << "`: " << c["runs"].size() << " runs of `"
     << c.value("scenario", "") << "` (GraphSLAM drives, the methods run in shadow on the same "
     << "observations), " << c.value("jobs", 0) << " at once, " << fixed(c["wall_time_s"], 0)
     << " s";
  if (c.value("reused_runs", 0) > 0)
    md << " (" << c.value("reused_runs", 0) << " runs reused from an earlier call: the time is "
       << "not theirs)";
  md << ". Figures from each run's metrics.json (docs/metrics.md).\n\n";
  if (!c["failed_runs"].empty()) {
    md << "**" << c["failed_runs"].size() << " runs gave no figures:**\n\n";
    for (const json& f : c["failed_runs"])
      md << "- " << f["id"].get<std::string>() << " (" << f["dir"].get<std::string>()
         << "): " << f["reason"].get<std::string>() << "\n";
    md << "\n";
  }
  auto cell = [](const json& v) {
    std::string s = v.is_string() ? v.get<std::string>() : json_text(v);
    std::replace(s.begin(), s.end(), '|', '/');
    return s;
  };
  for (const std::string study : c["studies"]) {
    md << "## " << study << "\n\n| condition | conesim | thesis |\n|---|---|---|\n";
    for (const json& cond : c["conditions"])
      if (cond["study"] == study)
        md << "| " << cell(cond["name"]) << " | " << cell(cond["conesim"]) << " | "
           << cell(cond["thesis"]) << " |\n";
    md << "\n";
    for (const json& t : c["tables"]) {
      if (t["study"] != study) continue;
      md << "### " << t["title"].get<std::string>() << "\n\n"
         << t["note"].get<std::string>() << "\n\n|";
      for (const json& h : t["header"]) md << " " << cell(h) << " |";
      md << "\n|";
      for (size_t i = 0; i < t["header"].size(); ++i) md << "---|";
      md << "\n";
      for (const json& row : t["rows"]) {
        md << "|";
        for (const json& v : row) md << " " << cell(v) << " |";
        md << "\n";
      }
      md << "\n";
    }
    for (const json& f : c["figures"])
      if (f["study"] == study)
        md << "![" << f["title"].get<std::string>() << "](" << f["file"].get<std::string>()
           << ")\n\n";
  }
  return md.str();
}

std::string compare_html(const json& c) {
  std::ostringstream h;
  h << "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>conesim compare "
    << html_escape(c.value("study", "")) << "</title>\n<style>body{font-family:sans-serif;"
    << "margin:2em;max-width:1400px}table{border-collapse:collapse;margin:1em 0}"
    << "td,th{border:1px solid #bbb;padding:3px 8px;text-align:left}th{background:#eee}"
    << ".fail{color:#b00020}img{max-width:100%}</style></head><body>\n";
  h << "<h1>conesim compare " << html_escape(c.value("study", "")) << "</h1>\n<p><code>"
    << html_escape(c.value("command", "")) << "</code>: " << c["runs"].size() << " runs, "
    << c.value("jobs", 0) << " at once, " << fixed(c["wall_time_s"], 0) << " s.</p>\n";
  if (!c["failed_runs"].empty()) {
    h << "<p class=\"fail\"><b>" << c["failed_runs"].size() << " runs gave no figures:</b></p><ul>";
    for (const json& f : c["failed_runs"])
      h << "<li class=\"fail\">" << html_escape(f["id"].get<std::string>()) << " ("
        << html_escape(f["dir"].get<std::string>())
        << "): " << html_escape(f["reason"].get<std::string>()) << "</li>";
    h << "</ul>\n";
  }
  auto text = [](const json& v) {
    return html_escape(v.is_string() ? v.get<std::string>() : json_text(v));
  };
  for (const std::string study : c["studies"]) {
    h << "<h2>" << html_escape(study) << "</h2>\n<table><tr><th>condition</th><th>conesim</th>"
      << "<th>thesis</th></tr>\n";
    for (const json& cond : c["conditions"])
      if (cond["study"] == study)
        h << "<tr><td>" << text(cond["name"]) << "</td><td>" << text(cond["conesim"]) << "</td><td>"
          << text(cond["thesis"]) << "</td></tr>\n";
    h << "</table>\n";
    for (const json& t : c["tables"]) {
      if (t["study"] != study) continue;
      h << "<h3>" << text(t["title"]) << "</h3>\n<p>" << text(t["note"]) << "</p>\n<table><tr>";
      for (const json& hd : t["header"]) h << "<th>" << text(hd) << "</th>";
      h << "</tr>\n";
      for (const json& row : t["rows"]) {
        h << "<tr>";
        for (const json& v : row) h << "<td>" << text(v) << "</td>";
        h << "</tr>\n";
      }
      h << "</table>\n";
    }
    for (const json& f : c["figures"])
      if (f["study"] == study)
        h << "<p>" << text(f["title"]) << "<br><img src=\"" << text(f["file"]) << "\"></p>\n";
  }
  h << "</body></html>\n";
  return h.str();
}

namespace {

// plan.json of a shard or a rerun: the whole list, and the study's arguments for the merge
json compare_plan_json(const fs::path& self, const StudyPlan& plan, const CompareOptions& o,
                       const std::vector<size_t>& picked) {
  std::vector<std::string> ids, dirs;
  std::vector<double> costs;
  for (const StudyRun& r : plan.runs) {
    ids.push_back(r.id());
    dirs.push_back(r.dir.generic_string());
    costs.push_back(r.cost);
  }
  json p = shard_plan_json("conesim compare plan", self, o.args, ids, dirs, costs, o.shard, picked,
                           o.jobs);
  json tracks = json::array();
  for (const fs::path& f : o.track_files) tracks.push_back(fs::absolute(f).string());
  p["study"] = o.study;
  p["tracks"] = tracks;
  p["seeds"] = o.seeds;
  p["sets"] = o.sets;
  p["plot"] = o.plot;
  return p;
}

// the figures, compare.json, compare.md and compare.html; the failed runs on `out`; the status
int write_compare(json& c, const StudyPlan& plan, const std::vector<StudyResult>& results,
                  const fs::path& out_dir, bool plot, double wall_s, std::ostream& out,
                  std::ostream& progress) {
  if (plot) draw_figures(plan, results, out_dir, c["figures"], progress);
  std::ofstream(out_dir / "compare.json") << json_text(c, 2) << "\n";
  std::ofstream(out_dir / "compare.md") << compare_markdown(c);
  std::ofstream(out_dir / "compare.html") << compare_html(c);
  const size_t failed = c["failed_runs"].size();
  for (const json& f : c["failed_runs"])
    out << "FAILED " << f["id"].get<std::string>() << " (" << f["dir"].get<std::string>()
        << "): " << f["reason"].get<std::string>() << "\n";
  out << plan.runs.size() - failed << " of " << plan.runs.size() << " runs gave figures ("
      << fixed(wall_s, 0) << " s); compare.md, compare.json, compare.html in " << out_dir.string()
      << "\n";
  return failed == 0 ? 0 : 1;
}

// a run's metrics.json, null when it has none or a broken one
json read_run_metrics(const fs::path& dir) {
  json m;
  if (std::ifstream in(dir / "metrics.json"); in) {
    try {
      in >> m;
    } catch (const std::exception&) {
      m = json();
    }
  }
  return m.is_object() ? m : json();
}

}  // namespace

std::vector<size_t> selected_study_runs(const StudyPlan& plan, const CompareOptions& o) {
  std::vector<std::string> ids;
  std::vector<double> costs;
  for (const StudyRun& r : plan.runs) {
    ids.push_back(r.id());
    costs.push_back(r.cost);
  }
  return select_runs(ids, costs, o.shard, o.only_ids, "study, --track, --seeds and --set values");
}

json compare_without_timing(json c) {
  if (!c.is_object()) return c;
  for (const char* key : {"command", "wall_time_s", "jobs", "reused_runs", "shards"}) c.erase(key);
  const auto drop_times = [](json& figures) {
    if (!figures.is_object()) return;
    for (const char* key :
         {"update_cpu_ms_median", "update_ms_median", "update_cpu_ms_p99", "update_ms_p99"})
      figures.erase(key);
  };
  if (c.contains("runs") && c["runs"].is_array())
    for (json& run : c["runs"])
      if (run.is_object() && run.contains("lanes"))
        for (auto& [lane, figures] : run["lanes"].items()) drop_times(figures);
  if (c.contains("summary") && c["summary"].is_array())
    for (json& s : c["summary"]) drop_times(s);
  if (c.contains("tables") && c["tables"].is_array()) {
    json kept = json::array();
    for (const json& t : c["tables"])
      if (!t.is_object() || t.value("title", std::string()).rfind("Time per update", 0) != 0)
        kept.push_back(t);
    c["tables"] = kept;
  }
  return c;
}

int run_compare(const fs::path& self, const CompareOptions& o, std::ostream& out,
                std::ostream& progress) {
  using clock = std::chrono::steady_clock;
  const auto start = clock::now();
  const StudyPlan whole = plan_study(o);
  fs::create_directories(o.out_dir);
  check_output_writable(o.out_dir);
  // a shard or a rerun runs its part of the list; plan.json names the whole list for the merge
  const std::vector<size_t> picked = selected_study_runs(whole, o);
  StudyPlan plan = whole;
  plan.runs.clear();
  for (size_t i : picked) plan.runs.push_back(whole.runs[i]);
  if (o.shard.active() || !o.only_ids.empty()) {
    std::ofstream(o.out_dir / "plan.json")
        << json_text(compare_plan_json(self, whole, o, picked), 1) << "\n";
    progress << (o.shard.active() ? "shard " + o.shard.text() : std::string("rerun")) << ": "
             << plan.runs.size() << " of " << whole.runs.size() << " runs; ";
  }
  progress << plan.runs.size() << " runs, " << o.jobs << " at once, into " << o.out_dir.string()
           << "\n";

  // every run a `conesim run` process with its condition's values
  std::vector<StudyResult> results(plan.runs.size());
  // with --reuse, a run that finished before is read, not run (its exit status from its verdict)
  std::vector<ProcessJob> jobs;
  std::vector<size_t> job_run;
  size_t reused = 0;
  for (size_t i = 0; i < plan.runs.size(); ++i) {
    const StudyRun& r = plan.runs[i];
    const fs::path dir = o.out_dir / r.dir;
    if (o.reuse) {
      results[i].metrics = read_run_metrics(dir);
      if (results[i].metrics.is_object()) {
        results[i].exit_code = results[i].metrics.value("passed", false) ? 0 : 1;
        ++reused;
        continue;
      }
    }
    std::vector<std::string> argv = {
        self.string(),          "run",   kScenario,    "--track",  r.track_file.string(), "--seed",
        std::to_string(r.seed), "--out", dir.string(), "--no-plot"};
    for (const std::string& set : r.sets) argv.insert(argv.end(), {"--set", set});
    jobs.push_back({argv, dir / "log.txt"});
    job_run.push_back(i);
  }
  if (reused > 0) progress << reused << " runs reused from " << o.out_dir.string() << "\n";
  size_t done = 0;
  run_processes(
      jobs, o.jobs,
      [&](size_t j) { fs::create_directories(o.out_dir / plan.runs[job_run[j]].dir); },
      [&](size_t j, int exit_code) {
        const size_t i = job_run[j];
        StudyResult& r = results[i];
        r.exit_code = exit_code;
        r.metrics = read_run_metrics(o.out_dir / plan.runs[i].dir);
        if (!r.metrics.is_object())
          r.log_tail = last_log_line(o.out_dir / plan.runs[i].dir / "log.txt");
        ++done;
        progress << "[" << done << "/" << jobs.size() << "] " << plan.runs[i].id() << ": "
                 << (run_usable(r) ? "done" : "FAILED (exit " + std::to_string(exit_code) + ")")
                 << "\n";
      });
  const double wall_s = std::chrono::duration<double>(clock::now() - start).count();

  // interrupted: no outputs (they would look complete); the finished runs stay for --reuse
  if (const int signal = interrupt_signal()) {
    progress << "interrupted by " << signal_name(signal) << ": " << done << " of " << jobs.size()
             << " runs finished; nothing written. Continue with: conesim compare ... --out "
             << o.out_dir.string() << " --reuse\n";
    return interrupted_exit_status(signal);
  }

  json c = compare_json(plan, results, o, wall_s);
  c["reused_runs"] = reused;
  return write_compare(c, plan, results, o.out_dir, o.plot, wall_s, out, progress);
}

bool holds_compare_plan(const std::vector<fs::path>& dirs) {
  for (const fs::path& dir : dirs)
    if (core::is_file(dir / "plan.json"))
      return read_json_file(dir / "plan.json", "a conesim plan.json").value("tool", "") ==
             "conesim compare plan";
  return false;
}

int merge_compare(const MergeOptions& m, std::ostream& out, std::ostream& progress) {
  using clock = std::chrono::steady_clock;
  const auto start = clock::now();
  if (m.dirs.empty()) throw InputError("merge", 0, "no folders to merge");
  if (m.baseline)
    throw InputError("--baseline", 0, "only for regress shards: a comparison has no baseline");
  // each folder: its plan (the whole list) and, when it finished, its compare.json
  struct Part {
    fs::path dir;
    json plan;
    json done;
    std::map<std::string, int> exit_codes;
    std::set<std::string> selected;
  };
  std::vector<Part> parts;
  const Part* whole = nullptr;
  std::vector<std::string> ids;
  for (const fs::path& dir : m.dirs) {
    Part p;
    p.dir = fs::absolute(dir).lexically_normal();
    if (core::is_file(dir / "plan.json"))
      p.plan = read_json_file(dir / "plan.json", "a conesim compare plan.json");
    if (core::is_file(dir / "compare.json")) {
      p.done = read_json_file(dir / "compare.json", "the shard's compare.json");
      for (const json& r : p.done.value("runs", json::array()))
        p.exit_codes[r.value("id", std::string())] = r.value("exit_code", -1);
    }
    if (p.plan.is_object())
      for (const json& id : p.plan.value("selected", json::array()))
        if (id.is_string()) p.selected.insert(id.get<std::string>());
    if (!core::is_folder(dir))
      progress << dir.string() << ": no such folder (its shard never started?)\n";
    else if (p.plan.is_null())
      progress << dir.string() << ": no plan.json (its shard never started?)\n";
    else if (p.done.is_null())
      progress << dir.string() << ": no compare.json: this shard did not finish; its runs that "
               << "wrote metrics.json are taken, the others are missing unless another folder "
               << "has them\n";
    parts.push_back(std::move(p));
  }
  for (const Part& p : parts) {
    if (p.plan.is_null()) continue;
    if (p.plan.value("tool", "") != "conesim compare plan")
      throw InputError((p.dir / "plan.json").string(), 0,
                       "not the plan of `conesim compare --shard`: merge regress shards and "
                       "compare shards apart");
    const std::vector<std::string> these = plan_run_ids(p.plan, p.dir / "plan.json");
    if (!whole) {
      whole = &p;
      ids = these;
    } else if (these != ids) {
      throw InputError((p.dir / "plan.json").string(), 0,
                       "lists other runs than " + (whole->dir / "plan.json").string() +
                           ": these folders are shards of different comparisons (the same "
                           "study, --track, --seeds and --set values make the same list)");
    }
  }
  if (!whole)
    throw InputError(m.dirs.front().string(), 0,
                     "no plan.json in any of the folders: merge takes the --out folders of "
                     "`conesim compare ... --shard I/N`");

  // the study again, from the shards' own arguments
  const json& wp = whole->plan;
  CompareOptions o;
  try {
    o.study = wp.at("study").get<std::string>();
    for (const std::string& t : wp.at("tracks").get<std::vector<std::string>>())
      o.track_files.push_back(t);
    o.seeds = wp.at("seeds").get<std::vector<unsigned long long>>();
    o.sets = wp.at("sets").get<std::vector<std::string>>();
    o.plot = wp.value("plot", true);
    o.jobs = wp.value("jobs", 1);
  } catch (const json::exception& e) {
    throw InputError((whole->dir / "plan.json").string(), 0,
                     std::string("not a conesim compare plan.json: ") + e.what());
  }
  o.out_dir = m.out_dir;
  o.command_line = m.command_line;
  const StudyPlan plan = plan_study(o);
  std::vector<std::string> planned;
  for (const StudyRun& r : plan.runs) planned.push_back(r.id());
  if (planned != ids)
    throw InputError((whole->dir / "plan.json").string(), 0,
                     "the study plans other runs here than the shards did (another conesim "
                     "version, or a track moved): merge with the binary the shards ran");

  // each run's result from the last folder that has it
  std::vector<StudyResult> results(plan.runs.size());
  json folders = json::object();
  std::vector<std::string> missing;
  double wall_s = 0.0;
  for (const Part& p : parts)
    if (p.done.is_object()) wall_s = std::max(wall_s, p.done.value("wall_time_s", 0.0));
  const fs::path out_abs = fs::absolute(m.out_dir).lexically_normal();
  for (size_t i = 0; i < plan.runs.size(); ++i) {
    const std::string id = plan.runs[i].id();
    StudyResult& r = results[i];
    r.missing = true;
    for (auto p = parts.rbegin(); p != parts.rend() && r.missing; ++p) {
      const fs::path dir = p->dir / plan.runs[i].dir;
      if (const auto it = p->exit_codes.find(id); it != p->exit_codes.end()) {
        r.exit_code = it->second;
        r.metrics = read_run_metrics(dir);
        if (!r.metrics.is_object()) r.log_tail = last_log_line(dir / "log.txt");
        r.missing = false;
      } else if (p->done.is_null() && p->selected.count(id)) {
        // a shard that did not finish: its finished runs count, as --reuse reads them
        r.metrics = read_run_metrics(dir);
        if (!r.metrics.is_object()) continue;
        r.exit_code = r.metrics.value("passed", false) ? 0 : 1;
        r.missing = false;
      }
      if (!r.missing) folders[id] = dir.lexically_relative(out_abs).generic_string();
    }
    if (r.missing) missing.push_back(id);
  }

  fs::create_directories(m.out_dir);
  check_output_writable(m.out_dir);
  progress << "merged " << parts.size() << " folders: " << plan.runs.size() - missing.size()
           << " of " << plan.runs.size() << " runs\n";
  json c = compare_json(plan, results, o, wall_s);
  c["reused_runs"] = 0;
  const std::string rerun = missing.empty() ? "" : rerun_command(wp, "compare", m.out_dir);
  json dirs = json::array();
  for (const Part& p : parts) dirs.push_back(p.dir.string());
  c["shards"] = {{"count", wp["shard"].is_object() ? wp["shard"].value("count", 0) : 0},
                 {"folders", dirs},
                 {"run_folders", folders},
                 {"missing_runs", missing},
                 {"rerun", rerun.empty() ? json(nullptr) : json(rerun)},
                 {"merge_time_s", std::chrono::duration<double>(clock::now() - start).count()}};
  int status = write_compare(c, plan, results, m.out_dir, o.plot, wall_s, out, progress);
  for (const std::string& id : missing) out << "missing (no result): " << id << "\n";
  if (!missing.empty())
    out << missing.size() << " runs missing; run only them and merge again with:\n  " << rerun
        << "\n";
  if (m.expect) {
    const json expected = read_json_file(*m.expect, "a conesim compare.json");
    const std::vector<std::string> diff =
        json_differences(compare_without_timing(expected), compare_without_timing(c));
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

int rerun_missing_compare(const fs::path& self, CompareOptions o, const fs::path& merge_dir,
                          std::ostream& out, std::ostream& progress) {
  return rerun_then_merge(
      merge_dir, "compare.json", o.command_line,
      [&](const std::vector<std::string>& ids, const fs::path& dir) {
        o.only_ids = ids;
        o.out_dir = dir;
        o.shard = {};
        o.reuse = false;
        run_compare(self, o, out, progress);
      },
      [&](const MergeOptions& m) { return merge_compare(m, out, progress); }, out, progress);
}

}  // namespace conesim::sim
