#include "metrics/image_metrics.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include "core/error.hpp"

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

// Separable Gaussian mean of `plane` at every pixel whose window lies inside the image; the
// result is (width - 2r) x (height - 2r).
std::vector<double> window_means(const std::vector<double>& plane, int width, int height) {
  static const auto w = gaussian_weights();
  const int ow = width - 2 * kRadius, oh = height - 2 * kRadius;
  std::vector<double> rows(size_t(ow) * height), out(size_t(ow) * oh);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < ow; ++x) {
      double s = 0;
      for (int k = 0; k <= 2 * kRadius; ++k) s += w[k] * plane[size_t(y) * width + x + k];
      rows[size_t(y) * ow + x] = s;
    }
  for (int y = 0; y < oh; ++y)
    for (int x = 0; x < ow; ++x) {
      double s = 0;
      for (int k = 0; k <= 2 * kRadius; ++k) s += w[k] * rows[size_t(y + k) * ow + x];
      out[size_t(y) * ow + x] = s;
    }
  return out;
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

double ssim(const Image& a, const Image& b) {
  require_same_shape(a, b);
  if (a.width < 2 * kRadius + 1 || a.height < 2 * kRadius + 1)
    throw Error("SSIM needs images of at least 11x11 pixels");
  constexpr double c1 = 0.01 * 0.01, c2 = 0.03 * 0.03;  // (K L)^2 with data range L = 1
  const size_t n = size_t(a.width) * a.height;
  double total = 0;
  for (int c = 0; c < a.channels; ++c) {
    std::vector<double> x(n), y(n), xx(n), yy(n), xy(n);
    for (size_t i = 0; i < n; ++i) {
      x[i] = a.pixels[i * a.channels + c];
      y[i] = b.pixels[i * b.channels + c];
      xx[i] = x[i] * x[i];
      yy[i] = y[i] * y[i];
      xy[i] = x[i] * y[i];
    }
    const auto mx = window_means(x, a.width, a.height), my = window_means(y, a.width, a.height);
    const auto mxx = window_means(xx, a.width, a.height), myy = window_means(yy, a.width, a.height);
    const auto mxy = window_means(xy, a.width, a.height);
    double sum = 0;
    for (size_t i = 0; i < mx.size(); ++i) {
      const double vx = mxx[i] - mx[i] * mx[i], vy = myy[i] - my[i] * my[i];
      const double cov = mxy[i] - mx[i] * my[i];
      sum += (2 * mx[i] * my[i] + c1) * (2 * cov + c2) /
             ((mx[i] * mx[i] + my[i] * my[i] + c1) * (vx + vy + c2));
    }
    total += sum / double(mx.size());
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
