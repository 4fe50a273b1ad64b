// PSNR and SSIM against hand-computed values and scikit-image's; image files round trip.

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <fstream>
#include <limits>

#include "core/error.hpp"
#include "metrics/image_metrics.hpp"
#include "render/transfer_function.hpp"
#include "test_util.hpp"

namespace linebake {
namespace {

Image constant(float v, int w = 16, int h = 16) {
  Image img(w, h, 3);
  std::fill(img.pixels.begin(), img.pixels.end(), v);
  return img;
}

// The pairs of tests/reference/metrics_reference.py.
Image pattern(int which) {
  Image img(32, 24, 3);
  for (int y = 0; y < 24; ++y)
    for (int x = 0; x < 32; ++x)
      for (int c = 0; c < 3; ++c) {
        const double a = double(
            float(0.5 + 0.4 * std::sin(0.37 * x + 0.11 * c) * std::cos(0.23 * y - 0.05 * c)));
        double v = a;
        if (which == 1)
          v = std::clamp(a + 0.08 * std::sin(1.3 * x + 2.1 * y + c) * std::cos(0.7 * x * y), 0.0,
                         1.0);
        if (which == 2) v = 0.8 * a + 0.1;
        img.at(x, y, c) = float(v);
      }
  return img;
}

TEST(Metrics, IdenticalImagesGiveTheCaps) {
  const Image a = pattern(0);
  EXPECT_EQ(psnr(a, a), 60.0);
  EXPECT_NEAR(ssim(a, a), 1.0, 1e-12);
}

TEST(Metrics, ConstantImagesByHand) {
  // MSE = 0.1^2 -> PSNR = 20 dB. Constant images have zero variance, so SSIM is the luminance
  // term alone: (2ab + C1) / (a^2 + b^2 + C1), C1 = 1e-4.
  const Image a = constant(0.5f), b = constant(0.6f);
  const double ma = double(0.5f), mb = double(0.6f);
  EXPECT_NEAR(psnr(a, b), -10 * std::log10((mb - ma) * (mb - ma)), 1e-9);
  EXPECT_NEAR(psnr(a, b), 20.0, 1e-5);
  EXPECT_NEAR(ssim(a, b), (2 * ma * mb + 1e-4) / (ma * ma + mb * mb + 1e-4), 1e-12);
  // A tiny difference stays capped at 60 dB (MSE 1e-8 would be 80 dB).
  EXPECT_EQ(psnr(constant(0.5f), constant(0.5001f)), 60.0);
}

TEST(Metrics, MatchScikitImage) {
  // Values printed by tests/reference/metrics_reference.py (scikit-image 0.19.3).
  const Image a = pattern(0), noise = pattern(1), contrast = pattern(2);
  EXPECT_NEAR(ssim(a, noise), 0.934840137868, 1e-6);
  EXPECT_NEAR(psnr(a, noise), 27.508969989057, 1e-5);
  EXPECT_NEAR(ssim(a, contrast), 0.972911435396, 1e-6);
  EXPECT_NEAR(psnr(a, contrast), 28.063220737005, 1e-5);
}

// SSIM by its definition, a second method: each window's weighted means computed directly over
// its 11x11 pixels (weights w_i w_j), not by separable passes in bands of rows.
double ssim_by_windows(const Image& a, const Image& b) {
  double w[11], sum = 0;
  for (int i = -5; i <= 5; ++i) sum += w[i + 5] = std::exp(-0.5 * i * i / (1.5 * 1.5));
  for (double& v : w) v /= sum;
  double total = 0;
  for (int c = 0; c < a.channels; ++c) {
    double channel = 0;
    for (int y = 0; y + 11 <= a.height; ++y)
      for (int x = 0; x + 11 <= a.width; ++x) {
        double mx = 0, my = 0, mxx = 0, myy = 0, mxy = 0;
        for (int j = 0; j < 11; ++j)
          for (int i = 0; i < 11; ++i) {
            const double k = w[i] * w[j], u = a.at(x + i, y + j, c), v = b.at(x + i, y + j, c);
            mx += k * u, my += k * v, mxx += k * u * u, myy += k * v * v, mxy += k * u * v;
          }
        const double vx = mxx - mx * mx, vy = myy - my * my, cov = mxy - mx * my;
        channel += (2 * mx * my + 1e-4) * (2 * cov + 9e-4) /
                   ((mx * mx + my * my + 1e-4) * (vx + vy + 9e-4));
      }
    total += channel / double((a.width - 10) * (a.height - 10));
  }
  return total / a.channels;
}

// Noise-like images whose output rows span three bands of rows (128 each) and a part.
Image speckled(int w, int h, int channels, unsigned seed) {
  Image img(w, h, channels);
  for (size_t i = 0; i < img.pixels.size(); ++i) {
    seed = seed * 1664525u + 1013904223u;
    img.pixels[i] = float(seed >> 8) / float(1u << 24);
  }
  return img;
}

TEST(Metrics, SsimInBandsEqualsTheWindowsDefinitionForAnyThreadCount) {
  const Image a = speckled(97, 421, 3, 1), b = speckled(97, 421, 3, 2);
  Image c = a;
  for (size_t i = 0; i < c.pixels.size(); i += 7) c.pixels[i] = 1.0f - c.pixels[i];
  for (const Image* other : {&b, static_cast<const Image*>(&c)}) {
    const double expected = ssim_by_windows(a, *other);
    double one = 0, four = 0;
    tbb::task_arena(1).execute([&] { one = ssim(a, *other); });
    tbb::task_arena(4).execute([&] { four = ssim(a, *other); });
    EXPECT_NEAR(one, expected, 1e-12);
    EXPECT_EQ(one, four);  // the same value, whatever the bands' threads
  }
  // Grey too, and a height of exactly one band.
  const Image g = speckled(40, 138, 1, 3), h = speckled(40, 138, 1, 4);
  EXPECT_NEAR(ssim(g, h), ssim_by_windows(g, h), 1e-12);
  // About 480 bytes a column a thread and a double an output row: a 20000x20000 image's SSIM
  // holds about 9 MiB a thread, not the 88 bytes a pixel (33 GiB) of whole planes.
  EXPECT_EQ(ssim_scratch_bytes(20000, 20000, 1), 5u * (11u * 19990u + 20000u) * 8u + 19990u * 8u);
  EXPECT_EQ(ssim_scratch_bytes(20000, 20000, 2),
            2 * ssim_scratch_bytes(20000, 20000, 1) - 19990u * 8u);
  // Scratch for as many bands as there are: 138 rows have 128 windows' rows, one band.
  EXPECT_EQ(ssim_scratch_bytes(40, 138, 8), ssim_scratch_bytes(40, 138, 1));
}

TEST(Metrics, RejectMismatchedOrTinyImages) {
  EXPECT_THROW(psnr(constant(0, 16, 16), constant(0, 16, 17)), Error);
  EXPECT_THROW(ssim(constant(0, 10, 10), constant(0, 10, 10)), Error);
}

// The first non-finite channel is named by its pixel, row by row; a finite image has none.
TEST(Metrics, NonFinitePixelsAreNamed) {
  Image image(4, 3, 3);
  EXPECT_EQ(first_nonfinite_pixel(image), "");
  image.pixels[3 * (2 * 4 + 1) + 2] = std::numeric_limits<float>::infinity();  // (1, 2), blue
  EXPECT_EQ(first_nonfinite_pixel(image), "pixel (1, 2)");
  image.pixels[3 * (0 * 4 + 3) + 0] = std::nanf("");  // (3, 0), red: comes first
  EXPECT_EQ(first_nonfinite_pixel(image), "pixel (3, 0)");
}

TEST(Metrics, ErrorImageIsWhiteWhereEqual) {
  Image a = constant(0.5f), b = constant(0.5f);
  b.at(3, 4, 0) = 0.8f;  // mean abs difference over 3 channels: 0.1
  const Image e = error_image(a, b);
  EXPECT_EQ(e.at(0, 0, 0), 1.0f);
  EXPECT_NEAR(e.at(3, 4, 0), 0.9, 1e-6);
}

TEST(ImageFiles, PfmIsExactAndPngIsSrgbEncoded) {
  test::TempDir dir;
  Image img(7, 5, 3);
  for (size_t i = 0; i < img.pixels.size(); ++i)
    img.pixels[i] = float(i) / float(img.pixels.size());
  write_pfm(img, dir.file("a.pfm"));
  const Image back = read_pfm(dir.file("a.pfm"));
  EXPECT_EQ(back.pixels, img.pixels);
  for (const int bits : {8, 16}) {
    write_png(img, dir.file("a.png"), bits);
    const Image png = read_png(dir.file("a.png"));
    ASSERT_EQ(png.width, 7);
    ASSERT_EQ(png.channels, 3);
    EXPECT_TRUE(png.srgb_encoded);
    const double step = bits == 8 ? 1 / 255.0 : 1 / 65535.0;
    for (size_t i = 0; i < img.pixels.size(); ++i)
      EXPECT_NEAR(png.pixels[i], linear_to_srgb(img.pixels[i]), 0.5 * step + 1e-7);
  }
  std::ofstream(dir.file("bad.png")) << "not a png";
  EXPECT_THROW(read_png(dir.file("bad.png")), InputError);
  std::ofstream(dir.file("short.pfm")) << "PF\n4 4\n-1.0\n0123";
  try {
    read_pfm(dir.file("short.pfm"));
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("truncated"), std::string::npos);
  }
  EXPECT_THROW(write_image(img, dir.file("a.tiff")), OutputError);
  EXPECT_EQ(dir.entries().size(), 4u);  // a.pfm a.png bad.png short.pfm: nothing half-written
}

// CRC-32 of PNG chunks (ISO 3309, the PNG specification's Annex D), bit by bit.
uint32_t png_crc(const std::string& bytes) {
  uint32_t c = 0xffffffffu;
  for (unsigned char b : bytes) {
    c ^= b;
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xedb88320u & (0u - (c & 1u)));
  }
  return c ^ 0xffffffffu;
}

