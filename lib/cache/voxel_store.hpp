#pragma once
// The voxel line grid in the cache: group /assets/voxels (docs/cache.md).

#include <memory>

#include "cache/cache.hpp"
#include "voxels/voxel_grid.hpp"
#include "voxels/voxelizer.hpp"

namespace linebake {

constexpr const char* kVoxelsGroup = "/assets/voxels";

// Writes the grid and its provenance; fills provenance.disk_bytes and memory_bytes (the
// representation VRC renders from: offsets + chords).
void store_voxels(CacheWriter& cache, const VoxelGrid& grid, Provenance provenance);
VoxelGrid load_voxels(const CacheReader& cache);
// The grid's description alone (placement, attribute, statistics; no arrays).
VoxelGrid load_voxel_description(const CacheReader& cache);
// The grid's arrays a piece at a time (VoxelPieces), each checked against its stored hash once
// read whole (finish()), the offsets as load_voxels checks them: for a reader that need not hold
// the grid whole (write_vdb).
std::unique_ptr<VoxelPieces> voxel_pieces(const CacheReader& cache);

// This rank's part of a grid merged by several ranks into one parallel cache (linebake-mpi):
// voxels from `first_voxel` and chords from `first_chord` on, in rank order.
struct VoxelSinkPiece {
  uint64_t first_voxel = 0, first_chord = 0;
  bool last = true;  // writes the closing offset (the total chord count)
  bool root = true;  // writes the coarser density levels
};

// Writes a streamed voxel build (VoxelStreamBuilder) into the cache as it merges. In a parallel
// cache every rank calls begin and end together, with the same grid and chord count; end writes
// what is left collectively.
class VoxelStoreSink : public VoxelSink {
 public:
  explicit VoxelStoreSink(CacheWriter& cache, VoxelSinkPiece piece = {});
  ~VoxelStoreSink() override;
  void begin(const VoxelGrid& grid, uint64_t chord_count) override;
  void voxels(uint64_t first, uint64_t count, const uint32_t* offsets, const uint8_t* line_counts,
              const float* density, const uint32_t* chords, uint64_t chord_count) override;
  void end(const VoxelGrid& grid, uint32_t chord_count,
           std::vector<Array<float>> coarse_density) override;
  // Writes the provenance (disk and memory bytes filled in); call after the builder's finish().
  void close(Provenance provenance);
  uint64_t chord_count() const;
  // Bytes of every array in memory: offsets, chords, line counts and the density levels.
  uint64_t memory_with_density() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace linebake
