#pragma once
// The regression a team puts in CI: scenarios x tracks x seeds, each run a `conesim run` process
// (at most --jobs at once), one row per run read from its metrics.json, written as summary.json,
// junit.xml and summary.html beside the runs, and compared against a stored summary.json.

#include <cmath>
#include <filesystem>
#include <functional>
#include <iosfwd>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "core/event.hpp"

namespace conesim::sim {

/// `--shard I/N`: the I-th (1-based) of N slices of the run list; count 0 is the whole list.
struct Shard {
  int index = 0;
  int count = 0;
  bool active() const { return count > 0; }
  /// "I/N"
  std::string text() const;
};

/// Parses "I/N" with 1 <= I <= N. Throws core::InputError naming `option` (e.g. --shard) and
/// what it expected for 0/4, 5/4, x and the like.
Shard parse_shard(const std::string& text, const std::string& option = "--shard");

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
  /// --shard I/N: only the runs of that slice run; plan.json beside them names the whole list.
  Shard shard;
  /// When not empty, only the runs with these ids run (--only-missing); plan.json names the
  /// whole list, so that `conesim merge` can take these runs in with the shards'.
  std::vector<std::string> only_ids;
  /// The command's arguments after `regress`, as given: plan.json keeps them for the command
  /// that reruns a dead shard's runs (without --shard, --out and --resume).
  std::vector<std::string> args;
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
  /// What the run is expected to cost, in units of one ground-truth autocross lap of 300 m
  /// (run_cost); shards are balanced by it.
  double cost = 1.0;

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

/// What a run costs besides driving, in run_cost's units: its process, its track (read or
/// generated), its metrics and trajectory; and run.png when plots are written. Measured on
/// 2 cores (see README, "Running on a cluster").
inline constexpr double kRunStartCost = 0.2;
inline constexpr double kRunPlotCost = 0.6;
/// The cost of 300 m of an event's driving against 300 m of trackdrive (a trackdrive's ten laps
/// average its exploring first lap with nine fast ones; autocross explores all the way).
inline constexpr double kAutocrossPer300m = 2.1;
inline constexpr double kSkidpadPer300m = 1.25;
inline constexpr double kAccelerationPer300m = 1.0;

/// The expected cost of one run, in units of one ground-truth trackdrive lap of a 300 m circuit:
/// the laps the event drives (acceleration 1, skidpad 4, autocross 1, trackdrive 10) x the lap
/// length / 300 m (the track's centre line; 0: the usual length, acceleration 75 m, skidpad
/// 60 m, circuits 300 m) x the event's cost per 300 m (k...Per300m), x 1.5 with a SLAM back-end
/// driving, + 0.5 per shadow back-end, x 3 for raw-data perception (lidar, stereo, fused), +
/// kRunStartCost, + kRunPlotCost with `plot`. Rounded to 1/1000 so that every machine balances
/// the same list the same way.
/// `laps`: the laps a trackdrive drives when not the usual 10 (driver.trackdrive_laps; 0: 10).
double run_cost(core::EventType event, double lap_length_m, bool slam_driving, int slam_shadows,
                bool raw_perception, int laps = 0, bool plot = false);

struct Scenario;

/// run_cost of a run of scenario `s` (its event, SLAM back-ends, perception and trackdrive laps)
/// on a lap of `lap_length_m` (0: the event's usual length).
double scenario_run_cost(const Scenario& s, double lap_length_m, bool plot);

/// The lap of the track the scenario in `scenario_file` with `sets` drives with `seed` (its
/// file's, or the circuit generated from the seed: a few milliseconds); 0 for skidpad and
/// acceleration (their usual layouts) and for a track that cannot be made (the run says why).
double scenario_lap_length_m(const std::filesystem::path& scenario_file,
                             const std::vector<std::string>& sets, unsigned long long seed);

/// The length of a track file's centre line (a closed circuit's lap; 0 without one), for
/// run_cost. Throws what tracks::read_track throws for an unreadable file.
double track_lap_length_m(const std::filesystem::path& file);

/// Slices `costs` (one per run, in run order) into `count` shards by greedy longest processing
/// time: runs from the most to the least expensive (ties by run order) each go to the shard
/// with the least cost so far (ties to the lower shard). Returns each shard's run indexes in
/// run order. Every run is in exactly one shard; a shard's total exceeds another's by at most
/// the most expensive run.
std::vector<std::vector<size_t>> shard_runs(const std::vector<double>& costs, int count);

/// Each run's shard (1-based) when `costs` are dealt into `count` shards by shard_runs.
std::vector<int> shard_of_runs(const std::vector<double>& costs, int count);

/// The indexes (into the run list) of the runs a call runs, in run order: those whose ids are
/// in `only_ids` (--only-missing) when it is not empty, else shard `shard`'s slice of the list
/// (shard_runs over `costs`), else all. `ids` and `costs` are the whole list's. Throws
/// core::InputError naming --only-missing for an id not in the list; `what` says which
/// arguments make the list (e.g. "scenarios, tracks, seeds and --set values").
std::vector<size_t> select_runs(const std::vector<std::string>& ids,
                                const std::vector<double>& costs, const Shard& shard,
                                const std::vector<std::string>& only_ids, const std::string& what);

/// How the run list's expected cost spreads over 1, 2, 4 ... 32 shards (the --list of a whole
/// list): per count, the costliest shard against total / count, the share of a perfect split,
/// and the runs in the costliest shard.
void print_shard_scaling(const std::vector<double>& costs, std::ostream& out);

/// plan.json of a shard or a rerun (`tool`: "conesim regress plan" or "conesim compare plan"):
/// the whole list (each run's id, folder, cost and, sharded, its shard), the binary and the
/// arguments as given, the shard, --jobs and the ids this call runs. The caller adds its own.
nlohmann::json shard_plan_json(const std::string& tool, const std::filesystem::path& self,
                               const std::vector<std::string>& args,
                               const std::vector<std::string>& ids,
                               const std::vector<std::string>& dirs,
                               const std::vector<double>& costs, const Shard& shard,
                               const std::vector<size_t>& selected, int jobs);

/// The run ids of a plan.json (`file` names it in errors); throws core::InputError when it is
/// not one.
std::vector<std::string> plan_run_ids(const nlohmann::json& plan,
                                      const std::filesystem::path& file);

/// The command that runs only a merge's missing runs and merges again:
/// `BINARY COMMAND ARGS --only-missing MERGE_DIR`, from a shard's plan.json (the arguments
/// without --shard, --out, --jobs and --resume).
std::string rerun_command(const nlohmann::json& plan, const std::string& command,
                          const std::filesystem::path& merge_dir);

/// A JSON file parsed; core::InputError naming the file and `what` it should be otherwise.
nlohmann::json read_json_file(const std::filesystem::path& file, const std::string& what);

/// The runs of the plan this call runs, in run order: those of options.only_ids, else the
/// slice of options.shard, else all. Throws core::InputError for an id not in the plan.
std::vector<RegressionRun> selected_runs(const RegressionPlan& plan, const RegressOptions& options);

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
/// With `missing` (a merge of shards): one failed testcase per run that has no result.
std::string junit_xml(const std::vector<RunRow>& rows, double wall_s,
                      const BaselineComparison* comparison = nullptr,
                      const std::vector<std::string>* missing = nullptr);

/// summary.html: self-contained, failures first, a link to each run's report.html.
/// A merge passes the runs with no result (`missing`) and where each run's folder is, relative
/// to options.out_dir, by run id (`run_folders`; else a run's own `dir`).
std::string summary_html(const std::vector<RunRow>& rows, const RegressionPlan& plan,
                         const RegressOptions& options, double wall_s,
                         const BaselineComparison* comparison,
                         const std::vector<std::string>* missing = nullptr,
                         const std::map<std::string, std::string>* run_folders = nullptr);

/// The console table, the reason under every FAIL row.
void print_table(const std::vector<RunRow>& rows, std::ostream& out);

/// Runs the plan, writes the three summaries into options.out_dir, prints the table and returns
/// the exit status: 0 all passed and no regression, 1 otherwise. Throws core::InputError for an
/// unreadable baseline (checked before any run starts).
int run_regression(const std::filesystem::path& self, const RegressOptions& options,
                   std::ostream& out, std::ostream& progress);

/// `conesim merge DIR... --out OUT`: the --out folders of `conesim regress --shard I/N` (and of
/// `--only-missing` reruns) into one summary.
struct MergeOptions {
  std::vector<std::filesystem::path> dirs;
  std::filesystem::path out_dir;
  /// Compare against this summary.json; else against the shards' own --baseline, if they had one.
  std::optional<std::filesystem::path> baseline;
  /// --expect: a summary.json the merged one must equal apart from timing (same_apart_from_timing).
  std::optional<std::filesystem::path> expect;
  std::string command_line;
};

/// Reads each folder's plan.json (the whole run list) and summary.json (its runs' rows), and
/// writes into out_dir the summary.json, junit.xml and summary.html an unsharded regress writes,
/// with the same rows in the same order (a run found in several folders: the last folder's row).
/// summary.json gains `shards`: the folders, the runs with no result (`missing_runs`: a shard
/// that died or was never run) and the one command that runs only those (`rerun`). Prints the
/// table, the missing runs and that command. Returns 0 when every run is there and passed (and
/// nothing regressed, and --expect matched), 1 otherwise. Throws core::InputError when no folder
/// has a plan.json or two folders' plans list different runs.
int merge_regression(const MergeOptions& options, std::ostream& out, std::ostream& progress);

/// A summary.json without what differs between two calls of the same study: the command, when
/// it finished, wall times, jobs, real-time factors and a merge's `shards`.
nlohmann::json summary_without_timing(nlohmann::json summary);

/// The differences between two summaries apart from timing, one "path: a -> b" a line (at most
/// `limit`); empty when they are the same.
std::vector<std::string> summary_differences(const nlohmann::json& a, const nlohmann::json& b,
                                             size_t limit = 20);

/// The differences between two JSON documents, one "path: a -> b" a line (at most `limit`);
/// empty when they are the same.
std::vector<std::string> json_differences(const nlohmann::json& a, const nlohmann::json& b,
                                          size_t limit = 20);

/// What --only-missing does for regress and compare alike: reads the `shards` of MERGE_DIR's
/// merged `file_name` (summary.json or compare.json; core::InputError naming --only-missing when
/// it has none), and when runs are missing calls `run(ids, MERGE_DIR/rerun-K)` and then `merge`
/// with the merge's folders and the rerun's into MERGE_DIR. Returns merge's status (0 when
/// nothing is missing; the signal's status when interrupted).
int rerun_then_merge(const std::filesystem::path& merge_dir, const std::string& file_name,
                     const std::string& command_line,
                     const std::function<void(const std::vector<std::string>& ids,
                                              const std::filesystem::path& rerun_dir)>& run,
                     const std::function<int(const MergeOptions&)>& merge, std::ostream& out,
                     std::ostream& progress);

/// `conesim regress ... --only-missing MERGE_DIR`: runs the runs that MERGE_DIR's summary.json
/// lists as missing (options as the shards had them, out_dir ignored) into MERGE_DIR/rerun-K,
/// then merges the shards and the rerun into MERGE_DIR again. Returns merge_regression's status.
int rerun_missing(const std::filesystem::path& self, RegressOptions options,
                  const std::filesystem::path& merge_dir, std::ostream& out,
                  std::ostream& progress);

/// One word of a shell command line, quoted when it needs to be.
std::string shell_word(const std::string& word);

/// `args` without the options named: `with_value` ones with their value (--out X, --out=X),
/// `flags` alone.
std::vector<std::string> without_options(const std::vector<std::string>& args,
                                         const std::set<std::string>& with_value,
                                         const std::set<std::string>& flags);

/// A fresh run directory under `parent` named <name>-<UTC stamp>, made unique with a suffix.
std::filesystem::path make_run_dir(const std::filesystem::path& parent, const std::string& name);

}  // namespace conesim::sim
