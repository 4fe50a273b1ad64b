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
// Voxels along a grid's axis at most.
inline constexpr uint32_t kMaxGridResolution = 4096;
// "256" -> longest axis 256; "113x110x128" -> explicit; "auto". Throws UsageError on anything
// else, a number outside 1..kMaxGridResolution included.
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
  // A run is spilled, too, when the process's resident memory with it would pass this (0:
  // never): a guard for what the shares above do not count (another step's buffers side by
  // side, the allocator's slack). Where the records go does not change the grid.
  uint64_t resident_limit = 0;
};
// The shares a streamed build takes of `available` bytes (bake's): one voxel range's merge, a
// quarter and 256 MiB at most (little beyond what the records hold already), and the records
// kept in memory, the rest less 5 % of slack. No spill location, no resident limit.
VoxelMemory voxel_memory_within(uint64_t available);

// A chord on its way to its voxel: what walking a line makes, and what the ranks of a
// distributed build send each other. 16 bytes: the line id is not kept; bit 31 of word1 (free in
// the chord layout) marks a line's first chord in its voxel, which is all the distinct-line count
// needs, and is cleared on output.
struct VoxelRecord {
  uint32_t voxel;
  uint32_t word0, word1;
  float weight;  // polyline length inside the voxel x the chord's mean attribute (density)
};

// Figures of a partial build that combine across the ranks of a distributed build: sums, and
// the largest error. The error sum is fixed point (2^-32 voxel) in 128 bits, so that it does not
// depend on the order in which the pieces are added.
struct VoxelTallies {
  uint64_t voxels_occupied = 0, voxels_overflowed = 0, chords_dropped = 0;
  double error_max = 0;
  uint64_t error_sum_low = 0, error_sum_high = 0;
  uint64_t error_samples = 0;
  void add(const VoxelTallies& other);
};

// Density mip levels 1.. from the sums of level 1 (each coarse voxel the sum of its 2x2x2
// children, added in voxel order): the 2x2x2 means, missing children counted as empty, down to
// one voxel. Nothing for a grid of one voxel.
std::vector<Array<float>> density_levels(const VoxelGrid& grid, Array<float> level1_sums);
// Level 1's sums, all zero, sized for the grid.
Array<float> zero_level1_sums(const VoxelGrid& grid);

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
  // Memory the build holds whatever its budget: a chord count per voxel (1 byte; 2 with a cap
  // above 255) and density level 1's sums, with the levels below it.
  uint64_t fixed_bytes() const;
  // Memory each add() keeps until the merge whatever its budget: its run's index of where each
  // unit of voxels starts (4 bytes a unit and one more, at most 4,096 units), in memory whether its
  // records are or were spilled.
  uint64_t run_index_bytes() const;
  // Memory the runs received from `ranks` ranks (distributed builds) keep for their indexes until
  // the merge, at the most: each covers one wave's units, and the waves cover each unit once.
  uint64_t received_index_bytes(int ranks) const;
  // Bytes of records written to the spill file (0: everything stayed in memory).
  uint64_t spilled_bytes() const;
  // Bytes of records held in memory at the most.
  uint64_t peak_record_bytes() const;

  // Distributed builds (linebake-mpi, docs/mpi.md). Each rank walks its own lines; the records
  // then go to the rank that owns their voxels, in rank order, and that rank merges its voxels.
  // What finish() does is then: kept_chords, merge, tallies combined by set_statistics, and
  // density_levels from every rank's level 1 sums.
  //
  // Numbers the lines from `line` on (before the first add): the chords keep line id mod 32.
  void start_at_line(uint64_t line);
  // Records per unit of voxels over every batch so far, and a unit's size in voxels.
  const std::vector<uint64_t>& unit_records() const;
  uint64_t unit_voxels() const;
  // Appends this builder's records of voxels [v0, v1) to `out`, unit by unit, in each unit in
  // the order they were walked: the canonical order of this builder's lines.
  void append_records(uint64_t v0, uint64_t v1, std::vector<VoxelRecord>& out);
  // Keeps records sent by the ranks, beside the builder's own until adopt_received(): the
  // buffer holds `counts[r]` records from rank r, in rank order, each rank's as append_records
  // gave them. Ranges of voxels may come in several calls, each range once, in voxel order. The
  // buffer is kept as it is within the builder's share for records, and spilled past it.
  void receive_records(Array<VoxelRecord> buffer, const std::vector<uint64_t>& counts);
  // The received records replace the builder's own.
  void adopt_received();
  // Chords voxels [v0, v1) keep under the cap.
  uint64_t kept_chords(uint64_t v0, uint64_t v1) const;
  // Merges voxels [v0, v1) into `sink` (its voxels() only), whose chords start at chord
  // `chords_before` of the grid; adds their density to `level1_sums`. Ranges merged into one
  // level 1 must come in voxel order, and a coarse voxel's children must all be merged into the
  // same one. Returns the chords written; `progress` counts voxels of the range.
  uint64_t merge(VoxelSink& sink, uint64_t v0, uint64_t v1, uint64_t chords_before,
                 Array<float>& level1_sums, const ProgressFn& progress = {});
  // This builder's walk and merge figures, and the grid's statistics from every rank's.
  VoxelTallies tallies() const;
  void set_statistics(const VoxelTallies& all);

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace linebake
