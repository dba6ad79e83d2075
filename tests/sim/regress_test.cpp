#include "sim/regress.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <unistd.h>

#include "core/error.hpp"
#include "sim/json_text.hpp"
#include "sim/run.hpp"
#include "sim/scenario.hpp"
#include "tracks/track.hpp"

namespace conesim::sim {
namespace {

using nlohmann::json;

// a metrics.json as `conesim run` writes it, with the events the referee reports
json metrics(bool passed, double best_lap_s) {
  json m = {
      {"scenario", "trackdrive"},
      {"event", "trackdrive"},
      {"track", "FSG19"},
      {"seed", 1},
      {"completed", true},
      {"dnf_reason", ""},
      {"laps", 2},
      {"lap_times_s", {best_lap_s + 3.0, best_lap_s}},
      {"penalties", {{"cones_hit", passed ? 0 : 1}, {"off_course", 0}}},
      {"final_time_s", 2 * best_lap_s + 3.0},
      {"wall_time_s", 4.0},
      {"real_time_factor", 12.5},
      {"lap_time_bound_s", best_lap_s / 1.25},
      {"passed", passed},
      {"pass_failures", json::array()},
      {"slam",
       {{"graph", {{"map_rmse_m", 0.05}, {"ate_rmse_m", 0.04}, {"da_correct_fraction", 0.998}}}}},
      {"perception", {{"mode", "cone_sensor"}}},
      {"events", json::array()}};
  if (!passed) {
    m["pass_failures"] = {"1 cones hit, at most 0 allowed"};
    m["events"] = {{{"kind", "cone_hit"},
                    {"t_s", 31.25},
                    {"lap", 2},
                    {"x_m", 12.34},
                    {"y_m", -4.5},
                    {"yaw_rad", 0.1},
                    {"reason", "hit blue cone 17"},
                    {"penalty_s", 2.0},
                    {"cone_id", 17},
                    {"cone_class", "blue"},
                    {"cone_x_m", 13.0},
                    {"cone_y_m", -3.9}}};
  }
  return m;
}

RegressionRun run(const std::string& track, unsigned long long seed) {
  return {"trackdrive", track, "", seed, "trackdrive/" + track + "-s" + std::to_string(seed)};
}

TEST(Regress, RowTakesTheDrivingBackEndsFiguresNotAShadows) {
  // "ekf" sorts before "graph": the row must follow slam_driving, not the first key
  json m = metrics(true, 20.0);
  m["slam_driving"] = "graph";
  m["slam"]["ekf"] = {{"map_rmse_m", 0.5}, {"ate_rmse_m", 0.6}, {"da_correct_fraction", 0.9}};
  const RunRow r = make_row(run("pacsim/FSG19", 1), m, 0);
  EXPECT_DOUBLE_EQ(r.map_rmse_m, 0.05);
  EXPECT_DOUBLE_EQ(r.ate_rmse_m, 0.04);
  EXPECT_DOUBLE_EQ(r.da_correct_fraction, 0.998);
}

TEST(Regress, RowCarriesVerdictReasonPlaceAndFigures) {
  const RunRow r = make_row(run("pacsim/FSG19", 1), metrics(false, 20.0), 1);
  EXPECT_FALSE(r.passed);
  ASSERT_EQ(r.reasons.size(), 1u);
  EXPECT_EQ(r.reasons[0], "1 cones hit, at most 0 allowed");
  ASSERT_EQ(r.events.size(), 1u);
  EXPECT_EQ(r.events[0].kind, "cone_hit");
  EXPECT_DOUBLE_EQ(r.events[0].x_m, 12.34);
  EXPECT_DOUBLE_EQ(r.best_lap_s, 20.0);
  EXPECT_NEAR(r.bound_ratio, 1.25, 1e-12);
  EXPECT_DOUBLE_EQ(r.map_rmse_m, 0.05);
  EXPECT_EQ(r.id, "trackdrive | pacsim/FSG19 | seed 1");
}

TEST(Regress, CrashWithoutMetricsFailsWithTheExitAndLogLine) {
  const RunRow r = make_row(run("x", 1), json(), 134, "terminate called after an exception");
  EXPECT_FALSE(r.passed);
  ASSERT_EQ(r.reasons.size(), 1u);
  EXPECT_NE(r.reasons[0].find("exit 134 (signal 6)"), std::string::npos);
  EXPECT_NE(r.reasons[0].find("terminate called"), std::string::npos);
}

TEST(Regress, LayoutRefusedByThePreRunCheckIsListedApartNotFailed) {
  const std::string said =
      "conesim: eufs/SmallCircle.csv: not drivable by this car: the yellow cone at (-2.9, -0.5) "
      "stands under the car where it starts";
  std::vector<RunRow> rows = {make_row(run("a", 1), metrics(true, 20.0), 0),
                              make_row(run("b", 1), json(), 2, said),
                              make_row(run("c", 1), json(), 2, "conesim: c.csv:3: x: expected")};
  EXPECT_TRUE(rows[1].refused);
  EXPECT_FALSE(rows[1].passed);
  EXPECT_NE(rows[1].reasons.at(0).find("stands under the car"), std::string::npos);
  EXPECT_FALSE(rows[2].refused);  // a malformed file is a failure
  EXPECT_EQ(row_to_json(rows[1])["verdict"], "refused");
  EXPECT_TRUE(row_from_json(row_to_json(rows[1])).refused);
  // JUnit: the refusal is skipped with its reason, the malformed file a failure
  const std::string x = junit_xml(rows, 1.0, nullptr);
  EXPECT_NE(x.find("failures=\"1\""), std::string::npos);
  EXPECT_NE(x.find("skipped=\"1\""), std::string::npos);
  EXPECT_NE(x.find("<skipped message=\"no metrics.json: exit 2: " + said), std::string::npos);
  // failures first, then refusals, then passes
  sort_failures_first(rows);
  EXPECT_EQ(rows[0].track, "c");
  EXPECT_EQ(rows[1].track, "b");
  EXPECT_EQ(rows[2].track, "a");
  // a run that passed in the baseline and is refused now is a regression
  const std::vector<RunRow> before = {make_row(run("b", 1), metrics(true, 20.0), 0)};
  std::vector<RunRow> now = {make_row(run("b", 1), json(), 2, said)};
  EXPECT_FALSE(compare_to_baseline(now, before).regressions.empty());
}

TEST(Regress, PassedMetricsButNonZeroExitIsAFailure) {
  const RunRow r = make_row(run("x", 1), metrics(true, 20.0), 3, "conesim: boom");
  EXPECT_FALSE(r.passed);
  EXPECT_EQ(r.reasons.at(0), "exit 3: conesim: boom");
}

TEST(Regress, DnfHasNoFinalTime) {
  json m = metrics(false, 20.0);
  m["completed"] = false;
  m["final_time_s"] = 0.0;
  EXPECT_TRUE(std::isnan(make_row(run("x", 1), m, 1).final_time_s));
}

TEST(Regress, FailedRunSortsFirst) {
  std::vector<RunRow> rows = {make_row(run("a", 1), metrics(true, 20.0), 0),
                              make_row(run("b", 1), metrics(true, 20.0), 0),
                              make_row(run("c", 1), metrics(false, 20.0), 1)};
  sort_failures_first(rows);
  EXPECT_EQ(rows[0].track, "c");
  EXPECT_EQ(rows[1].track, "a");
  EXPECT_EQ(rows[2].track, "b");
}

TEST(Regress, RowSurvivesTheJsonRoundTrip) {
  const RunRow r = make_row(run("pacsim/FSG19", 3), metrics(false, 20.0), 1);
  const RunRow back = row_from_json(json::parse(row_to_json(r).dump()));
  EXPECT_EQ(back.id, r.id);
  EXPECT_EQ(back.passed, r.passed);
  EXPECT_EQ(back.reasons, r.reasons);
  EXPECT_DOUBLE_EQ(back.best_lap_s, r.best_lap_s);
  EXPECT_DOUBLE_EQ(back.map_rmse_m, r.map_rmse_m);
  EXPECT_EQ(back.cones_hit, 1);
  EXPECT_EQ(back.events.size(), 1u);
  EXPECT_TRUE(std::isnan(back.perception_recall));
}

// a baseline is a file a user hands over: a count that is no whole number is named, with its
// run, rather than cast (a cast of 4e97 to int is undefined behaviour)
TEST(Baseline, CountThatIsNoWholeNumberIsNamedWithItsRun) {
  const std::string ok = R"({"runs":[{"id":"a","cones_hit":2,"seed":7}]})";
  const std::vector<RunRow> rows = parse_baseline(ok, "base.json");
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_EQ(rows[0].cones_hit, 2);
  EXPECT_EQ(rows[0].seed, 7u);
  for (const std::string& bad :
       {std::string(R"({"runs":[{"id":"a"},{"id":"b","cones_hit":4.4e97}]})"),
        std::string(R"({"runs":[{"id":"a"},{"id":"b","cones_hit":1.5}]})"),
        std::string(R"({"runs":[{"id":"a"},{"id":"b","cones_hit":-3}]})")}) {
    try {
      parse_baseline(bad, "base.json");
      ADD_FAILURE() << "accepted " << bad;
    } catch (const core::InputError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("base.json"), std::string::npos) << what;
      EXPECT_NE(what.find("runs[1].cones_hit"), std::string::npos) << what;
    }
  }
}

TEST(Baseline, PassToFailIsARegression) {
  const std::vector<RunRow> before = {make_row(run("a", 1), metrics(true, 20.0), 0)};
  std::vector<RunRow> now = {make_row(run("a", 1), metrics(false, 20.0), 1)};
  const BaselineComparison c = compare_to_baseline(now, before);
  ASSERT_FALSE(c.regressions.empty());
  EXPECT_NE(c.regressions[0].find("passed in the baseline, fails now"), std::string::npos);
  EXPECT_FALSE(now[0].regressions.empty());
}

TEST(Baseline, LapTimeOnePercentWorseIsNoiseTenPercentIsARegression) {
  const std::vector<RunRow> before = {make_row(run("a", 1), metrics(true, 30.0), 0)};
  std::vector<RunRow> one_percent = {make_row(run("a", 1), metrics(true, 30.3), 0)};
  EXPECT_TRUE(compare_to_baseline(one_percent, before).regressions.empty());
  std::vector<RunRow> ten_percent = {make_row(run("a", 1), metrics(true, 33.0), 0)};
  const BaselineComparison c = compare_to_baseline(ten_percent, before);
  ASSERT_FALSE(c.regressions.empty());
  EXPECT_NE(c.regressions[0].find("best lap"), std::string::npos);
  // faster is never a regression
  std::vector<RunRow> faster = {make_row(run("a", 1), metrics(true, 25.0), 0)};
  EXPECT_TRUE(compare_to_baseline(faster, before).regressions.empty());
}

TEST(Baseline, MapRmseOfOneRunWithinNoiseIsNotARegressionBeyondIs) {
  json m = metrics(true, 20.0);
  const std::vector<RunRow> before = {make_row(run("a", 1), m, 0)};
  // 0.05 -> 0.095 m: what a 1e-8 change of a driver setting did to one GraphSLAM run
  m["slam"]["graph"]["map_rmse_m"] = 0.095;
  std::vector<RunRow> now = {make_row(run("a", 1), m, 0)};
  EXPECT_TRUE(compare_to_baseline(now, before).regressions.empty());
  m["slam"]["graph"]["map_rmse_m"] = 0.12;
  now = {make_row(run("a", 1), m, 0)};
  EXPECT_EQ(compare_to_baseline(now, before).regressions.size(), 1u);
}

TEST(Baseline, MedianMapRmseOverAScenarioCatchesASmallerDrift) {
  std::vector<RunRow> before, drifted, noisy;
  for (unsigned long long seed = 1; seed <= 5; ++seed) {
    json m = metrics(true, 20.0);
    m["slam"]["graph"]["map_rmse_m"] = 0.03 + 0.001 * seed;
    before.push_back(make_row(run("a", seed), m, 0));
    // every run 0.01 m worse: within each run's noise, beyond the median's
    m["slam"]["graph"]["map_rmse_m"] = 0.04 + 0.001 * seed;
    drifted.push_back(make_row(run("a", seed), m, 0));
    // runs shuffled about, the median 0.002 m worse
    m["slam"]["graph"]["map_rmse_m"] = seed == 3 ? 0.035 : 0.03 + 0.001 * (6 - seed);
    noisy.push_back(make_row(run("a", seed), m, 0));
  }
  const BaselineComparison c = compare_to_baseline(drifted, before);
  ASSERT_EQ(c.median_regressions.size(), 1u);
  EXPECT_NE(c.median_regressions[0].find("trackdrive: median SLAM map RMSE over 5 runs"),
            std::string::npos);
  for (const RunRow& r : drifted) EXPECT_TRUE(r.regressions.empty());
  EXPECT_TRUE(compare_to_baseline(noisy, before).regressions.empty());
  // the medians' testcase fails in junit.xml
  EXPECT_NE(junit_xml(drifted, 1.0, &c).find("classname=\"baseline\" name=\"medians\""),
            std::string::npos);
}

TEST(Baseline, MissingAndNewRunsAreListedNotRegressions) {
  const std::vector<RunRow> before = {make_row(run("a", 1), metrics(true, 20.0), 0),
                                      make_row(run("b", 1), metrics(true, 20.0), 0)};
  std::vector<RunRow> now = {make_row(run("a", 1), metrics(true, 20.0), 0),
                             make_row(run("c", 1), metrics(true, 20.0), 0)};
  const BaselineComparison c = compare_to_baseline(now, before);
  EXPECT_TRUE(c.regressions.empty());
  ASSERT_EQ(c.missing.size(), 1u);
  EXPECT_EQ(c.missing[0], "trackdrive | b | seed 1");
  ASSERT_EQ(c.added.size(), 1u);
  EXPECT_EQ(c.added[0], "trackdrive | c | seed 1");
}

TEST(Junit, OneTestcasePerRunWithTheReasonsOnFailures) {
  std::vector<RunRow> rows = {make_row(run("pacsim/FSG19", 1), metrics(false, 20.0), 1),
                              make_row(run("a&b<c>", 2), metrics(true, 20.0), 0)};
  const std::string xml = junit_xml(rows, 12.0);
  EXPECT_NE(xml.find("tests=\"2\" failures=\"1\""), std::string::npos);
  EXPECT_NE(xml.find("classname=\"trackdrive\" name=\"pacsim/FSG19 seed 1\""), std::string::npos);
  EXPECT_NE(xml.find("message=\"1 cones hit, at most 0 allowed\""), std::string::npos);
  EXPECT_NE(xml.find("hit blue cone 17"), std::string::npos);
  EXPECT_NE(xml.find("name=\"a&amp;b&lt;c&gt; seed 2\""), std::string::npos);
}

TEST(Seeds, ListsAndRanges) {
  EXPECT_EQ(parse_seeds("1,2,3"), (std::vector<unsigned long long>{1, 2, 3}));
  EXPECT_EQ(parse_seeds("1-4"), (std::vector<unsigned long long>{1, 2, 3, 4}));
  EXPECT_EQ(parse_seeds("2-3,9"), (std::vector<unsigned long long>{2, 3, 9}));
  EXPECT_THROW(parse_seeds("a"), core::InputError);
  EXPECT_THROW(parse_seeds("5-1"), core::InputError);
  EXPECT_THROW(parse_seeds(""), core::InputError);
  EXPECT_THROW(parse_seeds("1,,2"), core::InputError);
}

TEST(Table, EveryFailRowCarriesItsReason) {
  std::vector<RunRow> rows = {make_row(run("pacsim/FSG19", 1), metrics(false, 20.0), 1)};
  std::ostringstream out;
  print_table(rows, out);
  EXPECT_NE(out.str().find("FAIL"), std::string::npos);
  EXPECT_NE(out.str().find("    1 cones hit, at most 0 allowed"), std::string::npos);
  EXPECT_NE(out.str().find("cone_hit lap 2 t 31.2 s at (12.3, -4.5)"), std::string::npos);
}

// --- shards and their merge --------------------------------------------------------------------

namespace fs = std::filesystem;

TEST(Shard, BadShardNamesTheOptionAndWhatItExpected) {
  for (const char* bad : {"0/4", "5/4", "x", "1/0", "2/", "/4", "-1/4", "1.5/4"}) {
    try {
      parse_shard(bad);
      ADD_FAILURE() << bad << " was taken";
    } catch (const core::InputError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("--shard"), std::string::npos) << what;
      EXPECT_NE(what.find("I/N"), std::string::npos) << what;
      EXPECT_NE(what.find(bad), std::string::npos) << what;
    }
  }
  EXPECT_EQ(parse_shard("3/4").index, 3);
  EXPECT_EQ(parse_shard("3/4").count, 4);
  EXPECT_EQ(parse_shard("1/1").text(), "1/1");
}

