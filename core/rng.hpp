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

/// xoshiro256++ (Blackman and Vigna 2021): a small generator several times faster than Rng, for
/// hot loops that draw many numbers (sensor noise). Seeded from an Rng, so that the run's seed
/// still decides every number; the same seed gives the same sequence on every machine.
class Xoshiro256 {
 public:
  using result_type = uint64_t;
  /// Takes its state from four outputs of seed_source.
  explicit Xoshiro256(Rng& seed_source) {
    for (uint64_t& word : state_) word = seed_source();
    // the all-zero state is the one state the generator cannot leave
    if ((state_[0] | state_[1] | state_[2] | state_[3]) == 0) state_[0] = 1;
  }
  static constexpr result_type min() { return 0; }
  static constexpr result_type max() { return ~result_type{0}; }

  /// The next 64 random bits.
  result_type operator()() {
    const uint64_t out = std::rotl(state_[0] + state_[3], 23) + state_[0];
    const uint64_t shifted = state_[1] << 17;
    state_[2] ^= state_[0];
    state_[3] ^= state_[1];
    state_[1] ^= state_[2];
    state_[0] ^= state_[3];
    state_[2] ^= shifted;
    state_[3] = std::rotl(state_[3], 45);
    return out;
  }

 private:
  uint64_t state_[4];
};

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

/// Where the tail of the base layer starts (R in Marsaglia and Tsang 2000).
inline constexpr double kZigguratTailStart = 3.6541528853610088;

/// A uniform double in [0, 1) from the top 53 bits of a generator output.
inline double unit_interval(uint64_t bits) {
  return static_cast<double>(bits >> 11) * 0x1.0p-53;
}

/// The sample beyond R (layer 0's tail), by Marsaglia's 1964 method: R + a with a exponential of
/// rate R, kept with probability exp(-a^2 / 2).
template <typename Generator>
double ziggurat_tail(Generator& bits, bool negative) {
  for (;;) {
    const double a = -std::log(1.0 - unit_interval(bits())) / kZigguratTailStart;
    const double b = -std::log(1.0 - unit_interval(bits()));
    if (b + b >= a * a) return negative ? -(kZigguratTailStart + a) : kZigguratTailStart + a;
  }
}

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
/// (each half: layer from 8 bits, sign from 1, abscissa from the top 23), for hot loops that need
/// many samples of float precision, such as sensor noise. The bits come from a Xoshiro256 seeded
/// from the Rng at construction (several times faster than Rng), and the samples are drawn a block
/// at a time; the same seed gives the same sequence.
class ZigguratNormals {
 public:
  explicit ZigguratNormals(Rng& rng) : bits_(rng), table_(detail::ziggurat_table()) {}

  /// The next sample.
  float operator()() {
    if (next_ == kBlock) refill();
    return block_[next_++];
  }

  /// The samples ready to be drawn, in the order operator() gives them, and their count (at
  /// least one: a new block when none is left). For hot loops, which read them from the pointer
  /// and then take() as many as they used.
  const float* ready(int& count) {
    if (next_ == kBlock) refill();
    count = kBlock - next_;
    return block_ + next_;
  }

  /// Draws the first count samples that ready() offered (count at most what it offered).
  void take(int count) { next_ += count; }

 private:
  static constexpr int kBlock = 64;

  // the next block of samples, two from each output of the generator: the block's bits first
  // (the generator's own dependency chain alone), then every sample as if it fell inside its
  // layer's rectangle (no branch), then the rare others drawn again, in order
  void refill() {
    uint32_t half_bits[kBlock];
    for (int i = 0; i < kBlock; i += 2) {
      const uint64_t both = bits_();
      half_bits[i] = static_cast<uint32_t>(both);
      half_bits[i + 1] = static_cast<uint32_t>(both >> 32);
    }
    bool rejected[kBlock];
    for (int i = 0; i < kBlock; ++i) {
      // layer from 8 bits, sign from 1, abscissa from the top 23 (exact in an int32)
      const uint32_t bits = half_bits[i];
      const unsigned layer = bits & 0xFF;
      const float x =
          static_cast<float>(static_cast<int32_t>(bits >> 9)) * 0x1.0p-23f * table_.x_single[layer];
      block_[i] = std::bit_cast<float>(std::bit_cast<uint32_t>(x) | ((bits & 0x100u) << 23));
      rejected[i] = !(x < table_.x_single[layer + 1]);
    }
    for (int i = 0; i < kBlock; ++i)
      if (rejected[i]) [[unlikely]]
        block_[i] = outside(half_bits[i]);
    next_ = 0;
  }

  // a sample whose first 32 bits fell outside their layer's rectangle: the tail, a point of the
  // wedge under the curve, or a new draw (rare: in double precision)
  float outside(uint32_t bits) {
    for (;;) {
      const unsigned layer = bits & 0xFF;
      const bool negative = (bits >> 8) & 1;
      const float x = static_cast<float>(bits >> 9) * 0x1.0p-23f * table_.x_single[layer];
      if (x < table_.x_single[layer + 1]) return negative ? -x : x;
      if (layer == 0) return static_cast<float>(detail::ziggurat_tail(bits_, negative));
      const double y = table_.f[layer] +
                       detail::unit_interval(bits_()) * (table_.f[layer + 1] - table_.f[layer]);
      if (y < std::exp(-0.5 * static_cast<double>(x) * x)) return negative ? -x : x;
      bits = static_cast<uint32_t>(bits_());
    }
  }

  Xoshiro256 bits_;
  const detail::ZigguratTable& table_;
  float block_[kBlock];
  int next_ = kBlock;
};

}  // namespace conesim::core
