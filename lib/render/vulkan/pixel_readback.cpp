#include "render/vulkan/pixel_readback.hpp"

#include <algorithm>

namespace linebake::vk {

PixelReadback read_pixels(const float* rgba, const uint32_t* counts, int width, int height) {
  const uint64_t pixels = uint64_t(width) * uint64_t(height);
  PixelReadback out;
  out.image = Image(width, height, 3);
  out.alpha.resize(pixels);
  out.counts.resize(pixels);
  for (uint64_t p = 0; p < pixels; ++p) {
    for (uint64_t k = 0; k < 3; ++k) out.image.pixels[3 * p + k] = rgba[4 * p + k];
    out.alpha[p] = rgba[4 * p + 3];
    out.counts[p] = counts[p];
    out.total += counts[p];
    out.maximum = std::max(out.maximum, counts[p]);
  }
  return out;
}

bool PixelTargets::resize(Context& context, int w, int h) {
  if (w == width && h == height) return false;
  vkDeviceWaitIdle(context.device());
  release(context);
  const uint64_t pixels = uint64_t(w) * uint64_t(h);
  rgba = context.create_result(pixels * 16, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  counts = context.create_result(pixels * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  width = w, height = h;
  return true;
}

PixelReadback PixelTargets::read(Context& context) const {
  return read_pixels(static_cast<const float*>(context.read_back(rgba)),
                     static_cast<const uint32_t*>(context.read_back(counts)), width, height);
}

void PixelTargets::release(Context& context) {
  context.destroy(rgba);
  context.destroy(counts);
  width = height = 0;
}

}  // namespace linebake::vk