// costs like a mixed study's: acceleration, skidpad, circuits, trackdrives with SLAM
std::vector<double> mixed_costs(size_t n) {
  std::vector<double> c;
  for (size_t i = 0; i < n; ++i)
    c.push_back(std::vector<double>{0.25, 0.8, 1.0, 1.7, 10.0, 15.0, 3.2}[i % 7] + 0.01 * (i % 5));
  return c;
}

TEST(Shard, SlicesPartitionTheListExactlyAndAreTheSameEveryTime) {
  const std::vector<double> costs = mixed_costs(41);
  for (int n = 1; n <= 9; ++n) {
    const auto shards = shard_runs(costs, n);
    ASSERT_EQ(shards.size(), static_cast<size_t>(n));
    std::vector<int> seen(costs.size(), 0);
    for (const auto& s : shards) {
      EXPECT_TRUE(std::is_sorted(s.begin(), s.end())) << "a shard runs in run order";
      for (size_t i : s) ++seen.at(i);
    }
    for (size_t i = 0; i < seen.size(); ++i) EXPECT_EQ(seen[i], 1) << "run " << i << ", " << n;
    EXPECT_EQ(shard_runs(costs, n), shards);
  }
  // more shards than runs: the extra shards are empty, every run still in one
  const auto many = shard_runs({1.0, 2.0}, 4);
  EXPECT_EQ(many[0], std::vector<size_t>{1});
  EXPECT_EQ(many[1], std::vector<size_t>{0});
  EXPECT_TRUE(many[2].empty() && many[3].empty());
}

