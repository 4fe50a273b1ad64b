#pragma once
// Reading back what the per-pixel GPU techniques (voxel caster, ray tracer) write: linear RGBA
// (16 bytes per pixel) and a hit count per pixel, from host-visible buffers.

#include <cstdint>
#include <vector>

#include "render/image.hpp"
#include "render/vulkan/context.hpp"

namespace linebake::vk {

struct PixelReadback {
  Image image;  // linear RGB
  std::vector<float> alpha;
  std::vector<uint32_t> counts;
  uint64_t total = 0;    // sum of the counts
  uint32_t maximum = 0;  // largest count
};

PixelReadback read_pixels(const Buffer& rgba, const Buffer& counts, int width, int height);

// The two host-visible per-pixel buffers those techniques write, sized for one image.
struct PixelTargets {
  Buffer rgba, counts;
  int width = 0, height = 0;
  // Reallocates for a new size (waiting for the device first); false when the size is unchanged.
  bool resize(Context& context, int w, int h);
  void release(Context& context);
  PixelReadback read() const { return read_pixels(rgba, counts, width, height); }
};

}  // namespace linebake::vk
