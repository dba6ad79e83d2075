#pragma once
// A minimal PNG encoder (8-bit RGB, zlib deflate) for dumping camera images without OpenCV.

#include <cstdint>
#include <string>
#include <vector>

#include "core/measurements.hpp"

namespace conesim::sensors {

/// The image encoded as a PNG file (8-bit RGB, no filtering, zlib compression).
std::vector<uint8_t> encode_png(const core::RgbImage& image);

/// A one-channel image encoded as a PNG file (colour type 0): `bit_depth` 8 takes one byte per
/// pixel, 16 two (big-endian, as PNG stores them); rows top to bottom. Empty when the sizes do
/// not match.
std::vector<uint8_t> encode_grey_png(int width_px, int height_px, int bit_depth,
                                     const std::vector<uint8_t>& pixels);

/// Writes bytes to a file; returns an empty string on success, else what went wrong.
std::string write_file_bytes(const std::string& path, const std::vector<uint8_t>& bytes);

/// Writes the image as a PNG file; returns an empty string on success, else what went wrong.
std::string write_png(const std::string& path, const core::RgbImage& image);

/// A grey image of a depth map for viewing: near is white, max_depth_m and beyond (and the sky)
/// black.
core::RgbImage depth_to_image(const std::vector<float>& depth_m, int width_px, int height_px,
                              double max_depth_m);

}  // namespace conesim::sensors