TEST(Shard, SlicesAreBalancedByExpectedCost) {
  const std::vector<double> costs = mixed_costs(40);
  double biggest = 0.0, total = 0.0;
  for (double c : costs) {
    biggest = std::max(biggest, c);
    total += c;
  }
  for (int n : {2, 3, 4, 8}) {
    std::vector<double> load;
    for (const auto& s : shard_runs(costs, n)) {
      double sum = 0.0;
      for (size_t i : s) sum += costs[i];
      load.push_back(sum);
    }
    const auto [lo, hi] = std::minmax_element(load.begin(), load.end());
    EXPECT_LE(*hi - *lo, biggest) << n << " shards";
    // within 10 % of a perfect split (or one run's cost, whichever is more)
    EXPECT_LE(*hi, std::max(1.10 * total / n, total / n + biggest)) << n << " shards";
  }
  // equal costs: equal counts, not the first shards full and the last ones empty
  for (const auto& s : shard_runs(std::vector<double>(40, 1.0), 4)) EXPECT_EQ(s.size(), 10u);
  // a trackdrive with SLAM costs more than an acceleration run; longer tracks cost more
  EXPECT_GT(run_cost(core::EventType::kTrackdrive, 300, true, 0, false),
            run_cost(core::EventType::kAcceleration, 0, false, 0, false) * 20);
  EXPECT_GT(run_cost(core::EventType::kAutocross, 600, false, 0, false),
            run_cost(core::EventType::kAutocross, 300, false, 0, false));
}

