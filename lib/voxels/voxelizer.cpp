#include "voxels/voxelizer.hpp"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <regex>

#include "core/error.hpp"
#include "core/interrupt.hpp"
#include "core/measure.hpp"
#include "core/spill_file.hpp"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace linebake {
namespace {

using Vec = std::array<double, 3>;

// Squared distances from 8 points (structure of arrays) to a polyline, in float relative to
// the voxel: a statistic, so float precision within a voxel is plenty, and 8 float lanes let the
// compiler vectorise across the points. Each segment's setup is paid once.
struct Samples {
  alignas(32) float x[8], y[8], z[8];
};
void squared_distances_to_path(const Samples& p, const std::vector<Vec>& path,
                               const std::array<int64_t, 3>& cell, float* best) {
  for (int i = 0; i < 8; ++i) best[i] = 3.4e38f;
  const auto consider = [&](float ax, float ay, float az, float dx, float dy, float dz,
                            float inv_dd) {
#if defined(__SSE2__)
    // Two groups of four lanes (SSE2 is part of every x86-64): GCC does not vectorise the
    // clamp and the min below by itself.
    const __m128 vax = _mm_set1_ps(ax), vay = _mm_set1_ps(ay), vaz = _mm_set1_ps(az);
    const __m128 vdx = _mm_set1_ps(dx), vdy = _mm_set1_ps(dy), vdz = _mm_set1_ps(dz);
    const __m128 inv = _mm_set1_ps(inv_dd), zero = _mm_setzero_ps(), one = _mm_set1_ps(1.0f);
    for (int h = 0; h < 8; h += 4) {
      const __m128 wx = _mm_sub_ps(_mm_load_ps(p.x + h), vax);
      const __m128 wy = _mm_sub_ps(_mm_load_ps(p.y + h), vay);
      const __m128 wz = _mm_sub_ps(_mm_load_ps(p.z + h), vaz);
      const __m128 dot =
          _mm_add_ps(_mm_add_ps(_mm_mul_ps(wx, vdx), _mm_mul_ps(wy, vdy)), _mm_mul_ps(wz, vdz));
      const __m128 t = _mm_min_ps(_mm_max_ps(_mm_mul_ps(dot, inv), zero), one);
      const __m128 ex = _mm_sub_ps(wx, _mm_mul_ps(t, vdx));
      const __m128 ey = _mm_sub_ps(wy, _mm_mul_ps(t, vdy));
      const __m128 ez = _mm_sub_ps(wz, _mm_mul_ps(t, vdz));
      const __m128 d2 =
          _mm_add_ps(_mm_add_ps(_mm_mul_ps(ex, ex), _mm_mul_ps(ey, ey)), _mm_mul_ps(ez, ez));
      _mm_store_ps(best + h, _mm_min_ps(_mm_load_ps(best + h), d2));
    }
#else
    for (int s = 0; s < 8; ++s) {
      const float wx = p.x[s] - ax, wy = p.y[s] - ay, wz = p.z[s] - az;
      float t = (wx * dx + wy * dy + wz * dz) * inv_dd;
      t = t < 0 ? 0 : (t > 1 ? 1 : t);
      const float ex = wx - t * dx, ey = wy - t * dy, ez = wz - t * dz;
      const float d2 = ex * ex + ey * ey + ez * ez;
      best[s] = d2 < best[s] ? d2 : best[s];
    }
#endif
  };
  const auto local = [&](const Vec& v, int k) {
    return float(v[size_t(k)] - double(cell[size_t(k)]));
  };
  if (path.size() == 1)
    consider(local(path[0], 0), local(path[0], 1), local(path[0], 2), 0, 0, 0, 0);
  for (size_t i = 0; i + 1 < path.size(); ++i) {
    const float ax = local(path[i], 0), ay = local(path[i], 1), az = local(path[i], 2);
    const float dx = local(path[i + 1], 0) - ax, dy = local(path[i + 1], 1) - ay,
                dz = local(path[i + 1], 2) - az;
    const float dd = dx * dx + dy * dy + dz * dz;
    consider(ax, ay, az, dx, dy, dz, dd > 0 ? 1.0f / dd : 0.0f);
  }
}

// One chord as the walker finds it, in grid coordinates (voxel units from the grid origin).
struct Piece {
  uint64_t voxel = 0;
  std::array<int64_t, 3> cell{};
  Vec entry{}, exit{};
  uint32_t entry_face = kInteriorFace, exit_face = kInteriorFace;
  float entry_attribute = 0, exit_attribute = 0;
  double length = 0;                       // polyline length inside the voxel
  const std::vector<Vec>* path = nullptr;  // entry, the line's points inside, exit
};

// Records are made in line order and along each line, and every later step moves them stably,
// so a voxel's chords end up in the canonical order (line id, then along the line) without a
// sort.
using Record = VoxelRecord;
constexpr uint32_t kFirstOfLine = 1u << 31;

// The voxels one line has reached so far (open addressing; cleared per line in the time its
// entries took to insert).
class VoxelSet {
 public:
  // True when `voxel` was not in the set.
  bool insert(uint32_t voxel) {
    if (2 * (used_.size() + 1) > slots_.size()) grow();
    size_t i = slot_of(voxel);
    while (slots_[i] != kEmpty) {
      if (slots_[i] == voxel) return false;
      i = (i + 1) & (slots_.size() - 1);
    }
    slots_[i] = voxel;
    used_.push_back(uint32_t(i));
    return true;
  }
  void clear() {
    for (uint32_t i : used_) slots_[i] = kEmpty;
    used_.clear();
  }

