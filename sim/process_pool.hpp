#pragma once
// Child processes run side by side, at most a given number at once: the machinery behind
// `conesim regress` and `conesim compare`, which run every case as its own `conesim run`.

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace conesim::sim {

/// One process to run: its command line (argv[0] a path to the program) and the file that
/// takes its stdout and stderr.
struct ProcessJob {
  std::vector<std::string> argv;
  std::filesystem::path log_file;
};

/// Runs the jobs in order, at most `parallel` at once, and calls `on_started(index)` before
/// each starts and `on_done(index, exit_status)` as each ends (in the order they end), both on
/// the calling thread. The exit status is the process's code, 128 + the signal that ended it,
/// or 127 when it could not be started. On SIGINT or SIGTERM (sim/interrupt.hpp) no job
/// starts any more, the running children get the same signal, and the call returns once they
/// have ended: the jobs never started get no on_done.
void run_processes(const std::vector<ProcessJob>& jobs, int parallel,
                   const std::function<void(size_t)>& on_started,
                   const std::function<void(size_t, int)>& on_done);

/// The last non-empty line of a log file (empty when there is none).
std::string last_log_line(const std::filesystem::path& file);

}  // namespace conesim::sim
