#include "render/image.hpp"

#include <png.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/memory_budget.hpp"
#include "render/transfer_function.hpp"

namespace linebake {
namespace {

bool ends_with(const std::string& s, const std::string& suffix) {
  if (s.size() < suffix.size()) return false;
  std::string tail = s.substr(s.size() - suffix.size());
  std::transform(tail.begin(), tail.end(), tail.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  return tail == suffix;
}

using FilePtr = std::unique_ptr<std::FILE, int (*)(std::FILE*)>;

FilePtr open_file(const std::string& path, const char* mode) {
  return FilePtr(std::fopen(path.c_str(), mode), &std::fclose);
}

// Bytes from the read position to the end of the file; the position is kept.
size_t bytes_left(std::FILE* f) {
  const long here = std::ftell(f);
  if (here < 0 || std::fseek(f, 0, SEEK_END) != 0) return 0;
  const long end = std::ftell(f);
  std::fseek(f, here, SEEK_SET);
  return end > here ? size_t(end - here) : 0;
}

// Deflate's largest expansion: a 258-byte match coded in about 2 bits (RFC 1951), so no zlib
// stream inflates more than 1032 times its size. A header asking for more than the file can hold
// is refused before anything is allocated.
constexpr size_t kDeflateMaxRatio = 1032;
constexpr int kMaxImageSide = 1 << 16;

[[noreturn]] void png_fail(png_structp png, png_const_charp message) {
  *static_cast<std::string*>(png_get_error_ptr(png)) = message;
  png_longjmp(png, 1);
}
void png_warn(png_structp, png_const_charp) {}

void append_bytes(png_structp png, png_bytep data, png_size_t length) {
  auto* out = static_cast<std::string*>(png_get_io_ptr(png));
  out->append(reinterpret_cast<const char*>(data), length);
}
void no_flush(png_structp) {}

// Rows of big-endian samples, the form libpng writes, encoded as a PNG file in memory.
// `what` names the output in errors.
std::string encode_png_rows(const std::string& what, int width, int height, int channels, int bits,
                            bool srgb, const std::vector<unsigned char>& data) {
  std::string error, bytes;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &error, png_fail, png_warn);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!png || !info) {
    png_destroy_write_struct(&png, &info);
    throw OutputError(what, "out of memory in libpng");
  }
  const size_t row_bytes = size_t(width) * channels * (bits / 8);
  std::vector<png_bytep> rows(height);
  for (int y = 0; y < height; ++y) rows[y] = const_cast<png_bytep>(data.data() + y * row_bytes);
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    throw OutputError(what, "PNG write failed: " + error);
  }
  png_set_write_fn(png, &bytes, append_bytes, no_flush);
  png_set_IHDR(png, info, png_uint_32(width), png_uint_32(height), bits,
               channels == 1 ? PNG_COLOR_TYPE_GRAY : PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  if (srgb) png_set_sRGB_gAMA_and_cHRM(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
  png_write_info(png, info);
  png_write_image(png, rows.data());
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return bytes;
}

std::vector<unsigned char> quantized_samples(const Image& image, int bits) {
  const double scale = bits == 8 ? 255.0 : 65535.0;
  std::vector<unsigned char> data(image.pixels.size() * size_t(bits / 8));
  for (size_t i = 0; i < image.pixels.size(); ++i) {
    // As display_encoded encodes it, without a copy of the image.
    const float encoded =
        image.srgb_encoded ? image.pixels[i] : float(linear_to_srgb(image.pixels[i]));
    const auto v = uint32_t(std::lround(std::clamp(double(encoded), 0.0, 1.0) * scale));
    if (bits == 8) {
      data[i] = uint8_t(v);
    } else {
      data[2 * i] = uint8_t(v >> 8);
      data[2 * i + 1] = uint8_t(v);
    }
  }
  return data;
}

}  // namespace

Image display_encoded(Image image) {
  if (!image.srgb_encoded)
    for (float& v : image.pixels) v = float(linear_to_srgb(v));
  image.srgb_encoded = true;
  return image;
}

uint64_t image_bytes(int width, int height, int channels) {
  return uint64_t(width) * uint64_t(height) * uint64_t(channels) * sizeof(float);
}

std::string encode_png(const Image& image, int bits) {
  if (bits != 8 && bits != 16) throw OutputError("PNG", "bit depth must be 8 or 16");
  return encode_png_rows("PNG", image.width, image.height, image.channels, bits, true,
                         quantized_samples(image, bits));
}

void write_png(const Image& image, const std::string& path, int bits) {
  if (bits != 8 && bits != 16) throw OutputError(path, "PNG bit depth must be 8 or 16");
  write_file_atomically(path, encode_png_rows(path, image.width, image.height, image.channels, bits,
                                              true, quantized_samples(image, bits)));
}

void write_png_counts(const std::vector<uint32_t>& counts, int width, int height,
                      const std::string& path) {
  std::vector<unsigned char> data(counts.size() * 2);
  for (size_t i = 0; i < counts.size(); ++i) {
    const uint32_t v = std::min<uint32_t>(counts[i], 65535);
    data[2 * i] = uint8_t(v >> 8);
    data[2 * i + 1] = uint8_t(v);
  }
  write_file_atomically(path, encode_png_rows(path, width, height, 1, 16, false, data));
}

namespace {

// Refuses a read that would hold more than `max_bytes` (the image as floats, and what decoding it
// holds beside them), before anything is allocated.
void check_read_bytes(const std::string& path, int width, int height, int channels,
                      uint64_t decoding, uint64_t max_bytes) {
  const uint64_t floats = image_bytes(width, height, channels);
  if (floats + decoding <= max_bytes) return;
  throw BudgetExceeded(path + ": " + std::to_string(width) + "x" + std::to_string(height) + ", " +
                       std::to_string(channels) + (channels == 1 ? " channel" : " channels") +
                       ", takes " + format_bytes(floats) + " as floats" +
                       (decoding > 0 ? " and " + format_bytes(decoding) + " to decode" : "") +
                       ", more than the " + format_bytes(max_bytes) +
                       " the memory budget leaves; raise --memory-budget");
}

}  // namespace

Image read_png(const std::string& path, uint64_t max_bytes) {
  FilePtr f = open_file(path, "rb");
  if (!f) throw InputError(path, "", std::string("cannot open: ") + std::strerror(errno));
  unsigned char signature[8] = {};
  if (std::fread(signature, 1, 8, f.get()) != 8 || png_sig_cmp(signature, 0, 8) != 0)
    throw InputError(path, "byte offset 0", "not a PNG file");
  std::string error;
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &error, png_fail, png_warn);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!png || !info) {
    png_destroy_read_struct(&png, &info, nullptr);
    throw InputError(path, "", "out of memory in libpng");
  }
  Image image;
  std::vector<unsigned char> data;
  std::vector<png_bytep> rows;
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_read_struct(&png, &info, nullptr);
    throw InputError(path, "byte offset " + std::to_string(std::ftell(f.get())),
                     "corrupt PNG: " + error);
  }
  png_init_io(png, f.get());
  png_set_sig_bytes(png, 8);
  png_set_user_limits(png, kMaxImageSide, kMaxImageSide);
  // An ancillary chunk (text, a suggested palette, ...) is read whole by libpng, at the length
  // the file declares: a 43-byte file declaring a tEXt chunk of 2 GiB had libpng allocate it
  // (its chunk_malloc_max did not stop that). None of them matters here (alpha is dropped, the
  // values are taken as stored), so every one is skipped unread, a piece at a time; libpng
  // still reads IHDR, PLTE, tRNS, IDAT and IEND, whose lengths it bounds.
  png_set_keep_unknown_chunks(png, PNG_HANDLE_CHUNK_NEVER, nullptr, -1);
  const size_t file_bytes = bytes_left(f.get()) + 8;
  png_read_info(png, info);
  // The rows as stored, before they are expanded: palette indices and grey of 1 to 4 bits are
  // what the file's deflate stream holds (a valid 1000x1000 palette image of 1.8 KB had been
  // refused against its expanded RGB rows).
  const size_t stored_row_bytes = png_get_rowbytes(png, info);
  const bool alpha = (png_get_color_type(png, info) & PNG_COLOR_MASK_ALPHA) != 0 ||
                     png_get_valid(png, info, PNG_INFO_tRNS) != 0;
  png_set_expand(png);  // palette -> RGB, low-bit grey -> 8 bits, tRNS -> alpha
  png_set_strip_alpha(png);
  png_read_update_info(png, info);
  const int width = int(png_get_image_width(png, info)),
            height = int(png_get_image_height(png, info));
  const int bits = png_get_bit_depth(png, info);
  const int channels = png_get_channels(png, info);
  const size_t row_bytes = png_get_rowbytes(png, info);
  if (stored_row_bytes * size_t(height) > kDeflateMaxRatio * file_bytes) {
    png_destroy_read_struct(&png, &info, nullptr);
    throw InputError(path, "IHDR",
                     std::to_string(width) + "x" + std::to_string(height) +
                         " pixels need more than the " + std::to_string(file_bytes) +
                         "-byte file can inflate to");
  }
  if (channels == 1 || channels == 3) {
    const uint64_t decoding = uint64_t(row_bytes) * uint64_t(height) + sizeof(png_bytep) * height;
    try {
      check_read_bytes(path, width, height, channels, decoding, max_bytes);
    } catch (...) {
      png_destroy_read_struct(&png, &info, nullptr);
      throw;
    }
  }
  data.resize(row_bytes * height);
  rows.resize(height);
  for (int y = 0; y < height; ++y) rows[y] = data.data() + y * row_bytes;
  png_read_image(png, rows.data());
  png_read_end(png, nullptr);
  png_destroy_read_struct(&png, &info, nullptr);
  if (channels != 1 && channels != 3) throw InputError(path, "", "unsupported PNG channel layout");
  image = Image(width, height, channels);
  image.srgb_encoded = true;
  image.alpha_dropped = alpha;
  const double scale = bits == 16 ? 65535.0 : 255.0;
  for (size_t i = 0; i < image.pixels.size(); ++i)
    image.pixels[i] = float((bits == 16 ? (data[2 * i] << 8 | data[2 * i + 1]) : data[i]) / scale);
  return image;
}

