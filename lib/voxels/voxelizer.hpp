#pragma once
// Line set -> quantized voxel line grid (techniques.md section 8), whole (voxelize) or batch by
// batch out of core (VoxelStreamBuilder) with the same bytes. Lines are walked through the grid
// a batch at a time into chord records, which are grouped by voxel range and kept in memory or
// spilled to a temporary file; the merge then goes through the grid one voxel range at a time.
// Chords are ordered by line id inside each voxel, so the bytes depend neither on the thread
// count nor on the batches or the memory given.

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

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

// Receives a streamed build: the per-voxel arrays and the chords in voxel order, one range of
// voxels at a time, then the statistics and the coarser density levels.
class VoxelSink {
 public:
  virtual ~VoxelSink() = default;
  // The grid's placement and sizes (no arrays, no statistics yet) and how many chords it keeps.
  virtual void begin(const VoxelGrid& grid, uint64_t chord_count) = 0;
  // Voxels [first, first + count): where their chords start among all the grid's chords, their
  // distinct lines and density_0; then their chords (2 words each), in order.
  virtual void voxels(uint64_t first, uint64_t count, const uint32_t* offsets,
                      const uint8_t* line_counts, const float* density, const uint32_t* chords,
                      uint64_t chord_count) = 0;
  // The grid with its statistics (still no arrays), the total chord count (the last offset) and
  // density levels 1.. (level 0 went out with the voxels).
  virtual void end(const VoxelGrid& grid, uint32_t chord_count,
                   std::vector<Array<float>> coarse_density) = 0;
};

// Memory a streamed build may hold, besides a chord count per voxel (1 byte; 2 with a cap above
// 255). Chord records (16 bytes each) stay in memory up to `records_bytes` and go to a spill
// file beside `spill_near` past it; the merge takes ranges of voxels whose records, chords and
// per-voxel arrays fit `merge_bytes`.
struct VoxelMemory {
  std::string spill_near;  // "" : never spill
  uint64_t records_bytes = UINT64_MAX;
  uint64_t merge_bytes = uint64_t{1} << 30;
};

class VoxelStreamBuilder {
 public:
  VoxelStreamBuilder(const LineSet& header, const LineSetStats& stats, const VoxelOptions& options,
                     VoxelMemory memory = {});
  ~VoxelStreamBuilder();
  // Walks the batch's lines; their ids continue from the previous batch's.
  void add(const LineSet& batch);
  // Merges the records voxel range by voxel range into `sink`. `progress` counts voxels.
  void finish(VoxelSink& sink, const ProgressFn& progress = {});
  // The grid's placement from the start, its statistics once finished (no arrays).
  const VoxelGrid& description() const;
  // Bytes of records written to the spill file (0: everything stayed in memory).
  uint64_t spilled_bytes() const;
  // Bytes of records held in memory at the most.
  uint64_t peak_record_bytes() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace linebake
