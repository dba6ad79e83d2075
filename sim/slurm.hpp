#pragma once
// `conesim regress ... --slurm`: the regression as a Slurm job array (one task per shard) and a
// merge job that starts when the array has ended, submitted with Slurm's own sbatch; and
// `conesim slurm status`, a summary of their progress from sacct (or squeue).

#include <filesystem>
#include <iosfwd>
#include <string>
#include <vector>

#include "sim/regress.hpp"

namespace conesim::sim {

/// How the job array asks for its resources.
struct SlurmOptions {
  /// Shards: tasks of the array.
  int shards = 4;
  /// sbatch --partition, --time (e.g. 2:00:00), --cpus-per-task; empty or 0: the cluster's default.
  std::string partition;
  std::string time;
  int cpus_per_task = 0;
  /// Runs at once in each task: --jobs when given (non-zero), else SLURM_CPUS_PER_TASK (1 when
  /// Slurm does not set it).
  int jobs = 0;
};

/// What the job array runs: `conesim COMMAND ARGS --shard K/N --out OUT/shard-K` per task, and
/// `conesim merge OUT/shard-1 ... --out OUT` after it.
struct ShardedCall {
  /// "regress" or "compare".
  std::string command;
  /// The arguments after the command, as given (--slurm and its options are left out).
  std::vector<std::string> args;
  std::filesystem::path out_dir;
  /// The runs of the whole list (the note on shards without runs, jobs.json).
  size_t runs = 0;
};

/// The array's batch script: task K (SLURM_ARRAY_TASK_ID, 0-based) runs
/// `conesim COMMAND ARGS --shard K+1/N --out OUT/shard-(K+1)`, its log in OUT/slurm.
std::string slurm_shards_script(const std::filesystem::path& self, const ShardedCall& call,
                                const SlurmOptions& slurm);

/// The merge job's batch script: `conesim merge OUT/shard-1 ... OUT/shard-N --out OUT`.
std::string slurm_merge_script(const std::filesystem::path& self, const ShardedCall& call,
                               const SlurmOptions& slurm);

/// Writes both scripts into OUT/slurm, submits the array with `sbatch --parsable` and the merge
/// with `--dependency=afterany:ARRAY`, writes OUT/slurm/jobs.json and prints the job ids and the
/// commands that follow them. The caller has planned the runs (bad input stops before anything
/// is submitted). Returns 0, or 1 when sbatch failed (its words printed). Throws
/// core::InputError when sbatch is not on PATH.
int submit_shards_to_slurm(const std::filesystem::path& self, const ShardedCall& call,
                           const SlurmOptions& slurm, std::ostream& out, std::ostream& err);

/// Plans the regression here (bad input stops before anything is submitted), then
/// submit_shards_to_slurm.
int submit_regression_to_slurm(const std::filesystem::path& self, const RegressOptions& options,
                               const SlurmOptions& slurm, std::ostream& out, std::ostream& err);

/// One job or array task as sacct or squeue report it.
struct SlurmTask {
  std::string id;
  std::string name;
  std::string state;
  std::string exit_code;
  std::string elapsed;
  std::string reason;
};

/// Parses `sacct --parsable2 --noheader --format=JobID,JobName,State,ExitCode,Elapsed` lines
/// (job steps such as 12_0.batch are left out).
std::vector<SlurmTask> parse_sacct(const std::string& text);
/// Parses `squeue --noheader --format=%i|%j|%T|%r|%M` lines.
std::vector<SlurmTask> parse_squeue(const std::string& text);

/// `conesim slurm status JOB...` (or the OUT folder of a --slurm regress): per job, its tasks
/// counted by state and one line per task. With `wait`, polls every `poll_s` seconds until no
/// task is pending or running. Returns 0 when every task completed, 1 when one failed, was
/// cancelled or timed out, 3 while some still run, 2 when a job is not known.
int slurm_status(std::vector<std::string> jobs, bool wait, double poll_s, std::ostream& out,
                 std::ostream& err);

}  // namespace conesim::sim