 private:
  static constexpr uint32_t kEmpty = 0xFFFFFFFFu;  // no voxel has this index
  size_t slot_of(uint32_t voxel) const {
    return size_t((uint64_t(voxel) * 0x9E3779B97F4A7C15ull) >> 32) & (slots_.size() - 1);
  }
  void grow() {
    std::vector<uint32_t> old = std::move(slots_);
    slots_.assign(std::max<size_t>(64, 2 * old.size()), kEmpty);
    used_.clear();
    for (uint32_t v : old)
      if (v != kEmpty) {
        size_t i = slot_of(v);
        while (slots_[i] != kEmpty) i = (i + 1) & (slots_.size() - 1);
        slots_[i] = v;
        used_.push_back(uint32_t(i));
      }
  }
  std::vector<uint32_t> slots_;
  std::vector<uint32_t> used_;
};

__extension__ typedef unsigned __int128 uint128;
// Error sums in fixed point (2^-32 voxel): integer sums do not depend on the order of the
// blocks, so the mean is the same for any batches and thread count.
constexpr double kErrorScale = 4294967296.0;

// A run of lines walked by one task, cut every kSegmentsPerBlock segments.
struct Block {
  size_t first_line = 0, end_line = 0;
  std::vector<Record> records;
  VoxelSet visited;
  double error_max = 0;
  uint128 error_sum = 0;
  uint64_t error_samples = 0;
};

// One batch's records, sorted (stably) by unit: a unit is a range of 2^unit_shift voxels.
// `at(u)` is where unit u begins among the run's records; the records sit in memory or in
// the spill file from `file_offset`. The index covers units from `first_unit` on (a received
// run holds one wave's units, so the ranks' many runs do not each keep all 4,096 and one).
struct Run {
  std::vector<uint32_t> start;  // units first_unit .. first_unit + start.size() - 1
  uint64_t first_unit = 0;
  Array<Record> records;  // uninitialised, huge pages: a run is written once, in full
  bool spilled = false;
  uint64_t file_offset = 0;
  // A run received from the ranks: a piece of one exchange's buffer, shared by its pieces.
  std::shared_ptr<const Array<Record>> received;
  uint64_t received_first = 0;
  const Record* in_memory() const {
    return received ? received->data() + received_first : records.data();
  }
  uint64_t at(uint64_t unit) const {
    if (unit <= first_unit || start.empty()) return 0;
    return start[std::min<uint64_t>(unit - first_unit, start.size() - 1)];
  }
};

// Records received from the ranks of a distributed build, as runs of their own beside the
// builder's (which it still sends from), with their own counts and spill file.
struct Received {
  std::vector<Run> runs;
  std::vector<uint64_t> unit_records;
  uint64_t held_bytes = 0;
  std::unique_ptr<SpillFile> spill;
};

// Per-thread counters for the voxels of one unit.
struct UnitScratch {
  std::vector<uint32_t> n, distinct, cursor, room;
  std::vector<float> density;
  void resize(uint64_t voxels) {
    n.assign(voxels, 0);
    distinct.assign(voxels, 0);
    density.assign(voxels, 0.0f);
    cursor.resize(voxels);
    room.resize(voxels);
  }
};

}  // namespace

struct VoxelStreamBuilder::State {
  VoxelOptions options;
  VoxelMemory memory;
  VoxelGrid grid;  // placement and statistics; no arrays
  int attribute = -1;
  uint64_t lines_seen = 0;
  // Units of the grid, and what the runs hold.
  uint32_t unit_shift = 0;
  uint64_t units = 0;
  std::vector<Run> runs;
  std::vector<uint64_t> unit_records;  // over all runs
  uint64_t held_bytes = 0, peak_held_bytes = 0, spilled_bytes = 0;
  std::unique_ptr<SpillFile> spill;
  // Error statistics over all blocks.
  double error_max = 0;
  uint128 error_sum = 0;
  uint64_t error_samples = 0;
  std::optional<Received> received;  // a distributed build's exchange, while it lasts
  // What the merge found, over every range merged.
  uint64_t voxels_occupied = 0, voxels_overflowed = 0, chords_dropped = 0;
  // Scratch kept between batches, so pages are touched once.
  std::vector<Block> blocks;
  std::vector<uint32_t> block_counts;
  Array<Record> spill_buffer;  // a run on its way to the spill file, reused
  // Chords per voxel, saturating at the cap: the kept chords' count before the merge, so the
  // chords go straight to their place in the output.
  std::vector<uint8_t> counts8;
  std::vector<uint16_t> counts16;

  void place_grid(const LineSetStats& stats);
  template <class Emit>
  void walk(const LineSet& lines, size_t line, std::vector<Vec>& path, Emit&& emit) const;
  void emit(const Piece& piece, uint32_t line, bool first_in_voxel, Block& block) const;
  Vec to_grid(const LineSet& lines, uint64_t point) const {
    Vec g{};
    for (int k = 0; k < 3; ++k)
      g[k] = (double(lines.positions[3 * point + k]) - grid.origin[k]) / grid.voxel_size;
    return g;
  }
  uint8_t to_unorm8(float v) const {
    const float lo = grid.attribute_range[0], span = grid.attribute_range[1] - lo;
    if (!(span > 0) || !std::isfinite(v)) return 0;
    return uint8_t(std::clamp((v - lo) / span, 0.0f, 1.0f) * 255 + 0.5f);
  }
  Record* place_run(Run& run, uint64_t count);
  void keep_run(Run run, uint64_t count);
  // The records of units [u0, u1) of every run: `first[r]` points at run r's record start[u0],
  // in its memory or, for a spilled run, read back into `buffer`.
  void gather(uint64_t u0, uint64_t u1, std::vector<Record>& buffer,
              std::vector<const Record*>& first);
};

void VoxelStreamBuilder::State::place_grid(const LineSetStats& stats) {
  const Bounds& b = stats.bounds;
  if (b.empty) throw Error("voxels: the line set has no finite point");
  std::array<double, 3> extent{};
  for (int k = 0; k < 3; ++k) extent[k] = std::max(double(b.max[k]) - b.min[k], 0.0);
  const double longest = std::max({extent[0], extent[1], extent[2]});
  const double span = longest > 0 ? longest : 1.0;
  // No padding: points on the upper bound belong to the last voxel (cells are clamped).
  for (int k = 0; k < 3; ++k) grid.origin[k] = b.min[k];
  if (options.resolution) {
    const auto& r = *options.resolution;
    double h = 0;
    for (int k = 0; k < 3; ++k) {
      if (r[k] == 0 || r[k] > kMaxGridResolution)
        throw Error("voxels: resolution per axis must be 1.." + std::to_string(kMaxGridResolution));
      h = std::max(h, extent[k] / r[k]);
    }
    grid.voxel_size = float(h > 0 ? h : 1.0);
    grid.resolution = r;
  } else {
    const uint32_t longest_res =
        options.grid ? options.grid : automatic_grid_resolution(stats.segments);
    if (longest_res == 0 || longest_res > kMaxGridResolution)
      throw Error("voxels: grid resolution must be 1.." + std::to_string(kMaxGridResolution));
    grid.voxel_size = float(span / longest_res);
    for (int k = 0; k < 3; ++k)
      grid.resolution[k] = std::clamp<uint32_t>(
          uint32_t(std::ceil(extent[k] / grid.voxel_size - 1e-6)), 1, longest_res);
  }
}

