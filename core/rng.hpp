#pragma once
// The one source of randomness: a seeded generator passed in by the caller.

#include <cmath>
#include <cstdint>
#include <random>

namespace conesim::core {

/// 64-bit Mersenne Twister; identical sequences for identical seeds on every machine.
using Rng = std::mt19937_64;

/// Uniform double in [lo, hi), computed from the raw generator output so that the sequence
/// does not depend on the standard library's distribution implementation.
inline double uniform(Rng& rng, double lo, double hi) {
  const double u = static_cast<double>(rng() >> 11) * 0x1.0p-53;
  return lo + (hi - lo) * u;
}

/// Uniform integer in [lo, hi].
inline int64_t uniform_int(Rng& rng, int64_t lo, int64_t hi) {
  const uint64_t span = static_cast<uint64_t>(hi - lo) + 1;
  return lo + static_cast<int64_t>(rng() % span);
}

/// A child seed for an independent stream (sub-generators stay independent of call order).
inline uint64_t derive_seed(uint64_t seed, uint64_t stream) {
  uint64_t z = seed + 0x9E3779B97F4A7C15ull * (stream + 1);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

}  // namespace conesim::core

namespace conesim::core {

/// A standard normal sample (Box-Muller on the raw generator, so it is the same everywhere).
inline double standard_normal(Rng& rng) {
  double u1 = uniform(rng, 0.0, 1.0);
  while (u1 <= 0.0) u1 = uniform(rng, 0.0, 1.0);
  const double u2 = uniform(rng, 0.0, 1.0);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
}

/// A normal sample with the given mean and standard deviation.
inline double gaussian(Rng& rng, double mean, double sigma) {
  return mean + sigma * standard_normal(rng);
}

/// True with probability p.
inline bool bernoulli(Rng& rng, double p) { return uniform(rng, 0.0, 1.0) < p; }

}  // namespace conesim::core
