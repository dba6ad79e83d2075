// `conesim compare`: the studies expand into the same run list every time, and compare.json
// holds the theses' figures beside the runs' and names a run that gave none.

#include "sim/compare.hpp"

#include <gtest/gtest.h>

#include <set>

#include "core/error.hpp"

namespace conesim::sim {
namespace {

using nlohmann::json;

CompareOptions options(const std::string& study) {
  CompareOptions o;
  o.study = study;
  o.out_dir = "unused";
  return o;
}

std::vector<std::string> ids(const StudyPlan& plan) {
  std::vector<std::string> out;
  for (const StudyRun& r : plan.runs) out.push_back(r.id() + " @ " + r.dir.string());
  return out;
}

TEST(CompareStudies, ExpandDeterministicallyIntoDistinctRuns) {
  for (const std::string& study : study_names()) {
    const StudyPlan a = plan_study(options(study));
    const StudyPlan b = plan_study(options(study));
    EXPECT_EQ(ids(a), ids(b)) << study;
    ASSERT_FALSE(a.runs.empty()) << study;
    // every run has a folder of its own
    std::set<std::string> dirs;
    for (const StudyRun& r : a.runs) dirs.insert(r.dir.string());
    EXPECT_EQ(dirs.size(), a.runs.size()) << study;
    // each condition states what conesim runs and what the thesis ran
    for (const StudyCondition& c : a.conditions) {
      EXPECT_FALSE(c.conesim.empty()) << study << " " << c.name;
      EXPECT_FALSE(c.thesis.empty()) << study << " " << c.name;
    }
  }
  // all is the three studies, in order
  const StudyPlan all = plan_study(options("all"));
  std::vector<std::string> joined;
  for (const char* s : {"fst", "raceup", "monash"})
    for (const std::string& id : ids(plan_study(options(s)))) joined.push_back(id);
  EXPECT_EQ(ids(all), joined);
  // the FST study runs fssim's FSG first, under Table 4.1's noise, over five seeds
  const StudyPlan fst = plan_study(options("fst"));
  EXPECT_EQ(fst.runs[0].track_label, "fssim/FSG");
  EXPECT_EQ(fst.runs[4].seed, 5u);
  const auto& sets = fst.runs[0].sets;
  EXPECT_NE(std::find(sets.begin(), sets.end(), "sensors.cone_sensor.range_sigma_m=0.4"),
            sets.end());
}

TEST(CompareStudies, GivenTracksSeedsAndSetsReplaceTheStudysOwn) {
  CompareOptions o = options("monash");
  o.track_files = {std::string(CONESIM_TEST_DATA) + "/tracks/pacsim/FSE22.yaml"};
  o.seeds = {7};
  o.sets = {"driver.trackdrive_laps=1"};
  const StudyPlan plan = plan_study(o);
  ASSERT_EQ(plan.runs.size(), 2u);  // two conditions, one track, one seed
  EXPECT_EQ(plan.runs[0].track_label, "pacsim/FSE22");
  EXPECT_EQ(plan.runs[0].seed, 7u);
  EXPECT_EQ(plan.runs[0].sets.back(), "driver.trackdrive_laps=1");
}

TEST(CompareStudies, BadInputNamesWhatWasExpected) {
  try {
    plan_study(options("fsg"));
    FAIL() << "no error";
  } catch (const core::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("expected one of fst, raceup, monash, all, got 'fsg'"),
              std::string::npos)
        << e.what();
  }
  CompareOptions bad_set = options("fst");
  bad_set.sets = {"slam.shadow=[graph+no_gps]"};
  EXPECT_THROW(plan_study(bad_set), core::InputError);
  CompareOptions no_track = options("fst");
  no_track.track_files = {"/nonexistent/track.yaml"};
  EXPECT_THROW(plan_study(no_track), core::InputError);
}

// a lane's metrics.json figures as a run writes them
json lane(double map_rmse_m, int da_correct, int da_wrong, double update_ms) {
  return {
      {"role", "shadow"},
      {"association", "ml"},
      {"ablations", json::array()},
      {"ideal_association", false},
      {"map_rmse_m", map_rmse_m},
      {"map_matched", 100},
      {"map_spurious", 2},
      {"map_missed", 0},
      {"ate_rmse_m", 0.1},
      {"da_correct", da_correct},
      {"da_wrong", da_wrong},
      {"loop_closures", 1},
      {"update_cpu_ms_median", update_ms},
      {"loop_closure_events", json::array({{{"travel_m", 300.0}}})},
      {"map_error_over_distance", json::array({{{"distance_m", 290.0}, {"rmse_m", 2 * map_rmse_m}},
                                               {{"distance_m", 310.0}, {"rmse_m", map_rmse_m}}})}};
}

TEST(CompareJson, HoldsTheThesesFiguresBesideTheRunsAndNamesAFailedRun) {
  CompareOptions o = options("fst");
  o.track_files = {std::string(CONESIM_TEST_DATA) + "/tracks/fssim/FSG.yaml"};
  o.seeds = {1, 2};
  StudyPlan plan = plan_study(o);
  // the first condition (Table 4.1's) only: two runs
  ASSERT_EQ(plan.conditions[0].name, "table-4.1");
  plan.conditions.resize(1);
  plan.runs.resize(2);
  std::vector<StudyResult> results(2);
  results[0].exit_code = 1;  // pass criteria missed: the figures still count
  results[0].metrics = {{"completed", true},
                        {"slam_driving", "graph"},
                        {"slam_shadows", {"fastslam1", "fastslam2"}},
                        {"slam",
                         {{"graph", lane(0.10, 900, 10, 0.2)},
                          {"fastslam1", lane(0.30, 800, 50, 0.4)},
                          {"fastslam2", lane(0.20, 850, 30, 0.5)}}}};
  results[1].exit_code = 2;  // refused: no metrics.json
  results[1].log_tail = "not drivable by this car";
  const json c = compare_json(plan, results, o, 12.0);

  EXPECT_EQ(c["schema"], "conesim-compare/1");
  for (const char* key : {"conditions", "runs", "failed_runs", "summary", "per_track", "tables",
                          "figures", "wall_time_s", "command"})
    EXPECT_TRUE(c.contains(key)) << key;
  // the failed run is named, with its exit status and its log's last line
  ASSERT_EQ(c["failed_runs"].size(), 1u);
  EXPECT_EQ(c["failed_runs"][0]["id"], "fst | table-4.1 | fssim/FSG | seed 2");
  EXPECT_NE(c["failed_runs"][0]["reason"].get<std::string>().find(
                "exit status 2, no metrics.json: not drivable by this car"),
            std::string::npos);
  // per lane: the run's figures with the thesis's beside them, lanes in the run's order
  ASSERT_EQ(c["summary"].size(), 3u);
  EXPECT_EQ(c["summary"][0]["lane"], "graph");
  EXPECT_EQ(c["summary"][1]["lane"], "fastslam1");
  const json& fs1 = c["summary"][1];
  EXPECT_DOUBLE_EQ(fs1["map_rmse_m"]["median"].get<double>(), 0.30);
  EXPECT_DOUBLE_EQ(fs1["thesis"]["map_rmse_m"].get<double>(), 0.96);
  EXPECT_DOUBLE_EQ(c["summary"][0]["thesis"]["da_correct"].get<double>(), 2186);
  // before the closure: the last snapshot before it; after: the final map
  EXPECT_DOUBLE_EQ(c["summary"][0]["map_rmse_before_closure_m"].get<double>(), 0.20);
  EXPECT_DOUBLE_EQ(c["summary"][0]["map_rmse_after_closure_m"].get<double>(), 0.10);
  // the ordering FS1 > FS2 > Graph held in the one usable run
  ASSERT_EQ(c["per_track"].size(), 1u);
  EXPECT_EQ(c["per_track"][0]["ordering"]["holds"], 1);
  EXPECT_EQ(c["per_track"][0]["ordering"]["runs"], 1);
  // the tables and the two documents
  EXPECT_GE(c["tables"].size(), 4u);
  const std::string md = compare_markdown(c);
  EXPECT_NE(md.find("| fssim/FSG | 1 | 0.300 | 0.96 | 0.200 | 0.38 | 0.100 | 0.31 |"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("fst | table-4.1 | fssim/FSG | seed 2"), std::string::npos);
  EXPECT_NE(compare_html(c).find("<table>"), std::string::npos);
}

}  // namespace
}  // namespace conesim::sim
