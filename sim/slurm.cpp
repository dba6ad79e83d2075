#include "sim/slurm.hpp"

#include <sys/wait.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <ostream>
#include <sstream>
#include <thread>

#include "core/error.hpp"
#include "core/files.hpp"
#include "sim/json_text.hpp"
#include "sim/run.hpp"

namespace conesim::sim {

namespace fs = std::filesystem;
using core::InputError;
using nlohmann::json;

namespace {

// runs a command line (words quoted), its standard output and error in `output`; the exit status
int run_command(const std::vector<std::string>& argv, std::string& output) {
  std::string line;
  for (const std::string& w : argv) {
    if (!line.empty()) line += ' ';
    line += shell_word(w);
  }
  output.clear();
  FILE* p = popen((line + " 2>&1").c_str(), "r");
  if (!p) return 127;
  char buf[4096];
  size_t n = 0;
  while ((n = std::fread(buf, 1, sizeof(buf), p)) > 0) output.append(buf, n);
  const int status = pclose(p);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128;
}

bool on_path(const std::string& program) {
  std::string ignored;
  return run_command({"sh", "-c", "command -v " + program}, ignored) == 0;
}

std::string trimmed(std::string s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.pop_back();
  const size_t start = s.find_first_not_of(" \t\r\n");
  return start == std::string::npos ? "" : s.substr(start);
}

// the run list's arguments, whole: without what the array sets per task or the submit uses
std::vector<std::string> task_args(const ShardedCall& c) {
  return without_options(c.args,
                         {"--shard", "--out", "--only-missing", "--shards", "--partition", "--time",
                          "--cpus-per-task", "--jobs", "-j"},
                         {"--slurm", "--resume", "--reuse", "--list"});
}

// the #SBATCH lines both jobs share
std::string sbatch_header(const std::string& name, const fs::path& log, const SlurmOptions& s) {
  std::string h = "#!/bin/bash\n#SBATCH --job-name=" + name + "\n#SBATCH --output=" +
                  log.string() + "\n";
  if (!s.partition.empty()) h += "#SBATCH --partition=" + s.partition + "\n";
  if (!s.time.empty()) h += "#SBATCH --time=" + s.time + "\n";
  return h;
}

void require_sbatch() {
  if (!on_path("sbatch"))
    throw InputError("--slurm", 0,
                     "sbatch not found: submitting needs Slurm's client tools on this machine "
                     "(Debian: slurm-client), on a login node of the cluster");
}

fs::path absolute_out(const ShardedCall& c) { return fs::absolute(c.out_dir).lexically_normal(); }

}  // namespace

std::string slurm_shards_script(const fs::path& self, const ShardedCall& o,
                                const SlurmOptions& s) {
  const fs::path out = absolute_out(o);
  std::string h = sbatch_header("conesim-shards", out / "slurm" / "shard-%a.log", s);
  h += "#SBATCH --array=0-" + std::to_string(s.shards - 1) + "\n";
  if (s.cpus_per_task > 0) h += "#SBATCH --cpus-per-task=" + std::to_string(s.cpus_per_task) + "\n";
  h += "# written by `conesim " + o.command + " --slurm`: task K of the array runs shard K+1 of " +
       std::to_string(s.shards) + "\nset -eu\nshard=$((SLURM_ARRAY_TASK_ID + 1))\n";
  std::string cmd = "exec " + shell_word(self.string()) + " " + o.command;
  for (const std::string& a : task_args(o)) cmd.append(" ").append(shell_word(a));
  cmd.append(" --jobs ")
      .append(s.jobs > 0 ? std::to_string(s.jobs) : std::string("\"${SLURM_CPUS_PER_TASK:-1}\""))
      .append(" --shard \"$shard/")
      .append(std::to_string(s.shards))
      .append("\" --out ")
      .append(shell_word((out / "shard-").string()))
      .append("\"$shard\"");
  return h + cmd + "\n";
}

std::string slurm_merge_script(const fs::path& self, const ShardedCall& o,
                               const SlurmOptions& s) {
  const fs::path out = absolute_out(o);
  std::string h = sbatch_header("conesim-merge", out / "slurm" / "merge.log", s);
  h += "#SBATCH --cpus-per-task=1\n# written by `conesim " + o.command +
       " --slurm`: the shards' summaries into one, once the array has ended (whatever became "
       "of its tasks)\n";
  std::string cmd = "exec " + shell_word(self.string()) + " merge";
  for (int k = 1; k <= s.shards; ++k)
    cmd.append(" ").append(shell_word((out / ("shard-" + std::to_string(k))).string()));
  cmd += " --out " + shell_word(out.string());
  return h + cmd + "\n";
}

int submit_regression_to_slurm(const fs::path& self, const RegressOptions& o,
                               const SlurmOptions& s, std::ostream& out, std::ostream& err) {
  require_sbatch();
  // bad input stops here, before anything is queued
  fs::create_directories(o.out_dir / "slurm");
  check_output_writable(o.out_dir);
  const RegressionPlan plan = plan_regression(self, o);
  return submit_shards_to_slurm(self, {"regress", o.args, o.out_dir, plan.runs.size()}, s, out,
                                err);
}

int submit_shards_to_slurm(const fs::path& self, const ShardedCall& o, const SlurmOptions& s,
                           std::ostream& out, std::ostream& err) {
  require_sbatch();
  fs::create_directories(o.out_dir / "slurm");
  check_output_writable(o.out_dir);
  if (static_cast<size_t>(s.shards) > o.runs)
    err << "note: " << s.shards << " shards for " << o.runs << " runs: some shards have no run\n";
  const fs::path dir = absolute_out(o) / "slurm";
  const fs::path shards_file = dir / "shards.sh";
  const fs::path merge_file = dir / "merge.sh";
  std::ofstream(shards_file) << slurm_shards_script(self, o, s);
  std::ofstream(merge_file) << slurm_merge_script(self, o, s);

  std::string said;
  auto job_id = [&](const std::string& text) { return trimmed(text.substr(0, text.find(';'))); };
  if (run_command({"sbatch", "--parsable", "--chdir", fs::current_path().string(),
                   shards_file.string()},
                  said) != 0) {
    err << "sbatch refused " << shards_file.string() << ": " << trimmed(said) << "\n";
    return 1;
  }
  const std::string array = job_id(said);
  if (run_command({"sbatch", "--parsable", "--chdir", fs::current_path().string(),
                   "--dependency=afterany:" + array, merge_file.string()},
                  said) != 0) {
    err << "sbatch refused " << merge_file.string() << ": " << trimmed(said)
        << " (the shards run as job " << array << "; merge them with: conesim merge "
        << (absolute_out(o) / "shard-*").string() << " --out " << absolute_out(o).string()
        << ")\n";
    return 1;
  }
  const std::string merge = job_id(said);
  std::ofstream(dir / "jobs.json") << json_text(json{{"shards_job", array},
                                                     {"merge_job", merge},
                                                     {"shards", s.shards},
                                                     {"command", o.command},
                                                     {"runs", o.runs},
                                                     {"out", absolute_out(o).string()}},
                                                1)
                                   << "\n";
  out << "submitted " << o.runs << " runs in " << s.shards
      << " shards as Slurm job array " << array << ", and their merge as job " << merge
      << " (starts when the array has ended)\n"
      << "  progress:       conesim slurm status " << absolute_out(o).string() << "\n"
      << "  merged summary: "
      << (absolute_out(o) / (o.command == "compare" ? "compare.html" : "summary.html")).string()
      << "\n"
      << "shards job " << array << "\nmerge job " << merge << "\n";
  return 0;
}

namespace {

// the '|'-separated fields of each line of `--parsable2` or `--format=%i|...` output
std::vector<std::vector<std::string>> field_lines(const std::string& text) {
  std::vector<std::vector<std::string>> lines;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream fields(line);
    std::string part;
    while (std::getline(fields, part, '|')) f.push_back(part);
    lines.push_back(f);
  }
  return lines;
}

}  // namespace