std::string big_endian(uint32_t v) {
  return {char(v >> 24), char(v >> 16), char(v >> 8), char(v)};
}

// The fuzzer's finding (CI, 2026-11-23): a PFM header asking for gigabytes in a small file was
// allocated before the pixels were read. Both image readers now refuse such a header first.
// A read within a budget: the image's floats (64 x 64 x 3 x 4 = 49,152 bytes), and for a PNG
// its decoded rows (64 x 192 bytes) and their pointers (64 x 8) as well, refused before they
// are allocated, naming the file; exactly enough reads it.
TEST(ImageFiles, AReadPastItsBytesIsRefusedNamingTheFile) {
  test::TempDir dir;
  const Image image = constant(0.25f, 64, 64);
  write_pfm(image, dir.file("a.pfm"));
  write_png(image, dir.file("a.png"), 8);
  EXPECT_EQ(read_pfm(dir.file("a.pfm"), 49152).pixels, image.pixels);
  EXPECT_EQ(read_png(dir.file("a.png"), 49152 + 12288 + 512).width, 64);
  try {
    read_image(dir.file("a.pfm"), 40000);
    FAIL();
  } catch (const BudgetExceeded& e) {
    EXPECT_NE(std::string(e.what()).find("a.pfm: 64x64, 3 channels, takes 48.00 KiB as floats, "
                                         "more than the 39.06 KiB the memory budget leaves"),
              std::string::npos)
        << e.what();
  }
  try {
    read_image(dir.file("a.png"), 49152 + 12288 + 511);
    FAIL();
  } catch (const BudgetExceeded& e) {
    EXPECT_NE(std::string(e.what()).find("a.png: 64x64, 3 channels, takes 48.00 KiB as floats "
                                         "and 12.50 KiB to decode"),
              std::string::npos)
        << e.what();
  }
}

