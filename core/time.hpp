#pragma once
// The one sim clock: integer microseconds, so that schedules never drift.

#include <cmath>
#include <cstdint>
#include <ctime>
#include <limits>

namespace conesim::core {

/// Sim time or a duration, microseconds.
using TimeUs = int64_t;

inline constexpr TimeUs kUsPerSecond = 1'000'000;

/// The physics step, microseconds. Every schedule (sensor rates, the driver, the camera) is a
/// whole number of steps, so that "t % period == 0" fires at every sample. The car
/// behaved the same at 0.5, 1 and 2 ms (docs/vehicle.md); 2 ms halves the physics cost.
inline constexpr TimeUs kPhysicsStepUs = 2000;

/// True when a rate's period is a whole number of physics steps.
inline bool whole_physics_steps(double rate_hz) {
  if (!(rate_hz > 0.0)) return false;
  const double steps = 1e6 / rate_hz / static_cast<double>(kPhysicsStepUs);
  return std::round(steps) >= 1.0 && std::abs(steps - std::round(steps)) < 1e-9;
}

/// Seconds as a double (for physics and output).
inline constexpr double to_seconds(TimeUs t) { return static_cast<double>(t) * 1e-6; }

/// Whole microseconds from seconds, rounded to nearest. Saturates at the clock's limits (about
/// +-292,000 years) instead of overflowing, and NaN gives 0: a conversion never has undefined
/// behaviour, whatever a scenario asks for.
inline constexpr TimeUs from_seconds(double s) {
  // 2^63 us is exactly representable; anything at or past it does not fit
  constexpr double kLimitUs = 9223372036854775808.0;
  const double us = s * 1e6 + (s >= 0 ? 0.5 : -0.5);
  if (us != us) return 0;
  if (us >= kLimitUs) return std::numeric_limits<TimeUs>::max();
  if (us <= -kLimitUs) return std::numeric_limits<TimeUs>::min();
  return static_cast<TimeUs>(us);
}

/// CPU time the calling thread has used, ms: for timings that other processes on a shared
/// machine must not inflate (wall time counts their time slices too).
inline double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return 1e3 * static_cast<double>(ts.tv_sec) + 1e-6 * static_cast<double>(ts.tv_nsec);
}

}  // namespace conesim::core