std::vector<SlurmTask> parse_sacct(const std::string& text) {
  std::vector<SlurmTask> tasks;
  for (const auto& f : field_lines(text)) {
    if (f.size() < 5 || f[0].find('.') != std::string::npos) continue;  // a step: 12_0.batch
    // "CANCELLED by 0": the state's first word
    tasks.push_back({f[0], f[1], f[2].substr(0, f[2].find(' ')), f[3], f[4], ""});
  }
  return tasks;
}

std::vector<SlurmTask> parse_squeue(const std::string& text) {
  std::vector<SlurmTask> tasks;
  for (const auto& f : field_lines(text))
    if (f.size() >= 5) tasks.push_back({f[0], f[1], f[2], "", f[4], f[3] == "None" ? "" : f[3]});
  return tasks;
}

namespace {

bool still_going(const std::string& state) {
  return state == "PENDING" || state == "RUNNING" || state == "CONFIGURING" ||
         state == "COMPLETING" || state == "REQUEUED" || state == "RESIZING" ||
         state == "SUSPENDED";
}

// the tasks of one job from sacct, else (no accounting) from squeue, which keeps ended jobs for
// MinJobAge (300 s by default)
std::vector<SlurmTask> job_tasks(const std::string& job, std::string& source) {
  std::string said;
  if (run_command({"sacct", "-j", job, "--noheader", "--parsable2", "--allocations",
                   "--format=JobID,JobName,State,ExitCode,Elapsed"},
                  said) == 0) {
    std::vector<SlurmTask> tasks = parse_sacct(said);
    if (!tasks.empty()) {
      source = "sacct";
      return tasks;
    }
  }
  source = "squeue";
  if (run_command({"squeue", "--noheader", "--array", "--states=all", "--jobs", job,
                   "--format=%i|%j|%T|%r|%M"},
                  said) != 0)
    return {};
  return parse_squeue(said);
}

}  // namespace

