#pragma once
/// PNG encoding/decoding through libpng, in memory.
#include <cstdint>
#include <string>
#include <vector>

namespace handskin {

struct Gray16Image {
  int width = 0;
  int height = 0;
  std::vector<std::uint16_t> pixels;  ///< row-major, height rows of width values
};

/// Decode a PNG that must be 16-bit, single-channel grayscale without alpha or transparency.
/// Throws InputError(name, ...) for anything else (not a PNG, truncated, 8-bit, RGB, alpha, ...).
/// Images over `max_side` pixels on a side are refused before any allocation.
Gray16Image decode_gray16_png(const std::string& bytes, const std::string& name, int max_side = 16384);

struct Rgb8Image {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgb;  ///< row-major, 3 bytes a pixel
};

/// Decode an 8-bit RGB PNG (an RGBA one loses its alpha), e.g. a scan's photo. Throws
/// InputError(name, ...) for anything else, as decode_gray16_png.
Rgb8Image decode_rgb8_png(const std::string& bytes, const std::string& name, int max_side = 16384);

/// Encode a 16-bit single-channel PNG. `level` is the zlib compression level (0..9).
std::string encode_gray16_png(const Gray16Image& img, int level = 6);

/// Encode an 8-bit RGB PNG (row-major, 3 bytes a pixel), for preview pictures.
std::string encode_rgb8_png(int width, int height, const std::vector<std::uint8_t>& rgb);

}  // namespace handskin
