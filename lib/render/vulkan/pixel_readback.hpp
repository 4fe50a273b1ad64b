#pragma once
// Reading back what the per-pixel GPU techniques (voxel caster, ray tracer) write: linear RGBA
// (16 bytes per pixel) and a hit count per pixel, through Context::read_back.

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

PixelReadback read_pixels(const float* rgba, const uint32_t* counts, int width, int height);

// The two per-pixel result buffers those techniques write, sized for one image.
struct PixelTargets {
  ResultBuffer rgba, counts;
  int width = 0, height = 0;
  // Reallocates for a new size (waiting for the device first); false when the size is unchanged.
  bool resize(Context& context, int w, int h);
  void release(Context& context);
  // After the GPU work that wrote them has been waited for.
  PixelReadback read(Context& context) const;
};

}  // namespace linebake::vk