// Walks a line through the grid (Amanatides-Woo per segment) and emits one piece per stay in
// a voxel: from where the line entered (a face, or its first point) to where it left (a face,
// or its last point). Pieces shorter than 1e-9 voxels (a line crossing an edge or corner) are
// not emitted.
template <class Emit>
void VoxelStreamBuilder::State::walk(const LineSet& lines, size_t line, std::vector<Vec>& path,
                                     Emit&& emit_piece) const {
  const uint64_t first = lines.line_offsets[line], last = lines.line_offsets[line + 1];
  if (last - first < 2) return;
  const std::vector<float>* values =
      attribute >= 0 ? &lines.attributes[size_t(attribute)].values : nullptr;
  const auto attribute_at = [&](uint64_t point) { return values ? (*values)[point] : 0.0f; };
  const auto& res = grid.resolution;
  Piece piece;
  piece.path = &path;
  const Vec start = to_grid(lines, first);
  for (int k = 0; k < 3; ++k)
    piece.cell[k] = std::clamp<int64_t>(int64_t(std::floor(start[k])), 0, int64_t(res[k]) - 1);
  piece.entry = start;
  piece.entry_face = kInteriorFace;
  piece.entry_attribute = attribute_at(first);
  path.assign(1, start);
  piece.length = 0;
  const auto finish = [&](const Vec& exit, uint32_t exit_face, float exit_attribute) {
    piece.exit = exit;
    piece.exit_face = exit_face;
    piece.exit_attribute = exit_attribute;
    if (piece.length > 1e-9) {
      piece.voxel =
          grid.index(uint32_t(piece.cell[0]), uint32_t(piece.cell[1]), uint32_t(piece.cell[2]));
      emit_piece(piece);
    }
  };
  const auto extend = [&](const Vec& p) {
    const Vec& q = path.back();
    piece.length += std::sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                              (p[2] - q[2]) * (p[2] - q[2]));
    path.push_back(p);
  };
  Vec a = start;
  for (uint64_t i = first; i + 1 < last; ++i) {
    const Vec b = to_grid(lines, i + 1);
    const Vec d{b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const float attribute_a = attribute_at(i), attribute_b = attribute_at(i + 1);
    double t = 0;
    for (int guard = 0; guard < 1 << 24; ++guard) {
      double t_next = 1;
      int axis = -1;
      for (int k = 0; k < 3; ++k) {
        if (d[k] == 0) continue;
        const double boundary = double(piece.cell[k] + (d[k] > 0 ? 1 : 0));
        const double tk = std::max((boundary - a[k]) / d[k], t);
        if (tk < t_next) t_next = tk, axis = k;
      }
      if (axis < 0) break;
      const int64_t step = d[axis] > 0 ? 1 : -1;
      const int64_t next = piece.cell[axis] + step;
      if (next < 0 || next >= int64_t(res[axis])) break;  // rounding at the grid's edge
      Vec x{a[0] + t_next * d[0], a[1] + t_next * d[1], a[2] + t_next * d[2]};
      x[axis] = double(piece.cell[axis] + (step > 0 ? 1 : 0));  // exactly on the face
      const float attribute_x = attribute_a + float(t_next) * (attribute_b - attribute_a);
      extend(x);
      finish(x, uint32_t(2 * axis + (step > 0 ? 1 : 0)), attribute_x);
      piece.cell[axis] = next;
      piece.entry = x;
      piece.entry_face = uint32_t(2 * axis + (step > 0 ? 0 : 1));
      piece.entry_attribute = attribute_x;
      path.assign(1, x);
      piece.length = 0;
      t = t_next;
    }
    extend(b);
    a = b;
  }
  finish(a, kInteriorFace, attribute_at(last - 1));
}

// Quantises and packs one chord, and measures it: the decoded chord sampled at five points
// against the polyline inside the voxel (quantisation and straightening error together).
void VoxelStreamBuilder::State::emit(const Piece& p, uint32_t line, bool first_in_voxel,
                                     Block& block) const {
  const uint32_t q = grid.quantization;
  std::array<float, 3> entry{}, exit{};
  for (int k = 0; k < 3; ++k) {
    entry[k] = float(std::clamp(p.entry[k] - double(p.cell[k]), 0.0, 1.0));
    exit[k] = float(std::clamp(p.exit[k] - double(p.cell[k]), 0.0, 1.0));
  }
  const ChordEnd start = quantise_end(entry, p.entry_face, q);
  const ChordEnd end = quantise_end(exit, p.exit_face, q);
  const uint8_t a0 = to_unorm8(p.entry_attribute), a1 = to_unorm8(p.exit_attribute);
  const auto words = pack_chord(start, end, line, a0, a1, q);
  const float weight = float(p.length) * (attribute >= 0 ? (float(a0) + float(a1)) / 510.0f : 1.0f);
  block.records.push_back(
      {uint32_t(p.voxel), words[0], words[1] | (first_in_voxel ? kFirstOfLine : 0), weight});

  const std::array<float, 3> s = decode_end(start, q), e = decode_end(end, q);
  Samples samples;
  for (int i = 0; i < 8; ++i) {  // 5 samples, padded with copies of the last
    const float f = float(std::min(i, 4)) / 4.0f;
    samples.x[i] = s[0] + (e[0] - s[0]) * f;
    samples.y[i] = s[1] + (e[1] - s[1]) * f;
    samples.z[i] = s[2] + (e[2] - s[2]) * f;
  }
  alignas(16) float d2[8];
  squared_distances_to_path(samples, *p.path, p.cell, d2);
  double largest = block.error_max;
  uint128 sum = block.error_sum;
  for (int i = 0; i < 5; ++i) {
    const double d = std::sqrt(double(std::max(d2[i], 0.0f)));
    largest = std::max(largest, d);
    sum += uint128(uint64_t(d * kErrorScale + 0.5));
  }
  block.error_max = largest;
  block.error_sum = sum;
  block.error_samples += 5;
}

// A run stays in memory (it owns its records) while the held runs fit the budget's share; a run
// that would pass it goes to the spill file from a reused buffer. Runs in memory and in the file
// mix freely: the merge reads each where it is. Returns where the run's records are to be put.
Record* VoxelStreamBuilder::State::place_run(Run& run, uint64_t count) {
  const uint64_t bytes = count * sizeof(Record);
  const bool past_share = held_bytes + bytes > memory.records_bytes;
  const bool past_resident =
      memory.resident_limit > 0 && current_rss_bytes() + bytes > memory.resident_limit;
  if ((past_share || past_resident) && !memory.spill_near.empty()) {
    if (!spill) spill = std::make_unique<SpillFile>(memory.spill_near, "voxels-spill");
    run.spilled = true;
    if (spill_buffer.size() < count) spill_buffer = Array<Record>(count);
    return spill_buffer.data();
  }
  run.records = Array<Record>(count);
  held_bytes += bytes;
  peak_held_bytes = std::max(peak_held_bytes, held_bytes);
  return run.records.data();
}

