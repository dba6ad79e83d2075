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

/// Runs the study: every run as a `conesim run` process of `self` (at most options.jobs at
/// once), then writes compare.json, compare.md, compare.html and the figures into
/// options.out_dir. Returns 0 when every run gave its figures, 1 when one did not (each named,
/// with its exit status and last log line, on `out` and in the outputs).
int run_compare(const std::filesystem::path& self, const CompareOptions& options, std::ostream& out,
                std::ostream& progress);

}  // namespace conesim::sim
