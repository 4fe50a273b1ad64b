// Multi-layer alpha blending (`mlab`, techniques.md section 4) and the paper's MLAB with depth
// buckets (`mlabdb`, section 5). The nodes (in pages, past one buffer where needed) are cleared
// plane by plane (depth +inf, rgb 0, T 1),
// MLABDB first finds each pixel's bucket depths, then every fragment is inserted under the
// pixel's critical section and a compute pass blends the k nodes.
#include "render/vulkan/raster_state.hpp"

namespace linebake::vk {
namespace {

constexpr uint32_t kPlusInfinity = 0x7F800000u;
constexpr uint32_t kOne = 0x3F800000u;

}  // namespace

void RasterRenderer::State::render_mlab(const RasterOptions& o, RasterFrame& frame) {
  const bool buckets = o.technique == RasterTechnique::MlabBuckets;
  const uint32_t k = uint32_t(o.layers);
  const uint64_t plane = pixels() * k;  // one word per node
  const bool interlock = o.interlock && ctx.info().fragment_shader_interlock;
  ctx.submit([&](VkCommandBuffer cmd) {
    begin_timing(cmd);
    fill(cmd, pixel_state, 0, pixels() * 4, 0);                         // locks
    fill(cmd, pixel_state, pixels() * 4, pixels() * 8, kPlusInfinity);  // bucket depths
    fill_pages(cmd, 0, plane, kPlusInfinity);
    fill_pages(cmd, plane, 3 * plane, 0);
    fill_pages(cmd, 4 * plane, plane, kOne);
    barrier_all(cmd);
    mark(cmd, "clear");
    if (buckets) {
      draw(cmd, DrawSetup{"mlabdb_depth.frag"});
      mark(cmd, "bucket depths");
    }
    const char* insert = interlock ? "mlab_gather_interlock.frag" : "mlab_gather.frag";
    draw(cmd, DrawSetup{insert, 0, false, false, {k, buckets ? 1u : 0u, paged()}});
    mark(cmd, "insert");
    dispatch(cmd, compute("mlab_resolve.comp", {k, 0, paged()}));
    mark(cmd, "resolve");
  });
  read_timings(frame.stats);
  read_output(frame);
  frame.stats.layers = int(k);
  frame.stats.critical_section = interlock ? "interlock" : "spin lock";
  frame.stats.node_buffers = uint32_t(pages.size());
  // Locks (+ two bucket depths for mlabdb), k nodes of 20 bytes, the output.
  frame.stats.frame_bytes = pixels() * ((buckets ? 12 : 4) + 20 * k + 16);
}

}  // namespace linebake::vk
