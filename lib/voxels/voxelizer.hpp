#pragma once
// Line set -> quantized voxel line grid (techniques.md section 8). Count, prefix sum and fill
// run on TBB; chords are ordered by line id inside each voxel, so the bytes do not depend on
// the thread count.

#include <array>
#include <cstdint>
#include <optional>
#include <string>

#include "core/progress.hpp"
#include "lines/line_set.hpp"
#include "voxels/voxel_grid.hpp"

namespace linebake {

struct VoxelOptions {
  // Voxels along the longest axis (the others in proportion); 0: automatic,
  // clamp(nextPow2(cbrt(segments)) * 2, 64, 512).
  uint32_t grid = 0;
  // Explicit voxels per axis (overrides grid); voxels stay cubic and cover the bounds.
  std::optional<std::array<uint32_t, 3>> resolution;
  uint32_t quantization = 32;          // 16, 32 or 64 cells per face axis
  uint32_t max_chords_per_voxel = 32;  // the rest are dropped and counted
  // Attribute carried as unorm8 at both chord ends: a vertex attribute by name, "" for the
  // first one, "none" for none.
  std::string attribute;
  std::optional<std::array<float, 2>> attribute_range;
};

uint32_t automatic_grid_resolution(uint64_t segments);
// "256" -> longest axis 256; "113x110x128" -> explicit. Throws Error on anything else.
void parse_grid(const std::string& text, VoxelOptions& options);

VoxelGrid voxelize(const LineSet& lines, const VoxelOptions& options,
                   const ProgressFn& progress = {});

}  // namespace linebake
