#pragma once
// Voxel ray casting with Vulkan compute (shaders/vrc.comp): the grid's offsets and chords and the
// occupancy mips uploaded once, then one dispatch per frame, one invocation per pixel. The same
// traversal, decoding and shading as the CPU caster (render/voxel_ray_caster.hpp), in float32.

#include <memory>

#include "render/voxel_ray_caster.hpp"
#include "render/vulkan/context.hpp"

namespace linebake::vk {

class VoxelCaster {
 public:
  // `grid` must outlive the caster (its voxel size clamps the radius); its arrays are copied.
  // Offsets and chords larger than one storage buffer (maxStorageBufferRange, or
  // max_buffer_bytes when lower and not 0) are split across up to 8 buffers each.
  VoxelCaster(Context& context, const VoxelGrid& grid, const OccupancyPyramid& occupancy,
              uint64_t max_buffer_bytes = 0);
  VoxelCaster(const VoxelCaster&) = delete;
  VoxelCaster& operator=(const VoxelCaster&) = delete;
  ~VoxelCaster();

  // stats: seconds (wall), gpu_ms in `gpu_ms`, hits and depth complexity, the slices below;
  // the traversal counters (voxels visited, cells skipped, chords tested) are CPU-only and stay 0.
  // On lavapipe, whose loop limit cuts an invocation short after 65535 trips of its loops
  // together, a walk the limit cut short is rendered again in slices of at most N voxel steps
  // a dispatch (256, then halved until none is cut short; kept for the caster's later frames,
  // which then walk in slices even where one walk would do), the pixels'
  // state kept between dispatches in bands of rows that fit one storage buffer: the same bytes as
  // one walk. Throws Error where even a step a dispatch is cut short.
  VrcFrame render(const Camera& camera, const TransferFunction& tf, const VrcOptions& options);
  // Slices of `steps` voxel steps a dispatch from the next frame on (0: one walk, sliced only
  // where lavapipe's limit cuts it short), in bands of at most `band_rows` rows (0: as many as
  // one storage buffer's state holds); for tests.
  void set_slice_steps(uint32_t steps, uint32_t band_rows = 0);
  double last_gpu_ms() const;
  uint64_t grid_bytes() const;    // offsets + chords + occupancy on the device
  uint32_t grid_buffers() const;  // storage buffers the offsets and chords took (2 unsplit)

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace linebake::vk