void write_pfm(const Image& image, const std::string& path) {
  std::string bytes = std::string(image.channels == 3 ? "PF" : "Pf") + "\n" +
                      std::to_string(image.width) + " " + std::to_string(image.height) + "\n-1.0\n";
  const size_t header = bytes.size();
  bytes.resize(header + image.pixels.size() * 4);
  const size_t row = size_t(image.width) * image.channels;
  for (int y = 0; y < image.height; ++y)  // bottom row first
    std::memcpy(bytes.data() + header + size_t(image.height - 1 - y) * row * 4,
                image.pixels.data() + size_t(y) * row, row * 4);
  write_file_atomically(path, bytes);
}

Image read_pfm(const std::string& path, uint64_t max_bytes) {
  FilePtr f = open_file(path, "rb");
  if (!f) throw InputError(path, "", std::string("cannot open: ") + std::strerror(errno));
  // "PF" or "Pf" and a whitespace ("PF4" is not a PFM header), then width, height and scale.
  char kind[3] = {};
  int width = 0, height = 0;
  double scale = 0;
  const bool magic = std::fread(kind, 1, 2, f.get()) == 2 &&
                     (std::strcmp(kind, "PF") == 0 || std::strcmp(kind, "Pf") == 0) &&
                     std::isspace(std::fgetc(f.get()));
  if (!magic || std::fscanf(f.get(), "%d %d %lf", &width, &height, &scale) != 3)
    throw InputError(path, "byte offset 0", "not a PFM file (expected PF or Pf header)");
  // The scale's sign is the byte order and its size a unit: NaN, infinity and 0 are neither.
  if (width <= 0 || height <= 0 || width > kMaxImageSide || height > kMaxImageSide || scale == 0 ||
      !std::isfinite(scale))
    throw InputError(path, "header", "implausible size or scale");
  if (scale > 0) throw InputError(path, "header", "big-endian PFM is not supported");
  // The single whitespace after the scale; a CRLF header's "\r\n" is one too (read as the
  // "\r" alone, the pixels had been read a byte off and the image compared at 2.7 dB).
  if (std::fgetc(f.get()) == '\r') {
    const int next = std::fgetc(f.get());
    if (next != '\n' && next != EOF) std::ungetc(next, f.get());
  }
  const int channels = kind[1] == 'F' ? 3 : 1;
  const size_t pixel_bytes = size_t(width) * height * channels * 4, left = bytes_left(f.get());
  // Bytes past the pixels mean the header was read otherwise than it was written (a .binlines
  // refuses them too).
  if (pixel_bytes < left)
    throw InputError(path, "byte offset " + std::to_string(std::ftell(f.get()) + long(pixel_bytes)),
                     std::to_string(left - pixel_bytes) +
                         " bytes after the pixel data: the header's " + std::to_string(width) +
                         "x" + std::to_string(height) + " pixels take " +
                         std::to_string(pixel_bytes) + " bytes");
  if (pixel_bytes > left)
    throw InputError(path, "byte offset " + std::to_string(std::ftell(f.get())),
                     "truncated pixel data: the header's " + std::to_string(width) + "x" +
                         std::to_string(height) + " pixels need " + std::to_string(pixel_bytes) +
                         " bytes, the file has " + std::to_string(left) + " left");
  check_read_bytes(path, width, height, channels, 0, max_bytes);
  Image image(width, height, channels);
  const size_t row = size_t(width) * image.channels;
  for (int y = height - 1; y >= 0; --y)
    if (std::fread(image.pixels.data() + size_t(y) * row, 4, row, f.get()) != row)
      throw InputError(path, "byte offset " + std::to_string(std::ftell(f.get())),
                       "truncated pixel data");
  return image;
}

void check_image_output(const std::string& path) {
  if (!ends_with(path, ".pfm") && !ends_with(path, ".png"))
    throw OutputError(path, "unknown image format (use .png or .pfm)");
  check_output_location(path);
}

bool is_png_path(const std::string& path) {
  return ends_with(path, ".png");
}

void write_image(const Image& image, const std::string& path, int png_bits) {
  if (ends_with(path, ".pfm")) return write_pfm(image, path);
  if (ends_with(path, ".png")) return write_png(image, path, png_bits);
  throw OutputError(path, "unknown image format (use .png or .pfm)");
}

Image read_image(const std::string& path, uint64_t max_bytes) {
  if (ends_with(path, ".pfm")) return read_pfm(path, max_bytes);
  return read_png(path, max_bytes);
}

Image read_image(const std::string& path, MemoryBudget& budget) {
  Image image = read_image(path, budget.available());
  budget.reserve(image_bytes(image.width, image.height, image.channels), path);
  return image;
}

}  // namespace linebake
