#include "sim/report.hpp"

#include <gtest/gtest.h>

namespace conesim::sim {
namespace {

using nlohmann::json;

// a failed ground-truth run as metrics.json gives it (no pictures drawn)
json failed_run() {
  return {{"scenario", "autocross"},
          {"event", "autocross"},
          {"track", "FSG19"},
          {"seed", 3},
          {"completed", true},
          {"dnf_reason", ""},
          {"laps", 1},
          {"lap_times_s", {41.23456}},
          {"penalties",
           {{"cones_hit", 1}, {"cones_hit_ids", {17}}, {"off_course", 0}, {"penalty_time_s", 2.0}}},
          {"raw_time_s", 41.23456},
          {"final_time_s", 43.23456},
          {"passed", false},
          {"pass_failures", {"1 cones hit, at most 0 allowed"}},
          {"slam", json::object()},
          {"perception", {{"mode", "ground_truth"}}},
          {"events",
           {{{"kind", "cone_hit"},
             {"t_s", 12.3456},
             {"lap", 1},
             {"x_m", 10.123456},
             {"y_m", -4.5},
             {"reason", "hit blue cone 17"},
             {"penalty_s", 2.0},
             {"cone_x_m", 10.9},
             {"cone_y_m", -3.9}}}}};
}

TEST(Report, VerdictComesFirstWithEveryFailure) {
  const std::string page = run_report_html("/nonexistent", failed_run());
  const size_t banner = page.find("FAILED");
  ASSERT_NE(banner, std::string::npos);
  EXPECT_EQ(page.find("PASSED"), std::string::npos);
  const size_t failure = page.find("1 cones hit, at most 0 allowed");
  ASSERT_NE(failure, std::string::npos);
  EXPECT_LT(banner, failure);
  EXPECT_LT(failure, page.find("<h2>Run</h2>"));
}

TEST(Report, EventsHavePlacesAndNumbersAreRounded) {
  const std::string page = run_report_html("/nonexistent", failed_run());
  EXPECT_NE(page.find("hit blue cone 17"), std::string::npos);
  EXPECT_NE(page.find("(10.12, -4.50) m; cone at (10.90, -3.90) m"), std::string::npos);
  EXPECT_NE(page.find("41.23 s"), std::string::npos);
  EXPECT_EQ(page.find("41.23456"), std::string::npos);
  // no raw JSON cells, no pictures that were not drawn
  EXPECT_EQ(page.find("{\""), std::string::npos);
  EXPECT_EQ(page.find("<img"), std::string::npos);
}

TEST(Report, PassedRunWithSlamShowsItsFigures) {
  json m = failed_run();
  m["passed"] = true;
  m["pass_failures"] = json::array();
  m["slam"] = {
      {"graph",
       {{"map_rmse_m", 0.0412345},
        {"by_class",
         {{"blue", {{"matched", 40}, {"missed", 1}, {"spurious", 0}, {"rmse_m", 0.03}}}}}}}};
  const std::string page = run_report_html("/nonexistent", m);
  EXPECT_NE(page.find("PASSED"), std::string::npos);
  EXPECT_NE(page.find("SLAM: graph"), std::string::npos);
  EXPECT_NE(page.find("0.041 m"), std::string::npos);
}

TEST(Report, DrivingBackEndFirstThenShadowsWithTheIdealOneFlagged) {
  json m = failed_run();
  m["slam_driving"] = "graph";
  m["slam"] = {{"ekf", {{"map_rmse_m", 0.05}, {"ideal_association", false}}},
               {"ekf-ideal", {{"map_rmse_m", 0.04}, {"ideal_association", true}}},
               {"graph", {{"map_rmse_m", 0.03}, {"ideal_association", false}}}};
  const std::string page = run_report_html("/nonexistent", m);
  const size_t graph = page.find("SLAM: graph (drives the car)");
  const size_t ekf = page.find("SLAM: ekf (shadow, scored only)");
  const size_t ideal = page.find("SLAM: ekf-ideal (shadow, scored only)");
  ASSERT_NE(graph, std::string::npos);
  ASSERT_NE(ekf, std::string::npos);
  ASSERT_NE(ideal, std::string::npos);
  EXPECT_LT(graph, ekf);
  // the flag stands in the ideal lane's section, and only there
  const size_t flag = page.find("Ideal association:");
  ASSERT_NE(flag, std::string::npos);
  EXPECT_GT(flag, ideal);
  EXPECT_EQ(page.find("Ideal association:", flag + 1), std::string::npos);
}

TEST(Report, HumanNumbers) {
  EXPECT_EQ(human_number(3.0), "3");
  EXPECT_EQ(human_number(0.123456), "0.123");
  EXPECT_EQ(human_number(12.3456), "12.35");
  EXPECT_EQ(human_number(1234.56), "1234.6");
  EXPECT_EQ(human_number(NAN), "-");
  EXPECT_EQ(human_value(json{{"x", 1.23456}, {"ok", true}}), "ok: yes, x: 1.23");
  EXPECT_EQ(html_escape("<a&\">"), "&lt;a&amp;&quot;&gt;");
}

}  // namespace
}  // namespace conesim::sim
