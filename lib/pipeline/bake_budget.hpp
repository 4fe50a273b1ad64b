#pragma once
// What a bake takes from its memory budget before its batches, and the one check a line makes
// against it: the serial bake (bake.cpp) and each rank of the MPI bake (bake_mpi.cpp) alike.
// (The MPI bake had neither: a budget the serial bake refuses at once ran 30 times as long and
// over it, and a line longer than a batch passed 169 MiB under a 100 MiB budget.)

#include <algorithm>
#include <cstdint>
#include <string>

#include "cache/cache.hpp"
#include "core/error.hpp"
#include "core/memory_budget.hpp"

namespace linebake {

// Refuses a budget that leaves less than 32 MiB to work in beside what the process holds (HDF5's
// caches, TBB, the allocator's slack, the datasets' pending chunks), and reserves the bake's
// fixed buffers: an eighth of what is left, 24 to 96 MiB (measured: about 20 MiB at the least,
// encoded chunks in flight and HDF5's own structures), or up to a quarter where the chunks in
// flight of many threads want more. Nothing for an unlimited budget.
// `writes_chunks`: whether the bake writes compressed chunks itself (append_together; the MPI
// bake's ranks write through HDF5's collective writes instead). Returns the bytes its writer's
// chunks in flight may take (CacheWriter::limit_chunks_in_flight; UINT64_MAX: any).
inline uint64_t reserve_bake_fixed_buffers(MemoryBudget& budget, bool writes_chunks = true) {
  if (budget.unlimited()) return UINT64_MAX;
  if (budget.available() < (uint64_t{32} << 20))
    throw BudgetExceeded("the memory budget of " + format_bytes(budget.total()) +
                         " is less than the process already holds (" +
                         format_bytes(budget.baseline()) + ") plus 32 MiB to work in");
  // An eighth of the budget (24 to 96 MiB): HDF5's own structures (12 MiB of it) and the
  // compressed chunks in flight. Those want 1.06 MiB for each of twice the threads and one, and
  // 1 MiB a thread (7.3 MiB on 2 threads, 51 on 16): they get up to a quarter of the budget, and
  // the pipeline takes as many as fit (at least 2).
  const uint64_t hdf5 = uint64_t{12} << 20;
  const uint64_t eighth =
      std::clamp<uint64_t>(budget.available() / 8, uint64_t{24} << 20, uint64_t{96} << 20);
  const uint64_t fixed = writes_chunks
                             ? std::max(eighth, std::min(chunks_in_flight_wanted_bytes() + hdf5,
                                                         budget.available() / 4))
                             : eighth;
  budget.reserve(fixed, "the bake's fixed buffers");
  return writes_chunks ? fixed - hdf5 : UINT64_MAX;
}

// Refuses line `line` of `source` when its `points` points, at `per_point` bytes each through
// every step, need more than half of what the budget leaves for a batch: a batch holds whole
// lines, so one longer than a batch is held whole.
inline void check_line_fits_batch(const MemoryBudget& budget, uint64_t points, uint64_t per_point,
                                  const std::string& source, uint64_t line) {
  if (budget.unlimited() || points * per_point <= budget.available() / 2) return;
  throw BudgetExceeded(source + ": line " + std::to_string(line) + " has " +
                       std::to_string(points) + " points; baking it needs about " +
                       format_bytes(points * per_point) + ", more than the memory budget of " +
                       format_bytes(budget.total()) + " leaves for one batch (" +
                       format_bytes(budget.available() / 2) + "); raise --memory-budget");
}

// The most batches a reader makes of `points` points in `lines` lines when each holds whole lines
// of at most `batch_points` points (a longer line alone): each but the last holds more than
// `batch_points` less the longest line's points (LineReader::next).
inline uint64_t most_batches(uint64_t points, uint64_t lines, uint64_t batch_points,
                             uint64_t largest_line) {
  const uint64_t least = batch_points > largest_line ? batch_points - largest_line : 0;
  return std::min<uint64_t>(lines, points / (least + 1) + 1);
}

}  // namespace linebake
