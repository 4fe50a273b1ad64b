// The blended approximations: moment-based OIT (`mboit`, techniques.md section 6: a moment pass,
// a colour pass weighted by the reconstructed transmittance, a resolve) and weighted blended OIT
// (`wboit`, section 7: one accumulation pass and a resolve). Both blend additively into float32
// targets that are then copied into binding 2 for the next pass.
#include "render/vulkan/raster_state.hpp"

namespace linebake::vk {

void RasterRenderer::State::render_moments(const RasterOptions& o, RasterFrame& frame) {
  const uint64_t p = pixels();
  const bool wide = o.moments > 4;  // b4 .. b7 in a third target
  const std::vector<uint32_t> constants{o.moment_basis == MomentBasis::Trigonometric ? 1u : 0u,
                                        uint32_t(o.moments)};
  const uint64_t moment_bytes = (wide ? 36 : 20) * p;
  ctx.submit([&](VkCommandBuffer cmd) {
    begin_timing(cmd);
    DrawSetup moments{wide ? "mboit_moments_wide.frag" : "mboit_moments.frag", wide ? 3u : 2u,
                      false, true, constants};
    draw(cmd, moments);
    if (wide)
      copy_targets(cmd, nodes.buffer, {0, 16 * p, 20 * p});
    else
      copy_targets(cmd, nodes.buffer, {0, 16 * p});
    mark(cmd, "moments");
    draw(cmd, DrawSetup{"mboit_colour.frag", 1, false, true, constants});
    copy_targets(cmd, nodes.buffer, {moment_bytes});
    mark(cmd, "colour");
    dispatch(cmd, compute("mboit_resolve.comp", constants));
    mark(cmd, "resolve");
  });
  read_timings(frame.stats);
  read_output(frame);
  // Moment targets and their copy, accumulation target and copy, the output.
  frame.stats.frame_bytes = 2 * moment_bytes + p * (16 + 16 + 16);
}

void RasterRenderer::State::render_weighted(RasterFrame& frame) {
  const uint64_t p = pixels();
  ctx.submit([&](VkCommandBuffer cmd) {
    begin_timing(cmd);
    draw(cmd, DrawSetup{"wboit_accumulate.frag", 2, false, true});
    copy_targets(cmd, nodes.buffer, {0, 16 * p});
    mark(cmd, "accumulate");
    dispatch(cmd, compute("wboit_resolve.comp"));
    mark(cmd, "resolve");
  });
  read_timings(frame.stats);
  read_output(frame);
  frame.stats.frame_bytes = p * (20 + 20 + 16);
}

}  // namespace linebake::vk
