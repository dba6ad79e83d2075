#pragma once
// The regression a team puts in CI: scenarios x tracks x seeds, each run a `conesim run` process
// (at most --jobs at once), one row per run read from its metrics.json, written as summary.json,
// junit.xml and summary.html beside the runs, and compared against a stored summary.json.

#include <cmath>
#include <filesystem>
#include <iosfwd>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

namespace conesim::sim {

/// What `conesim regress` was asked to run.
struct RegressOptions {
  /// Scenario names or files; empty: the default set (or, with tracks, each track's own event).
  std::vector<std::string> scenarios;
  /// Track files (--track), each run by every scenario of a matching event.
  std::vector<std::filesystem::path> track_files;
  /// --tracks: a folder (every track file under it), a list file (one path a line, relative to
  /// the list), or `corpus` (the public layouts shipped in tests/data/tracks).
  std::vector<std::string> track_sets;
  /// --generated N[:profile]: N generated circuits, seeds 1..N, made by `conesim track generate
  /// --event trackdrive --seed K [--profile P]`.
  int generated = 0;
  std::string generated_profile;
  /// Seeds for every run; empty: each shipped scenario's default seeds (1 on given tracks).
  std::vector<unsigned long long> seeds;
  /// --set key=value overrides, handed to every run.
  std::vector<std::string> sets;
  int jobs = 2;
  /// Whether the runs draw their pictures (report.html shows them).
  bool plot = true;
  std::filesystem::path out_dir;
  std::optional<std::filesystem::path> baseline;
  /// The command line, for summary.json.
  std::string command_line;
  /// --resume: in an --out folder of an earlier, interrupted call with the same runs
  /// (runs.json), the runs that wrote their metrics.json are read, not run again.
  bool resume = false;
};

/// One run of the regression.
struct RegressionRun {
  std::string scenario;
  /// Where the track comes from: empty for the scenario's own, else e.g. "pacsim/FSG19" or
  /// "generated/trackdrive-s7".
  std::string track_label;
  std::filesystem::path track_file;
  unsigned long long seed = 1;
  /// The run's folder, relative to the regression's folder.
  std::filesystem::path dir;