void VoxelStreamBuilder::State::keep_run(Run run, uint64_t count) {
  if (run.spilled) run.file_offset = spill->append(spill_buffer.data(), count * sizeof(Record));
  runs.push_back(std::move(run));
}

void VoxelStreamBuilder::State::gather(uint64_t u0, uint64_t u1, std::vector<Record>& buffer,
                                       std::vector<const Record*>& first) {
  uint64_t spilled = 0;
  for (const Run& run : runs)
    if (run.spilled) spilled += run.at(u1) - run.at(u0);
  buffer.resize(spilled);
  first.resize(runs.size());
  uint64_t at = 0;
  for (size_t r = 0; r < runs.size(); ++r) {
    const Run& run = runs[r];
    const uint64_t begin = run.at(u0), count = run.at(u1) - begin;
    if (!run.spilled) {
      first[r] = run.in_memory() + begin;
      continue;
    }
    first[r] = buffer.data() + at;
    if (count)
      spill->read(run.file_offset + begin * sizeof(Record), buffer.data() + at,
                  count * sizeof(Record));
    at += count;
  }
}

VoxelStreamBuilder::VoxelStreamBuilder(const LineSet& header, const LineSetStats& stats,
                                       const VoxelOptions& options, VoxelMemory memory)
    : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.options = options;
  s.memory = std::move(memory);
  const uint32_t q = options.quantization;
  if (q != 16 && q != 32 && q != 64) throw Error("voxels: quantisation must be 16, 32 or 64");
  if (options.max_chords_per_voxel == 0 || options.max_chords_per_voxel > 65535)
    throw Error("voxels: the chord cap per voxel must be 1..65535");
  s.grid.quantization = q;
  s.grid.max_chords_per_voxel = options.max_chords_per_voxel;
  s.grid.segments = stats.segments;
  if (options.attribute != "none") {
    int index = -1;
    if (options.attribute.empty()) {
      index = header.attributes.empty() ? -1 : 0;
    } else {
      for (size_t i = 0; i < header.attributes.size(); ++i)
        if (header.attributes[i].name == options.attribute) index = int(i);
      if (index < 0) throw_unknown_attribute(header, "--voxel-attribute", options.attribute, true);
    }
    if (index >= 0) {
      s.attribute = index;
      s.grid.attribute = header.attributes[size_t(index)].name;
      if (options.attribute_range) {
        s.grid.attribute_range = *options.attribute_range;
      } else {
        const ValueRange* r = stats.attribute_range(s.grid.attribute);
        s.grid.attribute_range = {r ? r->min : 0.0f, r ? r->max : 0.0f};
      }
    }
  }
  s.place_grid(stats);
  const uint64_t voxels = s.grid.voxel_count();
  if (voxels >= 0xFFFFFFFFull) {
    const auto& r = s.grid.resolution;
    throw BudgetExceeded("voxels: the grid is " + std::to_string(r[0]) + " x " +
                         std::to_string(r[1]) + " x " + std::to_string(r[2]) + " = " +
                         std::to_string(voxels) +
                         " voxels, more than the 2^32 - 1 a grid may hold; use a coarser --grid");
  }
  if (stats.lines >= 0xFFFFFFFFull) throw Error("voxels: more than 2^32 - 1 lines");
  // At most 4096 units: small enough per-run tables, fine enough to split the merge.
  s.unit_shift = uint32_t(std::max(0, int(std::bit_width(voxels - 1)) - 12));
  s.units = ((voxels - 1) >> s.unit_shift) + 1;
  s.unit_records.assign(s.units, 0);
}

VoxelStreamBuilder::~VoxelStreamBuilder() = default;

const VoxelGrid& VoxelStreamBuilder::description() const {
  return state_->grid;
}
uint64_t VoxelStreamBuilder::fixed_bytes() const {
  const uint64_t voxels = state_->grid.voxel_count();
  return voxels * (state_->grid.max_chords_per_voxel > 255 ? 2 : 1) + voxels / 8 * 4 * 8 / 7 +
         (uint64_t{2} << 20);
}
uint64_t VoxelStreamBuilder::run_index_bytes() const {
  return (state_->units + 1) * sizeof(uint32_t) + sizeof(Run);
}
uint64_t VoxelStreamBuilder::received_index_bytes(int ranks) const {
  // A wave per unit at the most, each rank's piece of it a run spanning the wave's units and one
  // more entry: over the waves, every unit once and a run's struct and entry per wave.
  const uint64_t units = state_->units;
  return uint64_t(std::max(ranks, 1)) *
         (units * sizeof(uint32_t) + units * (sizeof(Run) + 2 * sizeof(uint32_t)));
}
uint64_t VoxelStreamBuilder::spilled_bytes() const {
  return state_->spilled_bytes + (state_->spill ? state_->spill->size() : 0);
}
uint64_t VoxelStreamBuilder::peak_record_bytes() const {
  return state_->peak_held_bytes;
}

