#include "voxels/occupancy.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>

namespace linebake {
namespace {

void set_bit(std::vector<uint32_t>& words, uint64_t first, uint64_t bit) {
  words[first + bit / 32] |= 1u << (bit % 32);
}

}  // namespace

OccupancyPyramid build_occupancy(const VoxelGrid& grid, size_t max_levels) {
  OccupancyPyramid p;
  std::array<uint32_t, 3> r = grid.resolution;
  for (size_t k = 0; k < max_levels; ++k) {
    p.resolution.push_back(r);
    if (r[0] == 1 && r[1] == 1 && r[2] == 1) break;
    for (uint32_t& n : r) n = (n + 1) / 2;
  }
  uint64_t words = 0;
  for (const auto& res : p.resolution) {
    p.first_word.push_back(words);
    words += (uint64_t(res[0]) * res[1] * res[2] + 31) / 32;
  }
  p.words.assign(words, 0);
  // Level 0: a voxel is occupied when it or one of its 26 neighbours has chords. Each z slab is
  // dilated into its own bytes in parallel; the bits are then set serially.
  const auto& g = grid.resolution;
  const auto has_chords = [&](int64_t x, int64_t y, int64_t z) {
    const uint64_t i = grid.index(uint32_t(x), uint32_t(y), uint32_t(z));
    return grid.offsets[i + 1] > grid.offsets[i];
  };
  std::vector<std::vector<uint8_t>> slabs(g[2]);
  tbb::parallel_for(uint32_t(0), g[2], [&](uint32_t z) {
    std::vector<uint8_t>& slab = slabs[z];
    slab.assign(uint64_t(g[0]) * g[1], 0);
    for (int64_t dz = -1; dz <= 1; ++dz) {
      const int64_t zz = int64_t(z) + dz;
      if (zz < 0 || zz >= int64_t(g[2])) continue;
      for (uint32_t y = 0; y < g[1]; ++y)
        for (uint32_t x = 0; x < g[0]; ++x) {
          if (!has_chords(x, y, zz)) continue;
          for (int64_t dy = -1; dy <= 1; ++dy)
            for (int64_t dx = -1; dx <= 1; ++dx) {
              const int64_t yy = int64_t(y) + dy, xx = int64_t(x) + dx;
              if (yy >= 0 && yy < int64_t(g[1]) && xx >= 0 && xx < int64_t(g[0]))
                slab[uint64_t(yy) * g[0] + uint64_t(xx)] = 1;
            }
        }
    }
  });
  for (uint32_t z = 0; z < g[2]; ++z)
    for (uint64_t i = 0; i < slabs[z].size(); ++i)
      if (slabs[z][i]) set_bit(p.words, 0, uint64_t(z) * g[0] * g[1] + i);
  for (size_t k = 1; k < p.levels(); ++k) {
    const auto& fine = p.resolution[k - 1];
    const auto& coarse = p.resolution[k];
    for (uint32_t z = 0; z < fine[2]; ++z)
      for (uint32_t y = 0; y < fine[1]; ++y)
        for (uint32_t x = 0; x < fine[0]; ++x)
          if (p.occupied(k - 1, x, y, z))
            set_bit(p.words, p.first_word[k],
                    (uint64_t(z / 2) * coarse[1] + y / 2) * coarse[0] + x / 2);
  }
  return p;
}

}  // namespace linebake
