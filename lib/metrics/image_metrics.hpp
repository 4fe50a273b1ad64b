#pragma once
// Image-quality metrics as the paper reports them (techniques.md section 11). Both run on the
// values as given in [0, 1]: compare display-encoded images with display-encoded ones.

#include <cstdint>
#include <string>

#include "render/image.hpp"

namespace linebake {

constexpr double kPsnrCap = 60.0;  // dB; the paper's value for identical images

// The first pixel, as "pixel (x, y)", with a channel that is not finite (NaN or infinity), or ""
// when there is none: PSNR and SSIM have no meaning there (a NaN made any image "identical",
// 60 dB), so callers refuse such an image naming the place.
std::string first_nonfinite_pixel(const Image& image);

// Why `image` and `reference` cannot be compared, or "" when they can: another size, another
// kind (grey against colour), or under SSIM's 11x11 window. `reference_name` (a file; "" for an
// array) is named in the message, as `linebake compare` and Python's compare() both say it.
std::string comparison_problem(const Image& image, const Image& reference,
                               const std::string& reference_name);

// -10 log10(MSE) over all pixels and channels, capped at 60 dB.
double psnr(const Image& a, const Image& b);

// SSIM (Wang et al. 2004): 11x11 Gaussian window (sigma 1.5), K1 = 0.01, K2 = 0.03, data range
// 1, population (co)variances, averaged over the windows that lie fully inside the image and then
// over the channels (per-channel SSIM, not luminance). Matches scikit-image's
// structural_similarity(gaussian_weights=True, sigma=1.5, use_sample_covariance=False,
// data_range=1, channel_axis=-1). Images must be at least 11x11.
// Runs in bands of rows on TBB's threads, holding per thread a few rows of the width (below), not
// planes of the image; the same value for any thread count.
double ssim(const Image& a, const Image& b);
// The memory ssim() holds beside the two images, at most, for images of width x height run on
// `threads` threads: about 480 bytes a column a thread.
uint64_t ssim_scratch_bytes(int width, int height, int threads);

// 1 - |a - b| (mean over channels) x scale, clamped: white where equal, as in the paper's
// figures.
Image error_image(const Image& a, const Image& b, double scale = 1.0);

}  // namespace linebake
