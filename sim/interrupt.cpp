#include "sim/interrupt.hpp"

#include <atomic>
#include <csignal>

namespace conesim::sim {

namespace {

// the one piece of process-wide mutable state: a signal handler can reach nothing else. A
// lock-free atomic is safe to store from a handler and to read from any thread.
std::atomic<int> g_signal{0};
static_assert(std::atomic<int>::is_always_lock_free);

extern "C" void record_signal(int signal) {
  g_signal.store(signal, std::memory_order_relaxed);
}

}  // namespace

void install_interrupt_handlers() {
  struct sigaction action {};
  action.sa_handler = record_signal;
  sigemptyset(&action.sa_mask);
  action.sa_flags = 0;  // no SA_RESTART: wait() and sleeps return early
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

int interrupt_signal() {
  return g_signal.load(std::memory_order_relaxed);
}

int interrupted_exit_status(int signal) {
  return 128 + signal;
}

const char* signal_name(int signal) {
  switch (signal) {
    case SIGINT:
      return "SIGINT";
    case SIGTERM:
      return "SIGTERM";
    default:
      return "a signal";
  }
}

void request_interrupt(int signal) {
  g_signal.store(signal, std::memory_order_relaxed);
}

}  // namespace conesim::sim