// 1. Walk: blocks of lines in parallel, each collecting its chords and error figures.
// 2. A stable counting sort of the batch's records by unit, scattered block by block in
//    parallel, makes the batch's run.
void VoxelStreamBuilder::add(const LineSet& batch) {
  State& s = *state_;
  const size_t line_count = batch.line_count();
  if (line_count == 0) return;
  // The per-voxel counts are allocated by the first batch, not by the constructor: a builder made
  // only to learn the grid's placement (estimates, budgets) touches no per-voxel memory.
  if (s.counts8.empty() && s.counts16.empty()) {
    if (s.grid.max_chords_per_voxel > 255)
      s.counts16.assign(s.grid.voxel_count(), 0);
    else
      s.counts8.assign(s.grid.voxel_count(), 0);
  }
  constexpr uint64_t kSegmentsPerBlock = 1 << 16;
  size_t used = 0;
  for (size_t first = 0; first < line_count; ++used) {
    size_t end = first;
    const uint64_t begin_point = batch.line_offsets[first];
    while (end < line_count &&
           (end == first || batch.line_offsets[end] - begin_point < kSegmentsPerBlock))
      ++end;
    if (s.blocks.size() <= used) s.blocks.emplace_back();
    Block& block = s.blocks[used];
    block.first_line = first;
    block.end_line = end;
    block.records.clear();
    block.records.reserve(2 * (batch.line_offsets[end] - begin_point));
    block.error_max = 0;
    block.error_sum = 0;
    block.error_samples = 0;
    first = end;
  }
  const uint64_t base_line = s.lines_seen;
  tbb::parallel_for(size_t{0}, used, [&](size_t b) {
    Block& block = s.blocks[b];
    std::vector<Vec> path;
    for (size_t l = block.first_line; l != block.end_line; ++l) {
      block.visited.clear();
      s.walk(batch, l, path, [&](const Piece& p) {
        s.emit(p, uint32_t(base_line + l), block.visited.insert(uint32_t(p.voxel)), block);
      });
    }
  });
  s.lines_seen += line_count;

  const uint64_t units = s.units;
  s.block_counts.assign(used * (units + 1), 0);
  tbb::parallel_for(size_t{0}, used, [&](size_t b) {
    uint32_t* counts = s.block_counts.data() + b * (units + 1);
    for (const Record& r : s.blocks[b].records) ++counts[r.voxel >> s.unit_shift];
  });
  Run run;
  run.start.assign(units + 1, 0);
  uint64_t total = 0;
  // Turn the counts into each block's first position per unit: unit-major, then block order.
  for (uint64_t u = 0; u < units; ++u) {
    run.start[u] = uint32_t(total);
    for (size_t b = 0; b < used; ++b) {
      uint32_t& c = s.block_counts[b * (units + 1) + u];
      const uint32_t n = c;
      c = uint32_t(total);
      total += n;
    }
    s.unit_records[u] += total - run.start[u];
  }
  if (total > 0xFFFFFFFFull) throw Error("voxels: more than 2^32 chords in one batch");
  run.start[units] = uint32_t(total);
  Record* const sorted = s.place_run(run, total);
  tbb::parallel_for(size_t{0}, used, [&](size_t b) {
    uint32_t* cursor = s.block_counts.data() + b * (units + 1);
    for (const Record& r : s.blocks[b].records) sorted[cursor[r.voxel >> s.unit_shift]++] = r;
  });
  // Count per voxel, unit by unit in parallel (units own disjoint voxels).
  const uint32_t cap = s.grid.max_chords_per_voxel;
  tbb::parallel_for(uint64_t{0}, units, [&](uint64_t u) {
    const Record* first = sorted + run.start[u];
    const Record* last = sorted + run.start[u + 1];
    if (!s.counts16.empty()) {
      for (const Record* r = first; r != last; ++r)
        if (s.counts16[r->voxel] < cap) ++s.counts16[r->voxel];
    } else {
      for (const Record* r = first; r != last; ++r)
        if (s.counts8[r->voxel] < cap) ++s.counts8[r->voxel];
    }
  });
  for (size_t b = 0; b < used; ++b) {
    const Block& block = s.blocks[b];
    s.error_max = std::max(s.error_max, block.error_max);
    s.error_sum += block.error_sum;
    s.error_samples += block.error_samples;
  }
  s.keep_run(std::move(run), total);
}

uint64_t VoxelStreamBuilder::kept_chords(uint64_t v0, uint64_t v1) const {
  const State& s = *state_;
  if (s.counts8.empty() && s.counts16.empty()) return 0;  // no batch came
  return tbb::parallel_reduce(
      tbb::blocked_range<uint64_t>(v0, std::max(v0, v1), uint64_t{1} << 16), uint64_t{0},
      [&](const tbb::blocked_range<uint64_t>& range, uint64_t sum) {
        for (uint64_t v = range.begin(); v != range.end(); ++v)
          sum += s.counts16.empty() ? s.counts8[v] : s.counts16[v];
        return sum;
      },
      std::plus<uint64_t>());
}

