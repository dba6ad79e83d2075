// Tests that the camera's sensor response does what a user of the images would measure: noise
// of the configured size at each brightness, exposure in stops, a gamma curve, the same noise
// for the same seed and frame and fresh noise for every other.

#include "sensors/image_response.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <vector>

namespace conesim::sensors {
namespace {

// an image of one grey level
core::RgbImage flat(int level, int width = 640, int height = 480) {
  core::RgbImage image;
  image.width_px = width;
  image.height_px = height;
  image.rgb.assign(3 * static_cast<size_t>(width) * height, static_cast<uint8_t>(level));
  return image;
}

struct Moments {
  double mean = 0.0, sigma = 0.0;
};
Moments moments(const core::RgbImage& image) {
  double sum = 0.0, squares = 0.0;
  for (uint8_t v : image.rgb) sum += v, squares += static_cast<double>(v) * v;
  const double n = static_cast<double>(image.rgb.size());
  const double mean = sum / n;
  return {mean, std::sqrt(squares / n - mean * mean)};
}

TEST(ImageResponse, NoiseHasTheSensorsSigmaAtEveryLevel) {
  const ImageResponse response;  // 10 000 electrons, 10 read noise
  const ImageResponseFilter filter(response, 7);
  for (int level : {10, 60, 128, 200}) {
    core::RgbImage image = flat(level);
    filter.apply(image, 1);
    const Moments m = moments(image);
    // shot and read noise in levels; 8-bit rounding adds 1/12 of a level squared
    const double sigma = std::sqrt(std::pow(response.noise_sigma(level), 2) + 1.0 / 12.0);
    EXPECT_NEAR(m.mean, level, 0.02) << level;
    EXPECT_NEAR(m.sigma, sigma, 0.05 * sigma) << level;
  }
  // brighter is noisier in levels (shot noise), as on a real sensor
  EXPECT_GT(response.noise_sigma(200), 1.5 * response.noise_sigma(30));
}

TEST(ImageResponse, SameSeedAndFrameSameNoiseAnyOtherFresh) {
  const ImageResponseFilter filter(ImageResponse{}, 3), other_seed(ImageResponse{}, 4);
  core::RgbImage a = flat(100), b = flat(100), c = flat(100), d = flat(100);
  filter.apply(a, 10);
  filter.apply(b, 10);
  filter.apply(c, 11);
  other_seed.apply(d, 10);
  EXPECT_EQ(a.rgb, b.rgb);
  EXPECT_NE(a.rgb, c.rgb);
  EXPECT_NE(a.rgb, d.rgb);
  // no two rows share their noise (rows read the table from random places)
  const size_t row = 3 * 640;
  int same_rows = 0;
  for (int r = 1; r < 480; ++r)
    same_rows += std::equal(a.rgb.begin(), a.rgb.begin() + row, a.rgb.begin() + r * row);
  EXPECT_EQ(same_rows, 0);
}

TEST(ImageResponse, ExposureIsInStopsAndGammaBendsTheLevels) {
  ImageResponse response;
  response.full_well_e = 0.0;  // no noise: the curve alone
  response.exposure_ev = 1.0;
  core::RgbImage image = flat(60);
  ImageResponseFilter(response, 1).apply(image, 0);
  EXPECT_EQ(image.rgb[0], 120);
  image = flat(200);  // saturates
  ImageResponseFilter(response, 1).apply(image, 0);
  EXPECT_EQ(image.rgb[0], 255);
  response.exposure_ev = 0.0;
  response.gamma = 2.2;
  image = flat(64);
  ImageResponseFilter(response, 1).apply(image, 0);
  EXPECT_EQ(image.rgb[0],
            static_cast<uint8_t>(std::lround(255.0 * std::pow(64.0 / 255.0, 1 / 2.2))));
  // the identity response leaves every level as it is
  response.gamma = 1.0;
  core::RgbImage ramp = flat(0, 256, 1);
  for (int i = 0; i < 768; ++i) ramp.rgb[i] = static_cast<uint8_t>(i / 3);
  const core::RgbImage before = ramp;
  ImageResponseFilter(response, 1).apply(ramp, 0);
  EXPECT_EQ(ramp.rgb, before.rgb);
}

TEST(ImageResponse, ValidateNamesTheBadKey) {
  ImageResponse r;
  EXPECT_EQ(r.validate(), "");
  r.exposure_ev = 9.0;
  EXPECT_EQ(r.validate().rfind("exposure_ev:", 0), 0u);
  r = {};
  r.gamma = 0.0;
  EXPECT_EQ(r.validate().rfind("gamma:", 0), 0u);
  r = {};
  r.full_well_e = 5.0;
  EXPECT_EQ(r.validate().rfind("full_well_e:", 0), 0u);
  r = {};
  r.read_noise_e = std::nan("");
  EXPECT_EQ(r.validate().rfind("read_noise_e:", 0), 0u);
}

}  // namespace
}  // namespace conesim::sensors