// a scenario's own circuit is priced by its length (generated from the run's seed, as
// `conesim run --seed` makes it): a long circuit's trackdrive costs more than a short one's
TEST(Shard, AScenariosOwnCircuitIsPricedByTheCircuitTheSeedMakes) {
  const fs::path trackdrive = find_scenario("trackdrive");
  std::vector<double> lengths;
  for (unsigned long long seed : {1ull, 4ull, 9ull}) {
    const double length = scenario_lap_length_m(trackdrive, {}, seed);
    const tracks::Track made = scenario_track(load_scenario(trackdrive, {}, seed));
    double expected = 0.0;
    for (size_t i = 0; i < made.centre_line.size(); ++i)
      expected += (made.centre_line[(i + 1) % made.centre_line.size()] - made.centre_line[i]).norm();
    EXPECT_NEAR(length, expected, 1e-6) << "seed " << seed;
    // FSG: a trackdrive lap is 200 m to 500 m
    EXPECT_GT(length, 200.0);
    EXPECT_LT(length, 500.0);
    lengths.push_back(length);
  }
  // seeds 1 and 9 make circuits of 404 and 287 m: their costs differ as much
  EXPECT_GT(std::abs(lengths[0] - lengths[2]), 50.0);
  const Scenario s = load_scenario(trackdrive);
  EXPECT_GT(scenario_run_cost(s, lengths[0], false) - kRunStartCost,
            1.3 * (scenario_run_cost(s, lengths[2], false) - kRunStartCost));
  // a fixed layout has no lap to measure; a track that cannot be made costs the usual lap
  EXPECT_EQ(scenario_lap_length_m(find_scenario("skidpad"), {}, 1), 0.0);
  EXPECT_EQ(scenario_lap_length_m(trackdrive, {"track.file=/nonexistent/track.yaml"}, 1), 0.0);
  // exploring all the way costs more per metre than ten laps of which nine are fast; the plot
  // of every run is priced
  EXPECT_GT(run_cost(core::EventType::kAutocross, 300, false, 0, false),
            1.5 * run_cost(core::EventType::kTrackdrive, 300, false, 0, false, 1));
  EXPECT_NEAR(run_cost(core::EventType::kAcceleration, 0, false, 0, false, 0, true) -
                  run_cost(core::EventType::kAcceleration, 0, false, 0, false, 0, false),
              kRunPlotCost, 1e-3);
}

