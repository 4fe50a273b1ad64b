#pragma once
// The voxel step of an MPI bake: every rank has walked its own lines; the chord records go to the
// ranks that own their voxels (z slabs), in waves of all-to-all exchanges in rank order, which is
// line order; each rank merges its slab in rounds of collective writes; rank 0 makes the coarser
// density levels. The grid equals the serial bake's byte for byte (docs/mpi.md).

#include <functional>

#include "cache/cache.hpp"
#include "pipeline/mpi_ranks.hpp"
#include "voxels/voxelizer.hpp"

namespace linebake {

// The voxels each rank merges: [bounds[r], bounds[r + 1]).
std::vector<uint64_t> voxel_owners(const VoxelGrid& grid, const std::vector<uint64_t>& unit_records,
                                   uint64_t unit_voxels, int ranks);

// Makes the step's provenance from this rank's figures, the chord count and the grid's bytes
// with its density levels; called on every rank, it returns the same on every rank.
using VoxelProvenance =
    std::function<Provenance(const nlohmann::json& mine, uint64_t chords, uint64_t bytes)>;
// Collective. `exchange_bytes` bounds a wave's buffers, `merge_bytes` a round of the merge.
void merge_voxels_mpi(const Ranks& ranks, VoxelStreamBuilder& builder, CacheWriter& writer,
                      uint64_t exchange_bytes, uint64_t merge_bytes, bool show,
                      const VoxelProvenance& provenance);

}  // namespace linebake
