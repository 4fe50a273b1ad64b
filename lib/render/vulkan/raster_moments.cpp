// The blended approximations: moment-based OIT (`mboit`, techniques.md section 6: a moment pass,
// a colour pass weighted by the reconstructed transmittance, a resolve) and weighted blended OIT
// (`wboit`, section 7: one accumulation pass and a resolve). Both blend additively into float32
// targets that are then copied into binding 2 for the next pass.
#include "render/vulkan/raster_state.hpp"

namespace linebake::vk {

void RasterRenderer::State::render_moments(RasterFrame& frame) {
  const uint64_t p = pixels();
  ctx.submit([&](VkCommandBuffer cmd) {
    begin_timing(cmd);
    draw(cmd, DrawSetup{"mboit_moments.frag", 2, false, true});
    copy_targets(cmd, 2, nodes.buffer, 0, 16 * p);
    mark(cmd, "moments");
    draw(cmd, DrawSetup{"mboit_colour.frag", 1, false, true});
    copy_targets(cmd, 1, nodes.buffer, 20 * p, 0);
    mark(cmd, "colour");
    dispatch(cmd, compute("mboit_resolve.comp"));
    mark(cmd, "resolve");
  });
  read_timings(frame.stats);
  read_output(frame);
  // Moment targets (20 bytes) and their copy, accumulation target and copy, the output.
  frame.stats.frame_bytes = p * (20 + 20 + 16 + 16 + 16);
}

void RasterRenderer::State::render_weighted(RasterFrame& frame) {
  const uint64_t p = pixels();
  ctx.submit([&](VkCommandBuffer cmd) {
    begin_timing(cmd);
    draw(cmd, DrawSetup{"wboit_accumulate.frag", 2, false, true});
    copy_targets(cmd, 2, nodes.buffer, 0, 16 * p);
    mark(cmd, "accumulate");
    dispatch(cmd, compute("wboit_resolve.comp"));
    mark(cmd, "resolve");
  });
  read_timings(frame.stats);
  read_output(frame);
  frame.stats.frame_bytes = p * (20 + 20 + 16);
}

}  // namespace linebake::vk
