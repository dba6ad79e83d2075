#pragma once
// The one source of randomness: a seeded generator passed in by the caller.

#include <bit>
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
inline bool bernoulli(Rng& rng, double p) {
  return uniform(rng, 0.0, 1.0) < p;
}

}  // namespace conesim::core

namespace conesim::core {

namespace detail {

/// The 256 layers of the standard normal's ziggurat: x[0] is the width of the base layer's
/// equal-area rectangle, x[1] = R where the tail starts, x[256] = 0; f[i] = exp(-x[i]^2 / 2).
struct ZigguratTable {
  static constexpr int kLayers = 256;
  double x[kLayers + 1];
  double f[kLayers + 1];
  /// x and f in single precision, for ZigguratNormals.
  float x_single[kLayers + 1];
  float f_single[kLayers + 1];
};

/// Builds the table (rng.cpp).
ZigguratTable make_ziggurat_table();

/// The table, built once on first use and never changed after.
inline const ZigguratTable& ziggurat_table() {
  static const ZigguratTable table = make_ziggurat_table();
  return table;
}

/// The sample beyond R (layer 0's tail), by Marsaglia's 1964 method.
double ziggurat_tail(Rng& rng, bool negative);

}  // namespace detail

/// A standard normal sample by the ziggurat method (Marsaglia and Tsang 2000, 256 layers; the
/// layer, the sign and the abscissa come from disjoint bits of one 64-bit output, as Doornik 2005
/// advises). About 99 % of samples cost one generator output and no transcendental function.
/// The same seed gives the same sequence; it differs from standard_normal()'s sequence.
inline double ziggurat_normal(Rng& rng) {
  const detail::ZigguratTable& t = detail::ziggurat_table();
  for (;;) {
    // layer from bits 0-7, sign from bit 8, abscissa in [0, x[layer]) from the top 53 bits
    const uint64_t bits = rng();
    const unsigned layer = static_cast<unsigned>(bits & 0xFF);
    const bool negative = (bits >> 8) & 1;
    const double x = static_cast<double>(bits >> 11) * 0x1.0p-53 * t.x[layer];

    // inside the layer's rectangle that lies wholly under the curve (the sign set without a
    // branch: a coin flip is the worst case for the branch predictor)
    if (x < t.x[layer + 1])
      return std::bit_cast<double>(std::bit_cast<uint64_t>(x) | ((bits & 0x100) << 55));

    // the base layer beyond R is the tail; elsewhere a point of the wedge under the curve
    if (layer == 0) return detail::ziggurat_tail(rng, negative);
    const double y = t.f[layer] + uniform(rng, 0.0, 1.0) * (t.f[layer + 1] - t.f[layer]);
    if (y < std::exp(-0.5 * x * x)) return negative ? -x : x;
  }
}

/// Single-precision standard normal samples by the same ziggurat, two from each 64-bit output
/// of the generator (each half: layer from 8 bits, sign from 1, abscissa from the top 23), for
/// hot loops that need many samples of float precision, such as sensor noise. Holds the
/// generator by reference and the unused half of the last output; the same seed gives the same
/// sequence.
class ZigguratNormals {
 public:
  explicit ZigguratNormals(Rng& rng) : rng_(rng), table_(detail::ziggurat_table()) {}

  /// The next sample.
  float operator()() {
    for (;;) {
      // the next 32 random bits: the spare half of the last output, or a new output
      uint32_t bits;
      if (has_spare_) {
        bits = spare_;
        has_spare_ = false;
      } else {
        const uint64_t both = rng_();
        bits = static_cast<uint32_t>(both);
        spare_ = static_cast<uint32_t>(both >> 32);
        has_spare_ = true;
      }
      const unsigned layer = bits & 0xFF;
      const bool negative = (bits >> 8) & 1;
      const float x = static_cast<float>(bits >> 9) * 0x1.0p-23f * table_.x_single[layer];

      // inside the layer's rectangle that lies wholly under the curve (sign without a branch)
      if (x < table_.x_single[layer + 1])
        return std::bit_cast<float>(std::bit_cast<uint32_t>(x) | ((bits & 0x100u) << 23));

      // the tail, or a point of the wedge under the curve (rare: drawn in double precision)
      if (layer == 0) return static_cast<float>(detail::ziggurat_tail(rng_, negative));
      const double y =
          table_.f[layer] + uniform(rng_, 0.0, 1.0) * (table_.f[layer + 1] - table_.f[layer]);
      if (y < std::exp(-0.5 * static_cast<double>(x) * x)) return negative ? -x : x;
    }
  }

 private:
  Rng& rng_;
  const detail::ZigguratTable& table_;
  uint32_t spare_ = 0;
  bool has_spare_ = false;
};

}  // namespace conesim::core
