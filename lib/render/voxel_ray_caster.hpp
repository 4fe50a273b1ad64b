#pragma once
// Voxel ray casting (VRC, Kanzler et al. 2018; techniques.md section 8) on the CPU: rays walk the
// quantized voxel line grid with a 3D DDA (Amanatides & Woo); in each voxel the chords of its
// 3x3x3 neighbourhood, decoded with the voxelizer's own unpack_chord(), are intersected as
// capsules of the tube radius; hits inside the voxel are sorted, a repeated line id (mod 32) in
// one voxel is skipped, and the rest are composited front to back with the ray tracer's shading.
// The Vulkan compute version (render/vulkan/voxel_caster.hpp) runs the same traversal.

#include <cstdint>
#include <vector>

#include "render/camera.hpp"
#include "render/image.hpp"
#include "render/ray_tracer.hpp"
#include "render/transfer_function.hpp"
#include "voxels/occupancy.hpp"
#include "voxels/voxel_grid.hpp"

namespace linebake {

struct VrcOptions {
  int width = 1280, height = 720;
  // Tube radius in world units; at most one voxel (the neighbourhood a voxel searches), larger
  // values are clamped and reported.
  double radius = 0;
  bool early_termination = true;  // stop at termination_alpha, as the paper's VRC does
  double termination_alpha = 0.99;
  bool skip_empty_space = true;  // jump over cells empty at any occupancy mip level
  Shading shading;
};

struct VrcStats {
  double seconds = 0;
  double radius = 0;  // the radius used (world units)
  bool radius_clamped = false;
  uint64_t voxels_visited = 0;  // voxels whose neighbourhood was searched
  uint64_t cells_skipped = 0;   // empty cells jumped over (any level)
  uint64_t chords_tested = 0;
  uint64_t hits = 0;  // composited hits
  uint32_t max_depth_complexity = 0;
  uint64_t frame_bytes = 0;
  // --on gpu: dispatches the frame took, and the voxel steps each walked at most (0: the whole
  // walk in one; lavapipe's loop limit makes slices, VoxelCaster::render).
  uint32_t gpu_slices = 0, gpu_slice_steps = 0;
};

struct VrcCounters {
  uint64_t voxels_visited = 0, cells_skipped = 0, chords_tested = 0;
};

struct VrcFrame {
  Image image;                             // linear RGB, background included
  std::vector<float> alpha;                // accumulated opacity per pixel
  std::vector<uint32_t> depth_complexity;  // hits composited per pixel
  VrcStats stats;
};

// Renders one frame with TBB over 16x16 tiles; the image does not depend on the thread count.
// `occupancy` is only read when options.skip_empty_space is set.
VrcFrame cast_voxel_frame(const VoxelGrid& grid, const OccupancyPyramid& occupancy,
                          const Camera& camera, const TransferFunction& tf,
                          const VrcOptions& options);

// The radius VRC would use for `requested` (clamped to one voxel); 0 picks 0.5 voxel.
double vrc_radius(const VoxelGrid& grid, double requested);

}  // namespace linebake
