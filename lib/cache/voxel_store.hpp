#pragma once
// The voxel line grid in the cache: group /assets/voxels (docs/cache.md).

#include "cache/cache.hpp"
#include "voxels/voxel_grid.hpp"

namespace linebake {

constexpr const char* kVoxelsGroup = "/assets/voxels";

// Writes the grid and its provenance; fills provenance.disk_bytes and memory_bytes (the
// representation VRC renders from: offsets + chords).
void store_voxels(CacheWriter& cache, const VoxelGrid& grid, Provenance provenance);
VoxelGrid load_voxels(const CacheReader& cache);

}  // namespace linebake