// 3. Merge, one range of whole units at a time: per voxel the chord count, density, distinct
//    lines and the cap; then, once every unit of the range knows how many chords it keeps, the
//    offsets and the chords themselves. Units run in parallel; each reads its records run by
//    run, so a voxel's chords stay in line order. Units at the ends of [first, end) are cut to
//    it (a distributed build splits the grid at z layers, not at units).
uint64_t VoxelStreamBuilder::merge(VoxelSink& sink, uint64_t first, uint64_t end,
                                   uint64_t chords_start, Array<float>& level1,
                                   const ProgressFn& progress) {
  State& s = *state_;
  const VoxelGrid& grid = s.grid;
  s.blocks.clear();
  s.blocks.shrink_to_fit();
  const uint64_t voxels = grid.voxel_count();
  end = std::min(end, voxels);
  if (first >= end) return 0;
  const uint64_t unit_span = uint64_t(1) << s.unit_shift;
  const uint64_t first_unit = first >> s.unit_shift, end_unit = ((end - 1) >> s.unit_shift) + 1;
  const auto lo = [&](uint64_t u) { return std::max(u << s.unit_shift, first); };
  const auto hi = [&](uint64_t u) { return std::min((u + 1) << s.unit_shift, end); };
  const uint32_t cap = grid.max_chords_per_voxel;
  // Per record: itself and at most one kept chord; per voxel: the output arrays.
  constexpr uint64_t kRecordCost = sizeof(Record) + 8, kVoxelCost = 4 + 1 + 4 + 16;
  // Large ranges gain nothing (the units run in parallel either way) and touch fresh pages.
  const uint64_t budget = std::clamp<uint64_t>(s.memory.merge_bytes, 1, uint64_t{256} << 20);
  const std::array<uint32_t, 3> coarse = grid.level_resolution(1);
  std::vector<Record> records;
  std::vector<const Record*> first_record;
  std::vector<uint32_t> offsets, chords;
  std::vector<uint8_t> line_counts;
  std::vector<float> density;
  tbb::enumerable_thread_specific<UnitScratch> scratch;
  struct UnitStats {
    uint64_t kept = 0, occupied = 0, overflowed = 0, dropped = 0;
  };
  std::vector<UnitStats> unit_stats;
  uint64_t merged = 0;
  for (uint64_t u0 = first_unit; u0 < end_unit;) {
    throw_if_interrupted();
    uint64_t u1 = u0, cost = 0;
    while (u1 < end_unit) {
      const uint64_t c =
          s.unit_records[u1] * (s.spill ? kRecordCost : kRecordCost - sizeof(Record)) +
          (hi(u1) - lo(u1)) * kVoxelCost;
      if (u1 > u0 && cost + c > budget) break;
      cost += c;
      ++u1;
    }
    const uint64_t v0 = lo(u0), v1 = hi(u1 - 1);
    if (cost > 2 * budget)
      throw BudgetExceeded(
          "voxels: " + std::to_string(s.unit_records[u0]) + " chords fall into voxels " +
          std::to_string(v0) + ".." + std::to_string(v1) +
          ", more than the memory budget leaves for merging (" + std::to_string(budget >> 20) +
          " MiB); use a coarser grid or a larger --memory-budget");
    s.gather(u0, u1, records, first_record);
    offsets.resize(v1 - v0);
    line_counts.resize(v1 - v0);
    density.resize(v1 - v0);
    unit_stats.assign(u1 - u0, {});
    const auto for_each_record = [&](uint64_t u, auto&& body) {
      const uint64_t a = lo(u), b = hi(u);
      for (size_t r = 0; r < s.runs.size(); ++r) {
        const Run& run = s.runs[r];
        const Record* p = first_record[r] + (run.at(u) - run.at(u0));
        const Record* last = p + (run.at(u + 1) - run.at(u));
        for (; p != last; ++p)
          if (p->voxel >= a && p->voxel < b) body(*p);
      }
    };
    tbb::parallel_for(u0, u1, [&](uint64_t u) {
      const uint64_t first_voxel = u << s.unit_shift;
      const uint64_t span = std::min(unit_span, voxels - first_voxel);
      UnitScratch& t = scratch.local();
      t.resize(span);
      for_each_record(u, [&](const Record& r) {
        const uint64_t v = r.voxel - first_voxel;
        ++t.n[v];
        t.density[v] += r.weight;
        t.distinct[v] += r.word1 >> 31;
      });
      UnitStats& us = unit_stats[u - u0];
      for (uint64_t v = lo(u) - first_voxel; v < hi(u) - first_voxel; ++v) {
        const uint64_t at = first_voxel + v - v0;
        density[at] = t.density[v];
        line_counts[at] = uint8_t(std::min<uint32_t>(t.distinct[v], 255));
        const uint32_t kept = std::min(t.n[v], cap);
        offsets[at] = kept;  // a count for now; the start once every unit is counted
        us.kept += kept;
        us.occupied += t.n[v] > 0;
        us.overflowed += t.n[v] > cap;
        us.dropped += t.n[v] - kept;
      }
    });
    std::vector<uint64_t> kept_start(u1 - u0 + 1, 0);
    for (uint64_t k = 0; k < u1 - u0; ++k) {
      kept_start[k + 1] = kept_start[k] + unit_stats[k].kept;
      s.voxels_occupied += unit_stats[k].occupied;
      s.voxels_overflowed += unit_stats[k].overflowed;
      s.chords_dropped += unit_stats[k].dropped;
    }
    const uint64_t range_chords = kept_start.back();
    const uint64_t chords_before = chords_start + merged;
    if (chords_before + range_chords > 0xFFFFFFFFull)
      throw Error("voxels: more than 2^32 chords; use a coarser grid");
    chords.resize(2 * range_chords);
    tbb::parallel_for(u0, u1, [&](uint64_t u) {
      const uint64_t first_voxel = u << s.unit_shift;
      const uint64_t span = std::min(unit_span, voxels - first_voxel);
      UnitScratch& t = scratch.local();
      t.resize(span);
      // Per voxel: where its next kept chord goes and how many more it keeps.
      uint64_t running = kept_start[u - u0];
      for (uint64_t v = lo(u) - first_voxel; v < hi(u) - first_voxel; ++v) {
        uint32_t& o = offsets[first_voxel + v - v0];
        t.room[v] = o;
        t.cursor[v] = uint32_t(running);
        o = uint32_t(chords_before + running);
        running += t.room[v];
      }
      for_each_record(u, [&](const Record& r) {
        const uint64_t v = r.voxel - first_voxel;
        if (t.room[v] == 0) return;  // over the cap: the first chords in canonical order stay
        --t.room[v];
        const uint64_t at = 2 * uint64_t(t.cursor[v]++);
        chords[at] = r.word0;
        chords[at + 1] = r.word1 & ~kFirstOfLine;
      });
    });
    sink.voxels(v0, v1 - v0, offsets.data(), line_counts.data(), density.data(), chords.data(),
                range_chords);
    // Level 1 of the density mips, summed in voxel order: for every coarse voxel the same
    // additions in the same order as the 2x2x2 loop of the levels above it.
    const auto& r = grid.resolution;
    uint64_t x = v0 % r[0], y = (v0 / r[0]) % r[1], z = v0 / (uint64_t(r[0]) * r[1]);
    for (uint64_t v = v0; v < v1; ++v) {
      level1[((z / 2) * coarse[1] + y / 2) * coarse[0] + x / 2] += density[v - v0];
      if (++x == r[0]) {
        x = 0;
        if (++y == r[1]) y = 0, ++z;
      }
    }
    merged += range_chords;
    if (progress) progress(v1 - first, end - first);
    u0 = u1;
  }
  return merged;
}

Array<float> zero_level1_sums(const VoxelGrid& grid) {
  const std::array<uint32_t, 3> coarse = grid.level_resolution(1);
  Array<float> level1(static_cast<uint64_t>(coarse[0]) * coarse[1] * coarse[2]);
  std::fill(level1.begin(), level1.end(), 0.0f);
  return level1;
}

std::vector<Array<float>> density_levels(const VoxelGrid& grid, Array<float> level1) {
  for (float& d : level1) d /= 8;
  std::vector<Array<float>> levels;
  const bool single = grid.resolution[0] == 1 && grid.resolution[1] == 1 && grid.resolution[2] == 1;
  if (!single) levels.push_back(std::move(level1));
  while (!levels.empty()) {
    const size_t level = levels.size();  // levels[level - 1] is mip level `level`
    const auto fine = grid.level_resolution(level), next = grid.level_resolution(level + 1);
    if (fine[0] == 1 && fine[1] == 1 && fine[2] == 1) break;
    Array<float> out(static_cast<uint64_t>(next[0]) * next[1] * next[2]);
    const Array<float>& src = levels.back();
    tbb::parallel_for(uint32_t{0}, next[2], [&](uint32_t z) {
      for (uint32_t y = 0; y < next[1]; ++y)
        for (uint32_t x = 0; x < next[0]; ++x) {
          float sum = 0;
          for (uint32_t dz = 0; dz < 2; ++dz)
            for (uint32_t dy = 0; dy < 2; ++dy)
              for (uint32_t dx = 0; dx < 2; ++dx) {
                const uint32_t fx = 2 * x + dx, fy = 2 * y + dy, fz = 2 * z + dz;
                if (fx < fine[0] && fy < fine[1] && fz < fine[2])
                  sum += src[(uint64_t(fz) * fine[1] + fy) * fine[0] + fx];
              }
          out[(uint64_t(z) * next[1] + y) * next[0] + x] = sum / 8;
        }
    });
    levels.push_back(std::move(out));
  }
  return levels;
}

