// Per-pixel linked lists (techniques.md section 3): gather every fragment into a node pool (24-
// or 12-byte nodes, split across storage buffers: shaders/ll_nodes.glsl), then a compute resolve
// sorts each pixel's list and blends it front to back. The node counter
// keeps counting past the capacity, so an overflowing frame is re-rendered with a buffer of the
// counted size instead of losing fragments.
#include "core/error.hpp"
#include "render/vulkan/raster_state.hpp"

namespace linebake::vk {
namespace {

constexpr uint32_t kEmptyList = 0xFFFFFFFFu;

uint32_t next_power_of_two(uint64_t v) {
  uint64_t p = 1;
  while (p < v) p <<= 1;
  return uint32_t(p);
}

}  // namespace

void RasterRenderer::State::render_lists(const Camera& camera, const TransferFunction& tf,
                                         const RasterOptions& o, RasterFrame& frame) {
  // Local arrays of the resolve hold 64 fragments to start with; longer lists re-resolve below.
  uint32_t resolve_max = 64;
  const auto gather_and_resolve = [&] {
    ctx.submit([&](VkCommandBuffer cmd) {
      begin_timing(cmd);
      fill(cmd, pixel_state, 0, VK_WHOLE_SIZE, kEmptyList);
      fill(cmd, counter.gpu, 0, VK_WHOLE_SIZE, 0);
      fill(cmd, stats.gpu, 0, VK_WHOLE_SIZE, 0);
      barrier_all(cmd);
      mark(cmd, "clear");
      draw(cmd, DrawSetup{"ll_gather.frag", 0, false, false, {0, 0, paged(), page_unit_bytes / 4}});
      mark(cmd, "gather");
      dispatch(cmd, compute("ll_resolve.comp",
                            {resolve_max, uint32_t(o.sort), paged(), page_unit_bytes / 4}));
      mark(cmd, "resolve");
    });
    return uint64_t(*static_cast<const uint32_t*>(ctx.read_back(counter)));
  };
  uint64_t needed = gather_and_resolve();
  // Overflow: grow the node buffer to what the frame needed and render it again.
  while (needed > list_capacity) {
    if (needed >= 0xFFFFFFFFull / 2)
      throw Error("ll: more than 2^31 fragments in one frame; use a smaller size");
    const uint64_t grown = needed + needed / 8;
    prepare_pages(grown, o.node_bytes, o.max_buffer_bytes, "ll");
    list_capacity = grown;
    fill_uniforms(camera, tf, o);
    ++frame.stats.regrows;
    needed = gather_and_resolve();
  }
  read_timings(frame.stats);
  // Lists longer than the resolve's local arrays: resolve those pixels again with room for them
  // (a pass of its own in the frame's GPU time).
  const uint32_t longest = *static_cast<const uint32_t*>(ctx.read_back(stats, 4));
  if (longest > resolve_max) {
    const uint32_t resolved = resolve_max;
    resolve_max = next_power_of_two(longest);
    ctx.submit([&](VkCommandBuffer cmd) {
      begin_timing(cmd);
      dispatch(cmd, compute("ll_resolve.comp", {resolve_max, uint32_t(o.sort), paged(),
                                                page_unit_bytes / 4, resolved}));
      mark(cmd, "resolve again");
    });
    RasterStats again;
    read_timings(again);
    frame.stats.pass_ms.insert(frame.stats.pass_ms.end(), again.pass_ms.begin(),
                               again.pass_ms.end());
  }
  frame.stats.fragments = needed;
  frame.stats.capacity = list_capacity;
  frame.stats.node_buffers = uint32_t(pages.size());
  read_depth_complexity(frame);
  read_output(frame);
  frame.stats.frame_bytes = pixels() * 4 + list_capacity * page_unit_bytes + 4 + pixels() * 16;
}

}  // namespace linebake::vk
