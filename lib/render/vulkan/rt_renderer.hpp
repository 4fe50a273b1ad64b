#pragma once
// Vulkan ray tracing of an RtScene (technique `rtx`): one ray generation invocation per pixel
// runs the closest-hit loop of shaders/rtx.rgen; hit groups for triangles and for capsules
// (intersection shader). Output, hit counts and counters are read back like the voxel caster's.

#include <memory>

#include "render/camera.hpp"
#include "render/image.hpp"
#include "render/ray_tracer.hpp"
#include "render/transfer_function.hpp"
#include "render/vulkan/context.hpp"
#include "render/vulkan/rt_scene.hpp"

namespace linebake::vk {

struct RtOptions {
  int width = 1280, height = 720;
  bool early_termination = false;  // stop at termination_alpha (off for comparisons)
  double termination_alpha = 0.99;
  uint32_t max_iterations = 1024;  // traces per pixel; a pixel that runs out is counted
  Shading shading;
};

struct RtStats {
  double seconds = 0;  // wall, readback included
  double gpu_ms = 0;   // vkCmdTraceRaysKHR between timestamps
  uint64_t hits = 0, back_hits = 0, traces = 0;
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