void VoxelTallies::add(const VoxelTallies& o) {
  voxels_occupied += o.voxels_occupied;
  voxels_overflowed += o.voxels_overflowed;
  chords_dropped += o.chords_dropped;
  error_max = std::max(error_max, o.error_max);
  const uint64_t low = error_sum_low + o.error_sum_low;
  error_sum_high += o.error_sum_high + (low < error_sum_low ? 1 : 0);
  error_sum_low = low;
  error_samples += o.error_samples;
}

VoxelTallies VoxelStreamBuilder::tallies() const {
  const State& s = *state_;
  VoxelTallies t;
  t.voxels_occupied = s.voxels_occupied;
  t.voxels_overflowed = s.voxels_overflowed;
  t.chords_dropped = s.chords_dropped;
  t.error_max = s.error_max;
  t.error_sum_low = uint64_t(s.error_sum);
  t.error_sum_high = uint64_t(s.error_sum >> 64);
  t.error_samples = s.error_samples;
  return t;
}

void VoxelStreamBuilder::set_statistics(const VoxelTallies& t) {
  VoxelGrid& grid = state_->grid;
  grid.voxels_occupied = t.voxels_occupied;
  grid.voxels_overflowed = t.voxels_overflowed;
  grid.chords_dropped = t.chords_dropped;
  grid.max_error = t.error_max;
  const uint128 sum = uint128(t.error_sum_high) << 64 | t.error_sum_low;
  grid.mean_error = t.error_samples ? double(sum) / kErrorScale / double(t.error_samples) : 0.0;
}

void VoxelStreamBuilder::finish(VoxelSink& sink, const ProgressFn& progress) {
  State& s = *state_;
  const uint64_t voxels = s.grid.voxel_count();
  const uint64_t kept_total = kept_chords(0, voxels);
  std::vector<uint8_t>().swap(s.counts8);
  std::vector<uint16_t>().swap(s.counts16);
  if (kept_total > 0xFFFFFFFFull) throw Error("voxels: more than 2^32 chords; use a coarser grid");
  sink.begin(s.grid, kept_total);
  Array<float> level1 = zero_level1_sums(s.grid);
  const uint64_t chords = merge(sink, 0, voxels, 0, level1, progress);
  s.runs.clear();
  if (s.spill) s.spilled_bytes += s.spill->size();
  s.spill.reset();
  set_statistics(tallies());
  sink.end(s.grid, uint32_t(chords), density_levels(s.grid, std::move(level1)));
}

void VoxelStreamBuilder::start_at_line(uint64_t line) {
  if (!state_->runs.empty()) throw Error("voxels: start_at_line after the first batch");
  state_->lines_seen = line;
}

const std::vector<uint64_t>& VoxelStreamBuilder::unit_records() const {
  return state_->unit_records;
}

uint64_t VoxelStreamBuilder::unit_voxels() const {
  return uint64_t(1) << state_->unit_shift;
}

void VoxelStreamBuilder::append_records(uint64_t v0, uint64_t v1, std::vector<VoxelRecord>& out) {
  State& s = *state_;
  v1 = std::min(v1, s.grid.voxel_count());
  if (v0 >= v1 || s.runs.empty()) return;
  const uint64_t first_unit = v0 >> s.unit_shift, end_unit = ((v1 - 1) >> s.unit_shift) + 1;
  std::vector<Record> buffer;
  std::vector<const Record*> first;
  // A few units at a time: spilled records are read back that many at once.
  constexpr uint64_t kUnitsAtOnce = 64;
  for (uint64_t u0 = first_unit; u0 < end_unit; u0 += kUnitsAtOnce) {
    const uint64_t u1 = std::min(end_unit, u0 + kUnitsAtOnce);
    s.gather(u0, u1, buffer, first);
    for (uint64_t u = u0; u < u1; ++u)
      for (size_t r = 0; r < s.runs.size(); ++r) {
        const Run& run = s.runs[r];
        const Record* p = first[r] + (run.at(u) - run.at(u0));
        const Record* last = p + (run.at(u + 1) - run.at(u));
        for (; p != last; ++p)
          if (p->voxel >= v0 && p->voxel < v1) out.push_back(*p);
      }
  }
}

void VoxelStreamBuilder::receive_records(Array<VoxelRecord> buffer,
                                         const std::vector<uint64_t>& counts) {
  State& s = *state_;
  if (!s.received) {
    // The per-voxel counts from here on are the received records' (this rank's own were only
    // needed for its walk).
    s.received.emplace();
    s.received->unit_records.assign(s.units, 0);
    if (s.grid.max_chords_per_voxel > 255)
      s.counts16.assign(s.grid.voxel_count(), 0);
    else
      s.counts8.assign(s.grid.voxel_count(), 0);
  }
  Received& in = *s.received;
  const uint32_t cap = s.grid.max_chords_per_voxel;
  uint64_t total = 0;
  for (const uint64_t count : counts) total += count;
  if (total > buffer.size()) throw Error("voxels: received counts exceed the records");
  // In memory (the buffer itself, shared by the ranks' runs) within the same share of the budget
  // as the builder's own records, else spilled.
  const bool spill = in.held_bytes + total * sizeof(Record) > s.memory.records_bytes &&
                     !s.memory.spill_near.empty();
  const auto shared = std::make_shared<const Array<Record>>(std::move(buffer));
  uint64_t at = 0;
  for (const uint64_t count : counts) {
    if (count > 0xFFFFFFFFull) throw Error("voxels: more than 2^32 records from one rank");
    if (count == 0) continue;
    const Record* records = shared->data() + at;
    // The run's index spans the units from its first record's to its last's (records arrive
    // sorted by unit), not the grid's every unit.
    Run run;
    // Sorted by unit, not by voxel within a unit (a unit's records come run by run, in line
    // order): the first and last records' units bound the run.
    const uint64_t first_voxel = records[0].voxel, last_voxel = records[count - 1].voxel;
    if (first_voxel >= s.grid.voxel_count() || last_voxel >= s.grid.voxel_count() ||
        (last_voxel >> s.unit_shift) < (first_voxel >> s.unit_shift))
      throw Error("voxels: received records out of order or outside the grid");
    run.first_unit = first_voxel >> s.unit_shift;
    const uint64_t span = (last_voxel >> s.unit_shift) - run.first_unit + 1;
    run.start.assign(span + 1, 0);
    uint64_t previous_unit = run.first_unit;
    for (uint64_t i = 0; i < count; ++i) {
      const uint32_t v = records[i].voxel;
      const uint64_t unit = v >> s.unit_shift;
      if (v >= s.grid.voxel_count() || unit < previous_unit || unit - run.first_unit >= span)
        throw Error("voxels: received records out of order or outside the grid");
      previous_unit = unit;
      ++run.start[unit - run.first_unit + 1];
      if (!s.counts16.empty()) {
        if (s.counts16[v] < cap) ++s.counts16[v];
      } else if (s.counts8[v] < cap) {
        ++s.counts8[v];
      }
    }
    for (uint64_t u = 0; u < span; ++u) {
      in.unit_records[run.first_unit + u] += run.start[u + 1];
      run.start[u + 1] += run.start[u];
    }
    if (spill) {
      if (!in.spill) in.spill = std::make_unique<SpillFile>(s.memory.spill_near, "voxels-received");
      run.spilled = true;
      run.file_offset = in.spill->append(records, count * sizeof(Record));
    } else {
      run.received = shared;
      run.received_first = at;
    }
    in.runs.push_back(std::move(run));
    at += count;
  }
  if (!spill) in.held_bytes += shared->bytes();
}

