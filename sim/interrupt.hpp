#pragma once
// Ctrl-C and SIGTERM: the handler only records the signal (async-signal-safe); the run loop,
// the process pool and the commands ask for it and stop at their next check.

namespace conesim::sim {

/// Installs handlers for SIGINT and SIGTERM that record the signal and return. Without
/// SA_RESTART, so that a blocking call returns early. Call once, from the command's main.
void install_interrupt_handlers();

/// The signal that asked the process to stop (SIGINT, SIGTERM), or 0 when none did.
int interrupt_signal();

/// The exit status of a command stopped by a signal: 128 + the signal, as shells report it
/// (130 for SIGINT, 143 for SIGTERM).
int interrupted_exit_status(int signal);

/// The signal's name: "SIGINT", "SIGTERM" or "signal N".
const char* signal_name(int signal);

/// Records `signal` as if it had arrived (tests).
void request_interrupt(int signal);

}  // namespace conesim::sim