// a folder as `conesim regress --shard I/N` leaves it: plan.json (the whole list) and, unless the
// shard died, summary.json of its runs
struct FakeStudy {
  fs::path root;
  std::vector<RegressionRun> runs;
  std::vector<RunRow> rows;
  FakeStudy() {
    root = fs::temp_directory_path() / ("conesim-merge-test-" + std::to_string(getpid()));
    fs::remove_all(root);
    fs::create_directories(root);
    for (unsigned long long seed = 1; seed <= 7; ++seed) {
      std::string track = "t";
      track += std::to_string(seed % 3);
      runs.push_back(run(track, seed));
      runs.back().cost = 1.0 + static_cast<double>(seed % 4);
      // seed 4 fails: failures sort first, in the merge as in the whole run
      rows.push_back(make_row(runs.back(), metrics(seed != 4, 20.0 + seed), seed == 4 ? 1 : 0));
    }
  }
  ~FakeStudy() { fs::remove_all(root); }
  json plan(int index, int count) const {
    json list = json::array();
    for (const RegressionRun& r : runs) list.push_back({{"id", r.id()}, {"dir", r.dir}});
    return {{"binary", "/opt/conesim"},
            {"args", {"trackdrive", "--seeds", "1-7", "--shard", "1/3", "--out", "x"}},
            {"shard", {{"index", index}, {"count", count}}},
            {"jobs", 1},
            {"baseline", nullptr},
            {"skipped_tracks", json::array()},
            {"event_mismatches_left_out", 0},
            {"runs", list}};
  }
  // the unsharded summary, and the shard folders
  fs::path whole() const {
    std::vector<RunRow> all = rows;
    sort_failures_first(all);
    RegressOptions o;
    const fs::path f = root / "whole.json";
    std::ofstream(f) << json_text(summary_json(all, RegressionPlan{}, o, 9.0, nullptr), 2);
    return f;
  }
  fs::path shard(int index, int count, bool finished) const {
    const fs::path dir = root / ("shard-" + std::to_string(index));
    fs::create_directories(dir);
    std::ofstream(dir / "plan.json") << plan(index, count).dump();
    if (!finished) return dir;
    std::vector<double> costs;
    for (const RegressionRun& r : runs) costs.push_back(r.cost);
    std::vector<RunRow> mine;
    const auto shards = shard_runs(costs, count);
    for (size_t i : shards[static_cast<size_t>(index - 1)]) mine.push_back(rows[i]);
    sort_failures_first(mine);
    RegressOptions o;
    o.command_line = "conesim regress --shard " + std::to_string(index);
    std::ofstream(dir / "summary.json")
        << json_text(summary_json(mine, RegressionPlan{}, o, 3.0 + index, nullptr), 2);
    return dir;
  }
  static json read(const fs::path& f) {
    std::ifstream in(f);
    return json::parse(in);
  }
};