  /// "scenario | track | seed N": how a run is found again in a baseline.
  std::string id() const;
};

/// A track of a folder or list that could not be read: skipped, with why.
struct SkippedTrack {
  std::string track;
  std::string reason;
};

/// The run list, deterministic: scenarios in the order given, tracks in the order given (folders
/// sorted), seeds in the order given.
struct RegressionPlan {
  std::vector<RegressionRun> runs;
  std::vector<SkippedTrack> skipped;
  /// Scenario and track pairs left out because their events differ (e.g. skidpad on a circuit).
  int event_mismatches = 0;
};

/// Parses "1,2,3", "1-5" or a mix ("1-3,7"). Throws core::InputError on anything else.
std::vector<unsigned long long> parse_seeds(const std::string& text);

/// The folder of the public layouts shipped with conesim (CONESIM_CORPUS overrides it).
std::filesystem::path shipped_corpus_dir();

/// Builds the run list; generated circuits are written under options.out_dir/tracks by `self`.
/// Throws core::InputError (exit 2) for an unknown scenario, a bad --set, an unreadable track
/// given by --track, a missing folder or list, or a profile the generator rejects.
RegressionPlan plan_regression(const std::filesystem::path& self, const RegressOptions& options);

/// One penalty or DNF of a run, from metrics.json `events`.
struct RunEvent {
  std::string kind;
  double t_s = 0.0;
  int lap = 0;
  double x_m = 0.0, y_m = 0.0;
  double penalty_s = 0.0;
  std::string reason;
};

/// One row of the summary: a run's verdict, why, and its figures (NaN when absent).
struct RunRow {
  std::string id;
  std::string scenario;
  std::string track;
  unsigned long long seed = 1;
  std::string dir;
  bool passed = false;
  /// Refused before it started: the pre-run check found the layout not drivable by this car
  /// (the reasons say where and why). Listed apart, not a failure of the run: a layout the car
  /// cannot drive says nothing of the stack under test; a run that passed in the baseline and is
  /// refused now is still a regression.
  bool refused = false;
  /// Every pass failure, or why the run has no verdict (crash, exit status).
  std::vector<std::string> reasons;
  std::string dnf_reason;
  int exit_code = 0;
  std::string event;
  int cones_hit = 0;
  int off_course = 0;
  std::vector<RunEvent> events;
  int laps = 0;
  double best_lap_s = NAN;
  double final_time_s = NAN;
  double lap_time_bound_s = NAN;
  /// best lap / lap-time bound.
  double bound_ratio = NAN;
  double map_rmse_m = NAN;
  double ate_rmse_m = NAN;
  double da_correct_fraction = NAN;
  double perception_recall = NAN;
  double perception_precision = NAN;
  double wall_time_s = NAN;
  double real_time_factor = NAN;
  /// Filled by compare_to_baseline: what got worse beyond the noise.
  std::vector<std::string> regressions;
};

/// The row of `run` from its metrics.json (null when the run wrote none), its exit status and
/// the last line of its log (the error of a run that stopped without metrics.json).
RunRow make_row(const RegressionRun& run, const nlohmann::json& metrics, int exit_code,
                const std::string& log_tail = "");

nlohmann::json row_to_json(const RunRow& row);
RunRow row_from_json(const nlohmann::json& j);

/// The rows of a stored summary.json (`--baseline`); `name` stands for the file in errors.
/// Throws core::InputError when the text is not a summary.
std::vector<RunRow> parse_baseline(const std::string& text, const std::string& name);

/// Failed runs first, then regressed ones, each group in run order.
void sort_failures_first(std::vector<RunRow>& rows);

/// The noise of each compared figure: a change within it is not a regression.
struct BaselineNoise {
  /// best lap and final time: worse by more than max(relative, absolute_s)
  double time_relative = 0.02;
  double time_absolute_s = 0.2;
  /// SLAM map and trajectory RMSE of one run: worse by more than max(relative, absolute_m).
  /// Wide: a 1e-8 relative change of one driver setting moved one run's map RMSE from 0.047 to
  /// 0.092 m (the associations differ, the closed loop drives on differently).
  double rmse_relative = 0.50;
  double rmse_absolute_m = 0.06;
  /// The median over a scenario's runs (at least median_min_runs in both summaries) of the SLAM
  /// map and trajectory RMSE: worse by more than max(relative, absolute_m). Tight: that change
  /// moved the medians by 0 and 5 %.
  double median_rmse_relative = 0.10;
  double median_rmse_absolute_m = 0.005;
  int median_min_runs = 5;
  /// fraction of correct SLAM associations: lower by more than this
  double association_fraction_absolute = 0.005;
  /// perception recall and precision: lower by more than this
  double fraction_absolute = 0.02;
  /// cones hit and off-course: any increase counts (a penalty is never noise)
};

/// What changed against the stored summary.
struct BaselineComparison {
  /// "id: what", one per regression (also filled into each row's `regressions`), then
  /// "scenario: median ..." for a scenario whose median SLAM figures regressed.
  std::vector<std::string> regressions;
  /// The median regressions alone (they belong to no run).
  std::vector<std::string> median_regressions;
  /// Runs of the baseline not run now, and runs now that the baseline does not have.
  std::vector<std::string> missing;
  std::vector<std::string> added;
};

/// Compares `rows` against `baseline` (rows of a stored summary.json) by run id: a run that
/// passed and now fails is a regression, and so is a figure worse than the noise allows.
BaselineComparison compare_to_baseline(std::vector<RunRow>& rows,
                                       const std::vector<RunRow>& baseline,
                                       const BaselineNoise& noise = {});

/// The noise thresholds in words (README, summary.html).
std::string describe_noise(const BaselineNoise& noise = {});

/// summary.json: command, version, rows, totals, wall time, baseline comparison.
nlohmann::json summary_json(const std::vector<RunRow>& rows, const RegressionPlan& plan,
                            const RegressOptions& options, double wall_s,
                            const BaselineComparison* comparison);

/// junit.xml: one testcase per run (classname the scenario, name track and seed), a failure
/// with the reasons for each failed or regressed run, and with a baseline one testcase
/// "baseline medians" that fails on a median regression.
std::string junit_xml(const std::vector<RunRow>& rows, double wall_s,
                      const BaselineComparison* comparison = nullptr);

/// summary.html: self-contained, failures first, a link to each run's report.html.
std::string summary_html(const std::vector<RunRow>& rows, const RegressionPlan& plan,
                         const RegressOptions& options, double wall_s,
                         const BaselineComparison* comparison);

/// The console table, the reason under every FAIL row.
void print_table(const std::vector<RunRow>& rows, std::ostream& out);

/// Runs the plan, writes the three summaries into options.out_dir, prints the table and returns
/// the exit status: 0 all passed and no regression, 1 otherwise. Throws core::InputError for an
/// unreadable baseline (checked before any run starts).
int run_regression(const std::filesystem::path& self, const RegressOptions& options,
                   std::ostream& out, std::ostream& progress);

/// A fresh run directory under `parent` named <name>-<UTC stamp>, made unique with a suffix.
std::filesystem::path make_run_dir(const std::filesystem::path& parent, const std::string& name);

}  // namespace conesim::sim
