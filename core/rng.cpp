#include "core/rng.hpp"

#include <cmath>

namespace conesim::core::detail {

namespace {

// Marsaglia and Tsang's constants for 256 layers: where the tail starts and each layer's area
constexpr double kTailStart = 3.6541528853610088;
constexpr double kLayerArea = 4.92867323399e-3;

double density(double x) {
  return std::exp(-0.5 * x * x);
}

}  // namespace

ZigguratTable make_ziggurat_table() {
  // the base layer is the rectangle under f(R) plus the tail, as one rectangle of equal area;
  // each layer above has the same area: x[i] (f(x[i+1]) - f(x[i])) = kLayerArea
  ZigguratTable t{};
  constexpr int n = ZigguratTable::kLayers;
  t.x[0] = kLayerArea / density(kTailStart);
  t.x[1] = kTailStart;
  for (int i = 1; i < n - 1; ++i)
    t.x[i + 1] = std::sqrt(-2.0 * std::log(kLayerArea / t.x[i] + density(t.x[i])));
  t.x[n] = 0.0;
  for (int i = 0; i <= n; ++i) {
    t.f[i] = density(t.x[i]);
    t.x_single[i] = static_cast<float>(t.x[i]);
    t.f_single[i] = static_cast<float>(t.f[i]);
  }
  return t;
}

double ziggurat_tail(Rng& rng, bool negative) {
  // x = R + a with a exponential of rate R, kept with probability exp(-a^2 / 2)
  for (;;) {
    const double a = -std::log(1.0 - uniform(rng, 0.0, 1.0)) / kTailStart;
    const double b = -std::log(1.0 - uniform(rng, 0.0, 1.0));
    if (b + b >= a * a) return negative ? -(kTailStart + a) : kTailStart + a;
  }
}

}  // namespace conesim::core::detail
