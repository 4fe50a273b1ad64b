#include "metrics/image_metrics.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "core/interrupt.hpp"

namespace linebake {
namespace {

void require_same_shape(const Image& a, const Image& b) {
  if (a.width != b.width || a.height != b.height || a.channels != b.channels)
    throw Error("images differ in size or channels: " + std::to_string(a.width) + "x" +
                std::to_string(a.height) + "x" + std::to_string(a.channels) + " against " +
                std::to_string(b.width) + "x" + std::to_string(b.height) + "x" +
                std::to_string(b.channels));
}

constexpr int kRadius = 5;  // 11x11 window: scipy's truncate 3.5 x sigma 1.5, rounded
constexpr double kSigma = 1.5;

// The Gaussian window, normalised to sum 1.
std::array<double, 2 * kRadius + 1> gaussian_weights() {
  std::array<double, 2 * kRadius + 1> w{};
  double sum = 0;
  for (int i = -kRadius; i <= kRadius; ++i)
    sum += w[i + kRadius] = std::exp(-0.5 * i * i / (kSigma * kSigma));
  for (double& v : w) v /= sum;
  return w;
}

// SSIM's window means, computed a band of output rows at a time: each band keeps the Gaussian
// row sums of the last 11 image rows (a ring) for the five quantities SSIM averages (x, y, x^2,
// y^2, xy), so memory grows with the width, not the image (a whole plane of each quantity, as
// before 2026-11-30, took about 88 bytes a pixel: two 20000x20000 images drove the process to the
// kernel's OOM killer). The sums run in the same order as a pass over whole planes, so the
// values are those of that pass; each output row's sum is kept and the rows added in order, so
// the result does not depend on the bands or the threads.
constexpr int kWindow = 2 * kRadius + 1;
constexpr int kQuantities = 5;  // x, y, x^2, y^2, xy
constexpr int kBandRows = 128;  // output rows a band computes

// The scratch one band holds, for an image `width` pixels wide.
uint64_t band_scratch_bytes(int width) {
  const uint64_t ow = uint64_t(std::max(width - 2 * kRadius, 0));
  return uint64_t(kQuantities) * (uint64_t(kWindow) * ow + uint64_t(width)) * sizeof(double);
}

// Adds to row_sums[oy] the SSIM of every window of channel c whose top row is oy, for output
// rows [first, last).
void ssim_band(const Image& a, const Image& b, int c, int first, int last,
               std::vector<double>& row_sums) {
  static const auto w = gaussian_weights();
  constexpr double c1 = 0.01 * 0.01, c2 = 0.03 * 0.03;  // (K L)^2 with data range L = 1
  const int width = a.width, ow = width - 2 * kRadius;
  const size_t channels = size_t(a.channels);
  std::vector<double> row(size_t(kQuantities) * width);          // one image row's quantities
  std::vector<double> ring(size_t(kQuantities) * kWindow * ow);  // their row sums, by row % 11
  const auto ring_row = [&](int q, int y) {
    return ring.data() + (size_t(q) * kWindow + y % kWindow) * ow;
  };
  for (int y = first; y < last + 2 * kRadius; ++y) {
    for (int x = 0; x < width; ++x) {
      const size_t i = (size_t(y) * width + x) * channels + c;
      const double vx = a.pixels[i], vy = b.pixels[i];
      row[x] = vx;
      row[size_t(width) + x] = vy;
      row[2 * size_t(width) + x] = vx * vx;
      row[3 * size_t(width) + x] = vy * vy;
      row[4 * size_t(width) + x] = vx * vy;
    }
    for (int q = 0; q < kQuantities; ++q) {
      const double* plane = row.data() + size_t(q) * width;
      double* sums = ring_row(q, y);
      for (int x = 0; x < ow; ++x) {
        double s = 0;
        for (int k = 0; k < kWindow; ++k) s += w[k] * plane[x + k];
        sums[x] = s;
      }
    }
    const int oy = y - 2 * kRadius;  // the output row whose window's last row this is
    if (oy < first) continue;
    double sum = 0;
    for (int x = 0; x < ow; ++x) {
      double m[kQuantities];
      for (int q = 0; q < kQuantities; ++q) {
        double s = 0;
        for (int k = 0; k < kWindow; ++k) s += w[k] * ring_row(q, oy + k)[x];
        m[q] = s;
      }
      const double mx = m[0], my = m[1];
      const double vx = m[2] - mx * mx, vy = m[3] - my * my, cov = m[4] - mx * my;
      sum += (2 * mx * my + c1) * (2 * cov + c2) / ((mx * mx + my * my + c1) * (vx + vy + c2));
    }
    row_sums[size_t(oy)] += sum;
  }
}

}  // namespace

std::string first_nonfinite_pixel(const Image& image) {
  const size_t channels = size_t(std::max(image.channels, 1));
  for (size_t i = 0; i < image.pixels.size(); ++i)
    if (!std::isfinite(image.pixels[i])) {
      const size_t pixel = i / channels, width = size_t(std::max(image.width, 1));
      return "pixel (" + std::to_string(pixel % width) + ", " + std::to_string(pixel / width) + ")";
    }
  return "";
}

std::string comparison_problem(const Image& image, const Image& reference,
                               const std::string& reference_name) {
  const std::string the_reference =
      "the reference " + (reference_name.empty() ? "" : reference_name + " ");
  const auto size = [](const Image& i) {
    return std::to_string(i.width) + "x" + std::to_string(i.height);
  };
  const auto kind = [](const Image& i) {
    return std::to_string(i.channels) + (i.channels == 1 ? " channel (grey)" : " channels");
  };
  if (image.width != reference.width || image.height != reference.height)
    return size(image) + ", but " + the_reference + "is " + size(reference) +
           ": images of one size compare";
  if (image.channels != reference.channels)
    return kind(image) + ", but " + the_reference + "has " + kind(reference) +
           ": images of one kind compare (convert the grey one to RGB first)";
  if (image.width < 2 * kRadius + 1 || image.height < 2 * kRadius + 1)
    return size(image) + ": SSIM needs images of at least 11x11 pixels";
  return "";
}

double psnr(const Image& a, const Image& b) {
  require_same_shape(a, b);
  double sum = 0;
  for (size_t i = 0; i < a.pixels.size(); ++i) {
    const double d = double(a.pixels[i]) - double(b.pixels[i]);
    sum += d * d;
  }
  const double mse = a.pixels.empty() ? 0.0 : sum / double(a.pixels.size());
  // + 0.0: an error of 1 everywhere gives -0.0, which JSON would print as such.
  return mse > 0 ? std::min(kPsnrCap, -10.0 * std::log10(mse)) + 0.0 : kPsnrCap;
}

uint64_t ssim_scratch_bytes(int width, int height, int threads) {
  const uint64_t oh = uint64_t(std::max(height - 2 * kRadius, 0));
  const uint64_t bands = (oh + kBandRows - 1) / kBandRows;
  return uint64_t(std::min<uint64_t>(bands, uint64_t(std::max(threads, 1)))) *
             band_scratch_bytes(width) +
         oh * sizeof(double);
}

double ssim(const Image& a, const Image& b) {
  require_same_shape(a, b);
  if (a.width < kWindow || a.height < kWindow)
    throw Error("SSIM needs images of at least 11x11 pixels");
  const int oh = a.height - 2 * kRadius;
  const size_t windows = size_t(a.width - 2 * kRadius) * size_t(oh);
  const int bands = (oh + kBandRows - 1) / kBandRows;
  double total = 0;
  for (int c = 0; c < a.channels; ++c) {
    std::vector<double> row_sums(size_t(oh), 0.0);
    tbb::parallel_for(0, bands, [&](int band) {
      throw_if_interrupted();  // a large image's SSIM takes seconds to minutes
      ssim_band(a, b, c, band * kBandRows, std::min(oh, (band + 1) * kBandRows), row_sums);
    });
    double sum = 0;
    for (const double s : row_sums) sum += s;
    total += sum / double(windows);
  }
  return total / a.channels;
}

Image error_image(const Image& a, const Image& b, double scale) {
  require_same_shape(a, b);
  Image e(a.width, a.height, 1);
  e.srgb_encoded = true;  // written as is
  for (size_t p = 0; p < size_t(a.width) * a.height; ++p) {
    double d = 0;
    for (int c = 0; c < a.channels; ++c)
      d += std::abs(double(a.pixels[p * a.channels + c]) - double(b.pixels[p * b.channels + c]));
    e.pixels[p] = float(std::clamp(1.0 - scale * d / a.channels, 0.0, 1.0));
  }
  return e;
}

}  // namespace linebake
