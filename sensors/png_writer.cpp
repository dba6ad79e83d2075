#include "sensors/png_writer.hpp"

#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <fstream>

namespace conesim::sensors {

namespace {

// appends a big-endian 32-bit integer
void put_u32(std::vector<uint8_t>& out, uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8) out.push_back(static_cast<uint8_t>(v >> shift));
}

// appends a chunk: length, type, data, CRC of type and data
void put_chunk(std::vector<uint8_t>& out, const char type[4], const std::vector<uint8_t>& data) {
  put_u32(out, static_cast<uint32_t>(data.size()));
  const size_t type_at = out.size();
  out.insert(out.end(), type, type + 4);
  out.insert(out.end(), data.begin(), data.end());
  const uLong crc = crc32(0L, out.data() + type_at, static_cast<uInt>(4 + data.size()));
  put_u32(out, static_cast<uint32_t>(crc));
}

// a PNG of rows of `row_bytes` each (filter type 0), with the header's bit depth and colour type
std::vector<uint8_t> encode_rows(int w, int h, uint8_t bit_depth, uint8_t colour_type,
                                 size_t row_bytes, const uint8_t* pixels) {
  std::vector<uint8_t> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};

  // header: size, bit depth, colour type, deflate, no filter, no interlace
  std::vector<uint8_t> header;
  put_u32(header, static_cast<uint32_t>(w));
  put_u32(header, static_cast<uint32_t>(h));
  header.insert(header.end(), {bit_depth, colour_type, 0, 0, 0});
  put_chunk(png, "IHDR", header);

  // scanlines, each led by filter type 0, compressed as one zlib stream
  std::vector<uint8_t> raw;
  raw.reserve((row_bytes + 1) * h);
  for (int r = 0; r < h; ++r) {
    raw.push_back(0);
    raw.insert(raw.end(), pixels + r * row_bytes, pixels + (r + 1) * row_bytes);
  }
  uLongf packed_size = compressBound(static_cast<uLong>(raw.size()));
  std::vector<uint8_t> packed(packed_size);
  compress2(packed.data(), &packed_size, raw.data(), static_cast<uLong>(raw.size()), 6);
  packed.resize(packed_size);
  put_chunk(png, "IDAT", packed);
  put_chunk(png, "IEND", {});
  return png;
}

}  // namespace

std::vector<uint8_t> encode_png(const core::RgbImage& image) {
  // 8 bits per channel, colour type 2 (RGB)
  return encode_rows(image.width_px, image.height_px, 8, 2, 3 * static_cast<size_t>(image.width_px),
                     image.rgb.data());
}

std::vector<uint8_t> encode_grey_png(int width_px, int height_px, int bit_depth,
                                     const std::vector<uint8_t>& pixels) {
  if ((bit_depth != 8 && bit_depth != 16) || width_px <= 0 || height_px <= 0) return {};
  const size_t row_bytes = static_cast<size_t>(width_px) * (bit_depth / 8);
  if (pixels.size() != row_bytes * height_px) return {};
  return encode_rows(width_px, height_px, static_cast<uint8_t>(bit_depth), 0, row_bytes,
                     pixels.data());
}

std::string write_file_bytes(const std::string& path, const std::vector<uint8_t>& bytes) {
  std::ofstream file(path, std::ios::binary);
  if (!file) return "cannot open " + path + " for writing";
  file.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  return file ? "" : "cannot write " + path;
}

std::string write_png(const std::string& path, const core::RgbImage& image) {
  if (image.rgb.size() != 3 * static_cast<size_t>(image.width_px) * image.height_px)
    return "image size does not match its pixel data";
  return write_file_bytes(path, encode_png(image));
}

core::RgbImage depth_to_image(const std::vector<float>& depth_m, int width_px, int height_px,
                              double max_depth_m) {
  core::RgbImage image{width_px, height_px, {}};
  image.rgb.reserve(3 * depth_m.size());
  for (const float d : depth_m) {
    const double level = std::isfinite(d) ? std::clamp(1.0 - d / max_depth_m, 0.0, 1.0) : 0.0;
    const auto grey = static_cast<uint8_t>(std::lround(255.0 * level));
    image.rgb.insert(image.rgb.end(), {grey, grey, grey});
  }
  return image;
}

}  // namespace conesim::sensors