TEST(ImageFiles, AHeaderAskingForMoreThanTheFileHoldsIsRefusedBeforeAllocating) {
  test::TempDir dir;
  std::ofstream(dir.file("huge.pfm"), std::ios::binary) << "PF\n65536 65536\n-1.0\n0123";
  try {
    read_pfm(dir.file("huge.pfm"));
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("51539607552 bytes, the file has 4 left"),
              std::string::npos)
        << e.what();
  }
  // A valid 1x1 PNG whose IHDR, with a correct CRC, then claims 65536x65536 RGB pixels: about
  // 12.9 GB, where deflate can inflate the file's few dozen bytes to at most 1032 times as many.
  write_png(constant(0.5f, 1, 1), dir.file("one.png"), 8);
  std::ifstream in(dir.file("one.png"), std::ios::binary);
  std::string png((std::istreambuf_iterator<char>(in)), {});
  ASSERT_EQ(png.substr(12, 4), "IHDR");
  const std::string ihdr = "IHDR" + big_endian(65536) + big_endian(65536) + png.substr(24, 5);
  png.replace(12, 17, ihdr);
  png.replace(29, 4, big_endian(png_crc(ihdr)));
  std::ofstream(dir.file("huge.png"), std::ios::binary) << png;
  try {
    read_png(dir.file("huge.png"));
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("65536x65536 pixels need more than"), std::string::npos)
        << e.what();
  }
  // One pixel wider than the limit is libpng's own refusal, still an InputError.
  png.replace(16, 4, big_endian(65537));
  png.replace(29, 4, big_endian(png_crc(png.substr(12, 17))));
  std::ofstream(dir.file("wide.png"), std::ios::binary) << png;
  EXPECT_THROW(read_png(dir.file("wide.png")), InputError);
}

}  // namespace
}  // namespace linebake
