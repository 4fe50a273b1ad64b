// Depth peeling (techniques.md section 2): a counting pass finds the depth complexity, whose
// maximum is the number of layers; each layer pass keeps the nearest fragment strictly behind the
// previous layer (depth test LESS plus a discard against the peeled depth), and a compute pass
// blends it under the pixels so far. Command buffers are flushed every 512 layers, like the
// public code.
#include <algorithm>

#include "render/vulkan/raster_state.hpp"

namespace linebake::vk {
namespace {

constexpr uint32_t kMinusOne = 0xBF800000u;  // -1.0f: nothing peeled yet
constexpr float kNoFragment = 2.0f;          // the layer depth target's clear value
constexpr int kLayersPerSubmission = 512;

}  // namespace

void RasterRenderer::State::render_peeling(const RasterOptions& o, RasterFrame& frame) {
  count_fragments(frame);
  const double count_ms = frame.stats.pass_ms.empty() ? 0.0 : frame.stats.pass_ms[0].second;
  const int needed = int(frame.stats.max_depth_complexity);
  const int layers = std::min(needed, o.max_layers);
  frame.stats.layers = layers;
  frame.stats.layers_capped = needed > o.max_layers;
  const uint64_t layer_depth_offset = pixels() * 16;
  DrawSetup peel{"dp_peel.frag", 2, true};
  peel.clear_scalar = kNoFragment;
  int done = 0;
  do {
    ctx.submit([&](VkCommandBuffer cmd) {
      if (done == 0) {
        begin_timing(cmd);
        fill(cmd, pixel_state, 0, VK_WHOLE_SIZE, kMinusOne);
        fill(cmd, output.gpu, 0, VK_WHOLE_SIZE, 0);
        barrier_all(cmd);
      }
      const int end = std::min(layers, done + kLayersPerSubmission);
      for (; done < end; ++done) {
        draw(cmd, peel);
        copy_targets(cmd, nodes.buffer, {0, layer_depth_offset});
        dispatch(cmd, compute("dp_blend.comp", {0}));
      }
      if (done == layers) {
        dispatch(cmd, compute("dp_blend.comp", {1}));  // the background behind what is left
        mark(cmd, "peel");
      }
    });
  } while (done < layers);
  read_timings(frame.stats);
  frame.stats.pass_ms.insert(frame.stats.pass_ms.begin(), {"count", count_ms});
  read_output(frame);
  // Peeled depth, the two layer targets and their copy, the depth attachment, the accumulation.
  frame.stats.frame_bytes = pixels() * (4 + 20 + 20 + 4 + 16);
}

}  // namespace linebake::vk
