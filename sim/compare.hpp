#pragma once
// `conesim compare STUDY`: the theses' experiments re-run against exact truth. A study is
// conditions (each the thesis's set-up as conesim can run it) x tracks x seeds; each run is one
// `conesim run` of GraphSLAM driving with every method of the study in shadow on the same
// observation stream, run as parallel processes. The results are gathered per method beside
// the theses' figures into compare.md, compare.json and compare.html.

#include <filesystem>
#include <iosfwd>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "sim/regress.hpp"

namespace conesim::sim {

/// What `conesim compare` was asked to run.
struct CompareOptions {
  /// fst, raceup, monash or all.
  std::string study;
  /// Runs at once.
  int jobs = 2;
  /// The folder of the runs and the three outputs.
  std::filesystem::path out_dir;
  /// Replace the study's tracks and seeds when given (a quick look, or a test).
  std::vector<std::filesystem::path> track_files;
  std::vector<unsigned long long> seeds;
  /// --set overrides handed to every run after the study's own.
  std::vector<std::string> sets;
  /// Whether the comparison's figures are drawn (gnuplot).
  bool plot = true;
  /// Runs whose folder already holds a metrics.json are not run again (their exit status is
  /// read from it: 0 when it passed, else 1): the outputs are written again from them.
  bool reuse = false;
  /// The command line, for compare.json.
  std::string command_line;
  /// --shard I/N: only that slice of the run list runs (balanced by expected cost, as regress
  /// deals its runs); plan.json beside the runs names the whole list for `conesim merge`.
  Shard shard;
  /// When not empty, only the runs with these ids run (--only-missing).
  std::vector<std::string> only_ids;
  /// The arguments after `compare`, as given: plan.json keeps them for the rerun command.
  std::vector<std::string> args;
};

/// One condition of a study: the --set values that give it, and in words what conesim runs
/// and what the thesis ran.
struct StudyCondition {
  std::string study;
  std::string name;
  std::vector<std::string> sets;
  std::string conesim;
  std::string thesis;
};

/// One run of a study.
struct StudyRun {
  std::string study;
  std::string condition;
  /// e.g. "fssim/FSG".
  std::string track_label;
  std::filesystem::path track_file;
  unsigned long long seed = 1;
  /// Every --set of the run: the condition's, then the command line's.
  std::vector<std::string> sets;
  /// The run's folder, relative to the comparison's folder.
  std::filesystem::path dir;
  /// Expected cost (run_cost: a trackdrive of the condition's laps on the track's centre line,
  /// GraphSLAM driving, the condition's shadows); shards are balanced by it.
  double cost = 1.0;

  /// "study | condition | track | seed N".
  std::string id() const;
};

/// The runs of a study, deterministic: studies, conditions, tracks and seeds in their order.
struct StudyPlan {
  std::vector<std::string> studies;
  std::vector<StudyCondition> conditions;
  std::vector<StudyRun> runs;
};

/// The studies shipped: fst, raceup, monash, all.
const std::vector<std::string>& study_names();

/// Expands the study into its runs. Throws core::InputError (exit 2) for an unknown study, a
/// missing track file, or a --set the scenario refuses (checked with every condition's own).
StudyPlan plan_study(const CompareOptions& options);

/// A finished run as the comparison reads it.
struct StudyResult {
  int exit_code = -1;
  /// metrics.json, null when the run wrote none.
  nlohmann::json metrics;
  /// The log's last line when the run wrote no metrics.json.
  std::string log_tail;
  /// A merge of shards found no result for the run (its shard died or never ran).
  bool missing = false;
};

/// True when a run's figures can be used: metrics.json written and an exit status of 0 or 1
/// (1: the scenario's pass criteria, which a noisy study condition is expected to miss).
bool run_usable(const StudyResult& result);

/// compare.json from the plan and the results (index for index): the conditions with the
/// theses' set-ups, every run's lanes, the per-method summaries and the tables.
nlohmann::json compare_json(const StudyPlan& plan, const std::vector<StudyResult>& results,
                            const CompareOptions& options, double wall_s);

/// compare.md and compare.html from compare.json; `figures` are the pictures drawn (file
/// names relative to the folder), shown where they belong.
std::string compare_markdown(const nlohmann::json& compare);
std::string compare_html(const nlohmann::json& compare);

/// The indexes (into plan.runs) of the runs this call runs: options.only_ids, else the slice
/// of options.shard, else all (select_runs).
std::vector<size_t> selected_study_runs(const StudyPlan& plan, const CompareOptions& options);

/// compare.json without what differs between two calls of the same study: the command, wall
/// time, jobs, reused runs, a merge's `shards`, and the CPU time per update (each lane's
/// update_cpu_ms_median and update_ms_median, and the tables of time per update).
nlohmann::json compare_without_timing(nlohmann::json compare);

/// True when the first of `dirs` with a plan.json holds one of `conesim compare --shard`.
bool holds_compare_plan(const std::vector<std::filesystem::path>& dirs);

/// `conesim merge` of the --out folders of `conesim compare --shard I/N` (and --only-missing
/// reruns): plans the study again from the plan.json's arguments, takes each run's result from
/// the last folder that has it (a finished shard's exit status, or the metrics.json of a run
/// whose shard did not finish), and writes the compare.json, compare.md, compare.html (and
/// figures) an unsharded compare writes. compare.json gains `shards`: the folders, where each
/// run's folder is, the runs with no result (`missing_runs`, also listed as failed runs) and the
/// one command that runs only them (`rerun`). Returns 0 when every run is there and gave its
/// figures (and --expect matched, apart from timing), 1 otherwise. Throws core::InputError when
/// no folder has a plan.json or the plans list different runs.
int merge_compare(const MergeOptions& options, std::ostream& out, std::ostream& progress);

/// `conesim compare ... --only-missing MERGE_DIR`: the runs MERGE_DIR/compare.json lists as
/// missing run into MERGE_DIR/rerun-K, then the shards and the rerun are merged into MERGE_DIR
/// again. Returns merge_compare's status.
int rerun_missing_compare(const std::filesystem::path& self, CompareOptions options,
                          const std::filesystem::path& merge_dir, std::ostream& out,
                          std::ostream& progress);

/// Runs the study: every run as a `conesim run` process of `self` (at most options.jobs at
/// once), then writes compare.json, compare.md, compare.html and the figures into
/// options.out_dir. Returns 0 when every run gave its figures, 1 when one did not (each named,
/// with its exit status and last log line, on `out` and in the outputs).
int run_compare(const std::filesystem::path& self, const CompareOptions& options, std::ostream& out,
                std::ostream& progress);

}  // namespace conesim::sim
