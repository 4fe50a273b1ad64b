#pragma once
// Vulkan ray tracing of an RtScene (technique `rtx`): one ray generation invocation per pixel
// runs the loop of shaders/rtx.rgen over windows of hits (any-hit shaders) or closest hits;
// hit groups for triangles and for capsules (intersection shader). Output, hit counts and counters
// are read back like the voxel caster's.

#include <memory>
#include <string>

#include "render/camera.hpp"
#include "render/image.hpp"
#include "render/ray_tracer.hpp"
#include "render/transfer_function.hpp"
#include "render/vulkan/context.hpp"
#include "render/vulkan/rt_scene.hpp"

namespace linebake::vk {

// How a pixel's hits are found, as the CPU tracer's HitCollection: `filter` collects windows
// of hits with any-hit shaders (every hit, exact order); `stepping` repeats closest-hit traces
// from just past the previous hit (hits closer than that behind it are lost).
enum class RtHits { Filter, Stepping };
RtHits parse_rt_hits(const std::string& name);  // filter | stepping
const char* to_string(RtHits hits);

struct RtOptions {
  int width = 1280, height = 720;
  bool early_termination = false;  // stop at termination_alpha (off for comparisons)
  double termination_alpha = 0.99;
  uint32_t max_iterations = 1024;  // traces per pixel; a pixel that runs out is counted
  RtHits hits = RtHits::Filter;
  Shading shading;
};

struct RtStats {
  double seconds = 0;  // wall, readback included
  double gpu_ms = 0;   // vkCmdTraceRaysKHR between timestamps
  uint64_t hits = 0, back_hits = 0, traces = 0;
  uint64_t seam_hits = 0;         // a second hit at a seam (shared edge or joint), not composited
  uint64_t truncated_pixels = 0;  // pixels that hit max_iterations before a miss
  uint32_t max_depth_complexity = 0;
  uint64_t frame_bytes = 0;
};

struct RtFrame {
  Image image;  // linear RGB
  std::vector<float> alpha;
  std::vector<uint32_t> depth_complexity;  // front hits composited per pixel
  RtStats stats;
};

class RtRenderer {
 public:
  explicit RtRenderer(Context& context);
  RtRenderer(const RtRenderer&) = delete;
  RtRenderer& operator=(const RtRenderer&) = delete;
  ~RtRenderer();

  RtFrame render(const RtScene& scene, const Camera& camera, const TransferFunction& tf,
                 const RtOptions& options);

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace linebake::vk
