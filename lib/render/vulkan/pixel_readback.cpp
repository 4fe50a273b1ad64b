#include "render/vulkan/pixel_readback.hpp"

#include <algorithm>

namespace linebake::vk {

PixelReadback read_pixels(const Buffer& rgba_buffer, const Buffer& counts_buffer, int width,
                          int height) {
  const uint64_t pixels = uint64_t(width) * uint64_t(height);
  PixelReadback out;
  out.image = Image(width, height, 3);
  out.alpha.resize(pixels);
  out.counts.resize(pixels);
  const auto* rgba = static_cast<const float*>(rgba_buffer.mapped);
  const auto* counts = static_cast<const uint32_t*>(counts_buffer.mapped);
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
  rgba = context.create_buffer(pixels * 16, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
  counts = context.create_buffer(pixels * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
  width = w, height = h;
  return true;
}

void PixelTargets::release(Context& context) {
  context.destroy(rgba);
  context.destroy(counts);
  width = height = 0;
}

}  // namespace linebake::vk
