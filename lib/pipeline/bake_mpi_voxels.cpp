#include "pipeline/bake_mpi_voxels.hpp"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <limits>
#include <numeric>

#include "cache/voxel_store.hpp"
#include "core/measure.hpp"
#include "core/progress.hpp"

namespace linebake {

// The voxels each rank merges: [bounds[r], bounds[r + 1]), cut where the records (summed over
// every rank, per unit of voxels) divide equally, rounded to a multiple of two z layers, so that
// every coarse voxel of density level 1 has all its children on one rank and is summed there in
// the serial build's order.
namespace {
__extension__ typedef unsigned __int128 uint128;
}  // namespace

std::vector<uint64_t> voxel_owners(const VoxelGrid& grid, const std::vector<uint64_t>& unit_records,
                                   uint64_t unit_voxels, int ranks) {
  const uint64_t voxels = grid.voxel_count();
  const uint64_t slab = 2 * uint64_t(grid.resolution[0]) * grid.resolution[1];
  const uint64_t total = std::accumulate(unit_records.begin(), unit_records.end(), uint64_t{0});
  std::vector<uint64_t> bounds(size_t(ranks) + 1, voxels);
  bounds[0] = 0;
  uint64_t unit = 0, before = 0;  // records in the units before `unit`
  for (int r = 1; r < ranks; ++r) {
    const uint64_t target = uint64_t(uint128(total) * uint64_t(r) / uint64_t(ranks));
    while (unit < unit_records.size() && before + unit_records[unit] <= target)
      before += unit_records[unit++];
    uint64_t voxel = unit * unit_voxels;
    if (unit < unit_records.size() && unit_records[unit])
      voxel += uint64_t(uint128(target - before) * unit_voxels / unit_records[unit]);
    voxel = (voxel + slab / 2) / slab * slab;
    bounds[size_t(r)] = std::clamp(voxel, bounds[size_t(r) - 1], voxels);
  }
  return bounds;
}

// The records go to their owners in waves of whole units, at most `exchange_bytes` of buffers
// each; the merge runs in rounds of whole units, each a collective write.
void merge_voxels_mpi(const Ranks& ranks, VoxelStreamBuilder& builder, CacheWriter& writer,
                      uint64_t exchange_bytes, uint64_t merge_bytes, bool show,
                      const VoxelProvenance& provenance) {
  const VoxelGrid& grid = builder.description();
  const std::vector<uint64_t> units = ranks.sum(builder.unit_records());
  const std::vector<uint64_t> bounds = voxel_owners(grid, units, builder.unit_voxels(), ranks.size);
  const uint64_t first = bounds[size_t(ranks.rank)], end = bounds[size_t(ranks.rank) + 1];
  const auto exchange_start = std::chrono::steady_clock::now();
  uint64_t walked = 0, received = 0;
  for (uint64_t n : builder.unit_records()) walked += n;
  // Waves of whole units, each at most `wave_records` records over all ranks: every rank sends
  // each owner its records of the wave's voxels, in one all-to-all per wave.
  // The same waves on every rank: the smallest rank's share.
  const uint64_t wave_records =
      std::max<uint64_t>(ranks.min(exchange_bytes) / (2 * sizeof(VoxelRecord)), 1);
  const uint64_t unit_voxels = builder.unit_voxels(), voxels = grid.voxel_count();
  std::vector<uint64_t> waves{0};
  uint64_t in_wave = 0;
  for (size_t u = 0; u < units.size(); ++u) {
    if (in_wave > 0 && in_wave + units[u] > wave_records) {
      waves.push_back(u * unit_voxels);
      in_wave = 0;
    }
    in_wave += units[u];
  }
  waves.push_back(voxels);
  const auto to_int = [](uint64_t n) {
    if (n > uint64_t(std::numeric_limits<int>::max()))
      throw Error("voxels: more than 2^31 chord records in one exchange; use a smaller budget");
    return int(n);
  };
  MPI_Datatype record_type;
  MPI_Type_contiguous(int(sizeof(VoxelRecord)), MPI_BYTE, &record_type);
  MPI_Type_commit(&record_type);
  const size_t n = size_t(ranks.size);
  // Room for this rank's largest wave, so the buffer grows once.
  std::vector<VoxelRecord> send;
  {
    const std::vector<uint64_t>& mine = builder.unit_records();
    uint64_t largest = 0;
    for (size_t w = 0; w + 1 < waves.size(); ++w) {
      uint64_t in = 0;
      for (uint64_t u = waves[w] / unit_voxels; u * unit_voxels < waves[w + 1]; ++u) in += mine[u];
      largest = std::max(largest, in);
    }
    send.reserve(largest);
  }
  std::vector<uint64_t> send_counts(n), receive_counts(n);
  std::vector<int> sc(n), sd(n), rc(n), rd(n);
  for (size_t w = 0; w + 1 < waves.size(); ++w) {
    send.clear();
    for (size_t r = 0; r < n; ++r) {
      const size_t before = send.size();
      builder.append_records(std::max(waves[w], bounds[r]), std::min(waves[w + 1], bounds[r + 1]),
                             send);
      send_counts[r] = send.size() - before;
    }
    MPI_Alltoall(send_counts.data(), 1, MPI_UINT64_T, receive_counts.data(), 1, MPI_UINT64_T,
                 ranks.comm);
    uint64_t sent = 0, got = 0;
    for (size_t r = 0; r < n; ++r) {
      sc[r] = to_int(send_counts[r]), sd[r] = to_int(sent), sent += send_counts[r];
      rc[r] = to_int(receive_counts[r]), rd[r] = to_int(got), got += receive_counts[r];
    }
    Array<VoxelRecord> incoming(got);
    MPI_Alltoallv(send.data(), sc.data(), sd.data(), record_type, incoming.data(), rc.data(),
                  rd.data(), record_type, ranks.comm);
    builder.receive_records(std::move(incoming), receive_counts);
    received += got;
  }
  MPI_Type_free(&record_type);
  std::vector<VoxelRecord>().swap(send);
  builder.adopt_received();
  const double exchange_s = seconds_since(exchange_start);

  // The chords this rank keeps, and where they start among the grid's.
  const uint64_t kept = builder.kept_chords(first, end);
  const uint64_t total = ranks.sum(kept), chords_before = ranks.exclusive_sum(kept);
  if (total > 0xFFFFFFFFull) throw Error("voxels: more than 2^32 chords; use a coarser grid");
  VoxelStoreSink sink(writer,
                      {first, chords_before, ranks.rank == ranks.size - 1, ranks.rank == 0});
  sink.begin(grid, total);
  // Rounds of whole units, each within the merge's share of the budget.
  const uint64_t round_records = std::max<uint64_t>(merge_bytes / 32, 1);
  std::vector<uint64_t> cuts{first};
  uint64_t in_round = 0;
  for (uint64_t u = first / unit_voxels; end > first && u <= (end - 1) / unit_voxels; ++u) {
    const uint64_t records = builder.unit_records()[u];
    if (in_round > 0 && in_round + records > round_records && u * unit_voxels > cuts.back()) {
      cuts.push_back(u * unit_voxels);
      in_round = 0;
    }
    in_round += records;
  }
  cuts.push_back(end);
  const uint64_t rounds = ranks.max(cuts.size() - 1);
  Array<float> level1 = zero_level1_sums(grid);
  TerminalProgress progress("merging voxels");
  const auto merge_start = std::chrono::steady_clock::now();
  uint64_t merged = 0;
  for (uint64_t round = 0; round < rounds; ++round) {
    if (round + 1 < cuts.size())
      merged += builder.merge(sink, cuts[round], cuts[round + 1], chords_before + merged, level1);
    writer.write_round();
    if (show) progress.update(round + 1, rounds);
  }
  // The grid's statistics from every rank's tallies, added in rank order.
  VoxelTallies mine = builder.tallies(), all;
  const std::string bytes(reinterpret_cast<const char*>(&mine), sizeof mine);
  for (const std::string& piece : ranks.allgather(bytes)) {
    VoxelTallies t;
    std::memcpy(&t, piece.data(), sizeof t);
    all.add(t);
  }
  builder.set_statistics(all);
  // Level 1: each coarse voxel was summed on one rank; the others add zeros, exactly.
  constexpr uint64_t kPiece = uint64_t{1} << 24;
  for (uint64_t at = 0; at < level1.size(); at += kPiece) {
    const int count = int(std::min(kPiece, level1.size() - at));
    if (ranks.rank == 0)
      MPI_Reduce(MPI_IN_PLACE, level1.data() + at, count, MPI_FLOAT, MPI_SUM, 0, ranks.comm);
    else
      MPI_Reduce(level1.data() + at, nullptr, count, MPI_FLOAT, MPI_SUM, 0, ranks.comm);
  }
  std::vector<Array<float>> levels;
  if (ranks.rank == 0) levels = density_levels(builder.description(), std::move(level1));
  sink.end(builder.description(), uint32_t(total), std::move(levels));
  const nlohmann::json mine_figures = {
      {"rank", ranks.rank},
      {"voxels", end - first},
      {"records_walked", walked},
      {"records_merged", received},
      {"chords", kept},
      {"exchange_waves", waves.size() - 1},
      {"exchange_s", exchange_s},
      {"merge_s", seconds_since(merge_start)},
      {"peak_rss_bytes", peak_rss_bytes()}};  // the rank's since it started: its job's, mostly
  sink.close(provenance(mine_figures, total, sink.memory_with_density()));
}

}  // namespace linebake