TEST(Merge, ShardsMergeIntoTheUnshardedSummaryApartFromTiming) {
  FakeStudy study;
  MergeOptions m;
  for (int k = 1; k <= 3; ++k) m.dirs.push_back(study.shard(k, 3, true));
  m.out_dir = study.root / "merged";
  m.expect = study.whole();
  std::ostringstream out, progress;
  EXPECT_EQ(merge_regression(m, out, progress), 1) << "one run failed";
  EXPECT_NE(out.str().find("same as"), std::string::npos) << out.str();
  const json merged = FakeStudy::read(m.out_dir / "summary.json");
  const json whole = FakeStudy::read(*m.expect);
  EXPECT_EQ(summary_without_timing(merged), summary_without_timing(whole));
  EXPECT_TRUE(summary_differences(whole, merged).empty());
  EXPECT_EQ(merged["runs"][0]["seed"], 4) << "the failure first, as unsharded";
  EXPECT_TRUE(merged["shards"]["missing_runs"].empty());
  EXPECT_TRUE(fs::exists(m.out_dir / "junit.xml"));
  EXPECT_TRUE(fs::exists(m.out_dir / "summary.html"));
  // a changed figure is found, and named by its place
  json other = whole;
  other["runs"][1]["best_lap_s"] = 99.0;
  ASSERT_EQ(summary_differences(other, merged).size(), 1u);
  EXPECT_NE(summary_differences(other, merged)[0].find("/runs/1/best_lap_s"), std::string::npos);
}

