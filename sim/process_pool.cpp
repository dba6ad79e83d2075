#include "sim/process_pool.hpp"

#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <fstream>
#include <map>
#include <thread>

#include "sim/interrupt.hpp"

namespace conesim::sim {

namespace fs = std::filesystem;

namespace {

// starts `argv` with stdout and stderr into log_file; returns the child's pid
pid_t spawn(const std::vector<std::string>& argv, const fs::path& log_file) {
  const pid_t pid = fork();
  if (pid < 0) return -1;
  if (pid == 0) {
    const int fd = open(log_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0) {
      dup2(fd, STDOUT_FILENO);
      dup2(fd, STDERR_FILENO);
      close(fd);
    }
    std::vector<char*> args;
    for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    execv(args[0], args.data());
    _exit(127);
  }
  return pid;
}

// the exit status of a finished child: its code, or 128 + the signal that ended it
int exit_status(int status) {
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

}  // namespace

void run_processes(const std::vector<ProcessJob>& jobs, int parallel,
                   const std::function<void(size_t)>& on_started,
                   const std::function<void(size_t, int)>& on_done) {
  // start while there is room, then collect the children of ours that ended; on SIGINT or
  // SIGTERM start nothing more, pass the signal on to the children and wait for them
  std::map<pid_t, size_t> running;
  size_t next = 0;
  int forwarded = 0;
  while ((next < jobs.size() && interrupt_signal() == 0) || !running.empty()) {
    while (interrupt_signal() == 0 && next < jobs.size() &&
           static_cast<int>(running.size()) < std::max(parallel, 1)) {
      if (on_started) on_started(next);
      const pid_t pid = spawn(jobs[next].argv, jobs[next].log_file);
      if (pid > 0)
        running[pid] = next;
      else
        on_done(next, 127);
      ++next;
    }
    if (const int signal = interrupt_signal(); signal != 0 && forwarded != signal) {
      for (const auto& [pid, index] : running) kill(pid, signal);
      forwarded = signal;
    }
    if (running.empty()) continue;
    // polled, so that a signal arriving between the check and the wait is seen within 20 ms
    int status = 0;
    const pid_t pid = waitpid(-1, &status, WNOHANG);
    if (pid == 0 || (pid < 0 && errno == EINTR)) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      continue;
    }
    if (pid < 0) break;
    const auto it = running.find(pid);
    if (it == running.end()) continue;
    const size_t index = it->second;
    running.erase(it);
    on_done(index, exit_status(status));
  }
}

std::string last_log_line(const fs::path& file) {
  std::ifstream in(file);
  std::string line, last;
  while (std::getline(in, line)) {
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
    if (!line.empty()) last = line;
  }
  return last;
}

}  // namespace conesim::sim
