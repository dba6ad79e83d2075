#pragma once
// What a camera's sensor does to the light the renderer draws: the exposure scales it, the
// photo-electrons carry shot noise and the read-out adds its own, and a gamma curve encodes the
// result in 8 bits. The renderer's image is the picture at exposure 0 EV, noiseless and linear.

#include <cstdint>
#include <string>
#include <vector>

#include "core/measurements.hpp"

namespace conesim::sensors {

/// The sensor's response. Defaults: a global-shutter machine-vision sensor of the kind FS teams
/// mount (Sony IMX-class, about 10 000 electrons at full scale and 10 of read noise: 1-2 grey
/// levels of noise at mid grey) exposed as the renderer's image.
struct ImageResponse {
  /// Exposure against the renderer's image, stops: each level times 2^exposure_ev.
  double exposure_ev = 0.0;
  /// Encoding gamma: out = 255 (in / 255)^(1 / gamma); 1 leaves the levels as rendered.
  double gamma = 1.0;
  /// Electrons at a full-scale level (shot noise: the square root of a level's electrons);
  /// 0 switches all noise off.
  double full_well_e = 10000.0;
  /// Read-out noise, electrons (one sigma).
  double read_noise_e = 10.0;

  /// No change at all: 0 EV, gamma 1, no noise.
  bool identity() const { return exposure_ev == 0.0 && gamma == 1.0 && full_well_e == 0.0; }
  /// The noise's sigma at a level (0-255 after the exposure), in levels.
  double noise_sigma(double level) const;
  /// Empty when usable; otherwise "key: what was expected" for the first bad value.
  std::string validate() const;
};

/// Applies a response to 8-bit RGB images, the noise drawn from the seed and a key per image
/// (the same seed and key give the same image bit for bit; keys differ per frame and eye).
class ImageResponseFilter {
 public:
  ImageResponseFilter(const ImageResponse& response, uint64_t seed);
  /// Every sample of `image` through the response.
  void apply(core::RgbImage& image, uint64_t key) const;
  const ImageResponse& response() const { return response_; }

 private:
  ImageResponse response_;
  uint64_t seed_ = 0;
  // per input level, kDraws (256) equally likely outputs (the .cpp)
  std::vector<uint8_t> outputs_;
};

}  // namespace conesim::sensors