TEST(Merge, ADeadShardsRunsAreMissingWithTheCommandThatRunsOnlyThem) {
  FakeStudy study;
  MergeOptions m;
  m.dirs = {study.shard(1, 3, true), study.shard(2, 3, false), study.shard(3, 3, true)};
  m.out_dir = study.root / "merged";
  std::ostringstream out, progress;
  EXPECT_EQ(merge_regression(m, out, progress), 1);
  std::vector<double> costs;
  for (const RegressionRun& r : study.runs) costs.push_back(r.cost);
  const auto lost = shard_runs(costs, 3)[1];
  ASSERT_FALSE(lost.empty());
  const json merged = FakeStudy::read(m.out_dir / "summary.json");
  EXPECT_EQ(merged["shards"]["missing_runs"].size(), lost.size());
  EXPECT_EQ(merged["runs"].size() + lost.size(), study.runs.size());
  for (size_t i : lost) {
    const std::string id = study.runs[i].id();
    EXPECT_NE(out.str().find("missing (no result): " + id), std::string::npos) << out.str();
    EXPECT_NE(merged["shards"]["missing_runs"].dump().find(id), std::string::npos);
  }
  // the rerun: the shards' arguments without --shard, --out and --jobs, and the merge folder
  const std::string rerun = merged["shards"]["rerun"];
  EXPECT_EQ(rerun, "/opt/conesim regress trackdrive --seeds 1-7 --only-missing " +
                       fs::absolute(m.out_dir).lexically_normal().string());
  EXPECT_NE(out.str().find(rerun), std::string::npos);
  // JUnit fails each missing run; the HTML lists them
  std::ifstream junit(m.out_dir / "junit.xml");
  const std::string x{std::istreambuf_iterator<char>(junit), {}};
  EXPECT_NE(x.find("classname=\"missing\""), std::string::npos);
  EXPECT_NE(x.find("failures=\"" + std::to_string(lost.size() + 1) + "\""), std::string::npos);
}

TEST(Merge, FoldersOfDifferentStudiesAreRefused) {
  FakeStudy study;
  MergeOptions m;
  m.dirs = {study.shard(1, 2, true), study.root / "other"};
  fs::create_directories(m.dirs[1]);
  json plan = study.plan(2, 2);
  plan["runs"].erase(0);
  std::ofstream(m.dirs[1] / "plan.json") << plan.dump();
  m.out_dir = study.root / "merged";
  std::ostringstream out, progress;
  EXPECT_THROW(merge_regression(m, out, progress), core::InputError);
  // and a folder that is no shard at all
  m.dirs = {study.root / "nothing"};
  EXPECT_THROW(merge_regression(m, out, progress), core::InputError);
}

}  // namespace
}  // namespace conesim::sim
