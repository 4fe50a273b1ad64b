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

  // stats: seconds (wall), gpu_ms in `gpu_ms`, hits and depth complexity; the traversal counters
  // (voxels visited, cells skipped, chords tested) are CPU-only and stay 0.
  VrcFrame render(const Camera& camera, const TransferFunction& tf, const VrcOptions& options);
  double last_gpu_ms() const;
  uint64_t grid_bytes() const;    // offsets + chords + occupancy on the device
  uint32_t grid_buffers() const;  // storage buffers the offsets and chords took (2 unsplit)

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace linebake::vk
