#pragma once
// Images as the renderers produce and the metrics read them: float pixels, row-major, top row
// first. PNG output is sRGB-encoded (8 or 16 bits); PFM keeps the float values exactly.

#include <cstdint>
#include <string>
#include <vector>

namespace linebake {

class MemoryBudget;

struct Image {
  int width = 0, height = 0, channels = 3;  // 1 (grey) or 3 (RGB)
  // What the values mean: linear light (renderers) or already sRGB-encoded (a PNG read back).
  bool srgb_encoded = false;
  // Read from a PNG with an alpha channel or tRNS transparency, which read_png drops.
  bool alpha_dropped = false;
  std::vector<float> pixels;  // width * height * channels

  Image() = default;
  Image(int w, int h, int c = 3) : width(w), height(h), channels(c), pixels(size_t(w) * h * c) {}
  float& at(int x, int y, int c) { return pixels[(size_t(y) * width + x) * channels + c]; }
  float at(int x, int y, int c) const { return pixels[(size_t(y) * width + x) * channels + c]; }
};

// The values a display shows, in [0, 1]: linear images are sRGB-encoded, encoded ones kept (in
// place when given an rvalue).
Image display_encoded(Image image);
// The bytes of an image's float pixels.
uint64_t image_bytes(int width, int height, int channels);

// PNG with 8 or 16 bits per channel, sRGB chunk set. Linear images are encoded on the way out.
void write_png(const Image& image, const std::string& path, int bits = 8);
// The same PNG file's bytes, in memory (e.g. for a data: URI).
std::string encode_png(const Image& image, int bits = 8);
// 16-bit grey PNG of raw counts (saturating at 65535), e.g. a depth-complexity image.
void write_png_counts(const std::vector<uint32_t>& counts, int width, int height,
                      const std::string& path);
// 8/16-bit grey, grey+alpha, RGB or RGBA; alpha dropped (alpha_dropped says so), grey kept as
// one channel. Values are the stored ones in [0, 1] (srgb_encoded = true).
// `max_bytes`: refuse (BudgetExceeded naming the file, its size and the bytes) an image whose
// floats and decoding buffers would take more, before allocating them (read_image too).
Image read_png(const std::string& path, uint64_t max_bytes = UINT64_MAX);

// Portable float map (little-endian "PF"/"Pf"): the exact float values, bottom row first on disk.
void write_pfm(const Image& image, const std::string& path);
Image read_pfm(const std::string& path, uint64_t max_bytes = UINT64_MAX);  // not srgb_encoded

// By extension: .png or .pfm.
void write_image(const Image& image, const std::string& path, int png_bits = 8);
// Before any work: what write_image would refuse (an extension other than .png or .pfm, a missing
// or read-only directory), as OutputError naming the path.
void check_image_output(const std::string& path);
// Whether write_image writes `path` as a PNG (its extension, in any case).
bool is_png_path(const std::string& path);
Image read_image(const std::string& path, uint64_t max_bytes = UINT64_MAX);
// read_image within what `budget` leaves, its floats then reserved from it (named by the path).
Image read_image(const std::string& path, MemoryBudget& budget);

}  // namespace linebake