int slurm_status(std::vector<std::string> jobs, bool wait, double poll_s, std::ostream& out,
                 std::ostream& /*err*/) {
  // an OUT folder of `conesim regress --slurm`: its two jobs, and how many tasks the array has
  std::map<std::string, size_t> expected_tasks;
  if (jobs.size() == 1 && core::is_file(fs::path(jobs[0]) / "slurm" / "jobs.json")) {
    std::ifstream in(fs::path(jobs[0]) / "slurm" / "jobs.json");
    json j;
    try {
      in >> j;
      jobs = {j.at("shards_job").get<std::string>(), j.at("merge_job").get<std::string>()};
      expected_tasks[jobs[0]] = j.at("shards").get<size_t>();
    } catch (const json::exception& e) {
      throw InputError((fs::path(jobs[0]) / "slurm" / "jobs.json").string(), 0, e.what());
    }
  }
  for (const std::string& j : jobs)
    if (j.empty() || j.find_first_not_of("0123456789_") != std::string::npos)
      throw InputError("slurm status", 0,
                       "expected Slurm job ids (e.g. 1234) or the --out folder of a `conesim "
                       "regress --slurm`, got '" + j + "'");
  if (!on_path("squeue") && !on_path("sacct"))
    throw InputError("slurm status", 0, "neither sacct nor squeue found: Slurm's client tools "
                                        "(Debian: slurm-client) are needed");
  for (;;) {
    int status = 0;
    bool going = false;
    std::ostringstream report;
    for (const std::string& job : jobs) {
      std::string source;
      const std::vector<SlurmTask> tasks = job_tasks(job, source);
      if (tasks.empty()) {
        report << "job " << job << ": not known to sacct or squeue (a wrong id, or it ended "
                                   "longer ago than the cluster's MinJobAge without accounting)\n";
        status = std::max(status, 2);
        continue;
      }
      std::map<std::string, int> by_state;
      for (const SlurmTask& t : tasks) {
        ++by_state[t.state];
        going = going || still_going(t.state);
        if (!still_going(t.state) && t.state != "COMPLETED") status = std::max(status, 1);
      }
      report << "job " << job << " " << tasks.front().name << ": " << tasks.size()
             << (tasks.size() == 1 ? " task:" : " tasks:");
      bool first = true;
      for (const auto& [state, n] : by_state) {
        report << (first ? " " : ", ") << n << " " << state;
        first = false;
      }
      // squeue forgets an array task cancelled before it started
      const auto expected = expected_tasks.find(job);
      if (expected != expected_tasks.end() && tasks.size() < expected->second) {
        report << ", " << expected->second - tasks.size()
               << " not reported (cancelled before it started?)";
        status = std::max(status, 1);
      }
      report << " (" << source << ")\n";
      for (const SlurmTask& t : tasks)
        report << "  " << t.id << "  " << t.state << "  " << t.elapsed
               << (t.exit_code.empty() ? "" : "  exit " + t.exit_code)
               << (t.reason.empty() ? "" : "  (" + t.reason + ")") << "\n";
    }
    if (going && status < 2) status = 3;
    if (!wait || !going || status == 2) {
      out << report.str();
      return status;
    }
    std::this_thread::sleep_for(std::chrono::duration<double>(poll_s));
  }
}

}  // namespace conesim::sim