void VoxelStreamBuilder::adopt_received() {
  State& s = *state_;
  if (!s.received) receive_records(Array<VoxelRecord>(), {});
  Received& in = *s.received;
  if (s.spill) s.spilled_bytes += s.spill->size();
  s.runs = std::move(in.runs);
  s.unit_records = std::move(in.unit_records);
  s.spill = std::move(in.spill);
  s.held_bytes = in.held_bytes;
  s.peak_held_bytes = std::max(s.peak_held_bytes, s.held_bytes);
  s.received.reset();
}

namespace {

// Collects a streamed build into a VoxelGrid's own arrays.
class GridSink : public VoxelSink {
 public:
  explicit GridSink(VoxelGrid& grid) : grid_(grid) {}
  void begin(const VoxelGrid& grid, uint64_t chord_count) override {
    grid_ = grid;
    const uint64_t voxels = grid.voxel_count();
    grid_.offsets = Array<uint32_t>(voxels + 1);
    grid_.line_counts = Array<uint8_t>(voxels);
    grid_.density.clear();
    grid_.density.emplace_back(voxels);
    chords_ = Array<uint32_t>(2 * chord_count);
    written_ = 0;
  }
  void voxels(uint64_t first, uint64_t count, const uint32_t* offsets, const uint8_t* line_counts,
              const float* density, const uint32_t* chords, uint64_t chord_count) override {
    std::copy_n(offsets, count, grid_.offsets.data() + first);
    std::copy_n(line_counts, count, grid_.line_counts.data() + first);
    std::copy_n(density, count, grid_.density[0].data() + first);
    std::copy_n(chords, 2 * chord_count, chords_.data() + written_);
    written_ += 2 * chord_count;
  }
  void end(const VoxelGrid& grid, uint32_t chord_count, std::vector<Array<float>> coarse) override {
    Array<uint32_t> offsets = std::move(grid_.offsets);
    Array<uint8_t> line_counts = std::move(grid_.line_counts);
    std::vector<Array<float>> density = std::move(grid_.density);
    grid_ = grid;
    grid_.offsets = std::move(offsets);
    grid_.offsets[grid.voxel_count()] = chord_count;
    grid_.line_counts = std::move(line_counts);
    grid_.density = std::move(density);
    for (Array<float>& level : coarse) grid_.density.push_back(std::move(level));
    grid_.chords = std::move(chords_);
  }

 private:
  VoxelGrid& grid_;
  Array<uint32_t> chords_;
  uint64_t written_ = 0;
};

}  // namespace

uint32_t automatic_grid_resolution(uint64_t segments) {
  const double root = std::cbrt(double(std::max<uint64_t>(segments, 1)));
  const uint64_t pow2 = std::bit_ceil(uint64_t(std::ceil(root)));
  return uint32_t(std::clamp<uint64_t>(pow2 * 2, 64, 512));
}

void parse_grid(const std::string& text, VoxelOptions& options) {
  static const std::regex single(R"(\d+)"), triple(R"((\d+)x(\d+)x(\d+))");
  // Each number within what the grid may have along an axis, said in plain numbers (a usage
  // error, as any option out of range): 0 had meant auto, and past 4 digits the form was refused.
  const auto axis = [&](const std::string& digits) {
    if (digits.size() > 4 || std::stoul(digits) == 0 || std::stoul(digits) > kMaxGridResolution)
      throw UsageError("--grid: " + digits + " is outside 1.." +
                       std::to_string(kMaxGridResolution) + " (auto: sized from the data)");
    return uint32_t(std::stoul(digits));
  };
  std::smatch m;
  if (text == "auto") {
    options.grid = 0;
    options.resolution.reset();
  } else if (std::regex_match(text, single)) {
    options.grid = axis(text);
    options.resolution.reset();
  } else if (std::regex_match(text, m, triple)) {
    options.resolution = std::array<uint32_t, 3>{axis(m[1]), axis(m[2]), axis(m[3])};
    // Known from the option alone (N alone takes the data's aspect): a usage error, as the
    // grid's own limit (place_grid) is for a grid sized from the data.
    const auto& r = *options.resolution;
    const uint64_t voxels = uint64_t(r[0]) * r[1] * r[2];
    if (voxels >= 0xFFFFFFFFull)
      throw UsageError("--grid: " + text + " is " + std::to_string(voxels) +
                       " voxels, more than the 2^32 - 1 a grid may hold");
  } else {
    throw UsageError("--grid: expected auto, N or NxNxN, got '" + text + "'");
  }
}

VoxelMemory voxel_memory_within(uint64_t available) {
  VoxelMemory memory;
  memory.merge_bytes = std::min<uint64_t>(available / 4, uint64_t{256} << 20);
  memory.records_bytes = available - memory.merge_bytes - available / 20;
  return memory;
}

VoxelGrid voxelize(const LineSet& lines, const VoxelOptions& options, const ProgressFn& progress) {
  VoxelStreamBuilder builder(lines, compute_stats(lines), options);
  builder.add(lines);
  if (progress) progress(1, 2);
  VoxelGrid grid;
  GridSink sink(grid);
  builder.finish(sink);
  if (progress) progress(2, 2);
  return grid;
}

}  // namespace linebake
