#pragma once
// Empty-space skipping for voxel ray casting (techniques.md section 8): which voxels can produce a
// hit, and 2x2x2 mip levels of that, as bitsets. A voxel can be hit by a chord of any voxel in its
// 3x3x3 neighbourhood (the tube radius is at most one voxel), so level 0 is the chord occupancy
// dilated by one voxel; level k + 1 is the OR of 2x2x2 cells of level k. A ray may jump over a
// cell that is empty at any level.
//
// The cached density mips are not used for this: they weight length by the attribute, so a line
// at the attribute's minimum would read as empty space.

#include <array>
#include <cstdint>
#include <vector>

#include "voxels/voxel_grid.hpp"

namespace linebake {

struct OccupancyPyramid {
  std::vector<std::array<uint32_t, 3>> resolution;  // per level, ceil(grid / 2^k)
  std::vector<uint64_t> first_word;                 // per level, into words
  std::vector<uint32_t> words;                      // bit (x + r0 (y + r1 z)) of each level

  size_t levels() const { return resolution.size(); }
  bool occupied(size_t level, uint32_t x, uint32_t y, uint32_t z) const {
    const auto& r = resolution[level];
    const uint64_t bit = (uint64_t(z) * r[1] + y) * r[0] + x;
    return (words[first_word[level] + bit / 32] >> (bit % 32)) & 1u;
  }
  uint64_t bytes() const { return words.size() * 4; }
};

// Levels down to a single cell (at most `max_levels`).
OccupancyPyramid build_occupancy(const VoxelGrid& grid, size_t max_levels = 16);

}  // namespace linebake
