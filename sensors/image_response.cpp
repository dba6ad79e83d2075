#include "sensors/image_response.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <sstream>

#include "core/rng.hpp"

namespace conesim::sensors {
namespace {

// each level's output is drawn by inverse-CDF sampling from this many equally likely values
constexpr int kDraws = 256;

// the standard normal quantile of p in (0, 1), by bisection on erfc (once per table entry)
double normal_quantile(double p) {
  double lo = -10.0, hi = 10.0;
  for (int i = 0; i < 80; ++i) {
    const double mid = 0.5 * (lo + hi);
    (0.5 * std::erfc(-mid / std::numbers::sqrt2) < p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace

double ImageResponse::noise_sigma(double level) const {
  if (!(full_well_e > 0.0)) return 0.0;
  const double electrons = std::max(0.0, level) / 255.0 * full_well_e;
  return std::sqrt(electrons + read_noise_e * read_noise_e) * 255.0 / full_well_e;
}

std::string ImageResponse::validate() const {
  std::ostringstream e;
  if (!(exposure_ev >= -4.0 && exposure_ev <= 4.0))
    e << "exposure_ev: expected -4 to 4 stops, got " << exposure_ev;
  else if (!(gamma >= 0.2 && gamma <= 5.0))
    e << "gamma: expected 0.2 to 5, got " << gamma;
  else if (!(full_well_e == 0.0 || (full_well_e >= 100.0 && full_well_e <= 1e6)))
    e << "full_well_e: expected 0 (no noise) or 100 to 1e6 electrons, got " << full_well_e;
  else if (!(read_noise_e >= 0.0 && read_noise_e <= 1000.0))
    e << "read_noise_e: expected 0 to 1000 electrons, got " << read_noise_e;
  return e.str();
}

ImageResponseFilter::ImageResponseFilter(const ImageResponse& response, uint64_t seed)
    : response_(response), seed_(seed) {
  // each input level's output: its level after the exposure, plus the noise at one of kDraws
  // equally likely quantiles, clipped and through the gamma curve (the draw picks the quantile,
  // so the output follows the noise's distribution to its 1/512 and 511/512 quantiles)
  const double gain = std::exp2(response.exposure_ev);
  const bool noisy = response.full_well_e > 0.0;
  std::vector<double> quantiles(kDraws, 0.0);
  if (noisy)
    for (int k = 0; k < kDraws; ++k) quantiles[k] = normal_quantile((k + 0.5) / kDraws);
  outputs_.resize(256 * static_cast<size_t>(kDraws));
  for (int level = 0; level < 256; ++level) {
    const double exposed = std::min(255.0, level * gain);
    const double sigma = response.noise_sigma(exposed);
    for (int k = 0; k < kDraws; ++k) {
      const double value = std::clamp(exposed + sigma * quantiles[k], 0.0, 255.0);
      const double encoded = 255.0 * std::pow(value / 255.0, 1.0 / response.gamma);
      outputs_[static_cast<size_t>(level) * kDraws + k] =
          static_cast<uint8_t>(std::clamp(std::lround(encoded), 0L, 255L));
    }
  }
}

void ImageResponseFilter::apply(core::RgbImage& image, uint64_t key) const {
  if (response_.identity()) return;
  core::Rng image_rng(core::derive_seed(seed_, key));
  core::Xoshiro256 draws(image_rng);
  uint8_t* sample = image.rgb.data();
  const size_t n = image.rgb.size();
  size_t i = 0;
  // eight samples per 64 random bits, one byte each picking the sample's quantile
  for (; i + 8 <= n; i += 8) {
    uint64_t bits = draws();
    for (int j = 0; j < 8; ++j, bits >>= 8)
      sample[i + j] = outputs_[static_cast<size_t>(sample[i + j]) * kDraws + (bits & 0xff)];
  }
  uint64_t bits = draws();
  for (; i < n; ++i, bits >>= 8)
    sample[i] = outputs_[static_cast<size_t>(sample[i]) * kDraws + (bits & 0xff)];
}

}  // namespace conesim::sensors
