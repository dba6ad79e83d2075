#include "core/rng.hpp"

#include <cmath>

namespace conesim::core::detail {

namespace {

// Marsaglia and Tsang's area of each of the 256 layers
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
  t.x[0] = kLayerArea / density(kZigguratTailStart);
  t.x[1] = kZigguratTailStart;
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

}  // namespace conesim::core::detail
