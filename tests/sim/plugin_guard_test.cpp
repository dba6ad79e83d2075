// A plug-in's calls under their guard, in both of its ways: on a thread of its own (a library
// user, no hang handler) and on the caller's thread under a watchdog (`conesim run`).
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <thread>

#include "sim/autonomy.hpp"

namespace conesim::sim {
namespace {

using namespace std::chrono_literals;

PluginSpec spec(double budget_ms) {
  PluginSpec s;
  s.kind = PluginKind::kDriver;
  s.file = "/nowhere/libtest_guard.so";
  s.time_budget_ms = budget_ms;
  return s;
}

std::string failure_of(const PluginGuard& guard, const std::function<void()>& f) {
  try {
    guard.call("update", f);
  } catch (const PluginFailure& e) {
    return e.what();
  }
  return "";
}

// what every guard does, whichever thread runs the call
void expect_common_behaviour(const PluginGuard& guard) {
  EXPECT_EQ(guard.call("update", [] { return 42; }), 42);
  const std::string threw = failure_of(guard, [] { throw std::runtime_error("injected"); });
  EXPECT_EQ(threw, guard.label() + " threw in update: injected");
  const std::string odd = failure_of(guard, [] { throw 7; });
  EXPECT_EQ(odd, guard.label() + " threw in update: an exception that is not a std::exception");
  // still usable after a call threw
  EXPECT_EQ(guard.call("status", [] { return std::string("ok"); }), "ok");
}

struct HandlerReset {
  ~HandlerReset() { set_plugin_hang_handler(nullptr); }
};

[[noreturn]] void print_and_exit(const std::string& reason) {
  std::fprintf(stderr, "hang: %s\n", reason.c_str());
  std::fflush(stderr);
  std::_Exit(3);
}

TEST(PluginGuard, OnItsOwnThreadWithoutAHangHandler) {
  PluginGuard guard(spec(200.0));
  expect_common_behaviour(guard);
  // a call that does not return within the budget is left behind; the plug-in is then refused
  const std::string late = failure_of(guard, [] { std::this_thread::sleep_for(600ms); });
  EXPECT_EQ(late, guard.label() + " did not return from update within its time budget of 200 ms");
  EXPECT_TRUE(guard.abandoned());
  EXPECT_NE(failure_of(guard, [] {}).find("is not answering"), std::string::npos);
  std::this_thread::sleep_for(500ms);  // the call left behind ends before the test does
}

TEST(PluginGuard, OnTheCallersThreadUnderAWatchdog) {
  HandlerReset reset;
  set_plugin_hang_handler(print_and_exit);
  PluginGuard guard(spec(200.0));
  expect_common_behaviour(guard);
  // the call runs on this thread
  const std::thread::id here = std::this_thread::get_id();
  EXPECT_EQ(guard.call("update", [] { return std::this_thread::get_id(); }), here);
  // late but returned (1.5 budgets): a failure naming how long it took; never abandoned
  const std::string late = failure_of(guard, [] { std::this_thread::sleep_for(300ms); });
  EXPECT_EQ(late.rfind(guard.label() +
                           " did not return from update within its time budget of 200 ms (it took ",
                       0),
            0u)
      << late;
  EXPECT_FALSE(guard.abandoned());
  EXPECT_EQ(guard.call("update", [] { return 1; }), 1);
}

TEST(PluginGuardDeathTest, ACallThatNeverReturnsGoesToTheHangHandler) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(
      {
        set_plugin_hang_handler(print_and_exit);
        PluginGuard guard(spec(100.0));
        guard.call("process", [] {
          for (;;) std::this_thread::sleep_for(1s);
        });
      },
      testing::ExitedWithCode(3),
      "hang: driver plug-in 'libtest_guard' .* did not return from process within its time "
      "budget of 100 ms \\(still running after [0-9]+ ms\\)");
}

}  // namespace
}  // namespace conesim::sim
