#include "voxels/voxelizer.hpp"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <regex>

#include "core/error.hpp"

namespace linebake {
namespace {

using Vec = std::array<double, 3>;

// Distances from n points to a polyline. Loops over the polyline's segments outside, so each
// segment's setup is paid once, and leaves the square roots independent of each other.
template <size_t n>
std::array<double, n> distances_to_path(const std::array<Vec, n>& points,
                                        const std::vector<Vec>& path) {
  std::array<double, n> best;
  best.fill(1e300);
  const auto consider = [&](const Vec& a, const Vec& d, double inv_dd) {
    for (size_t s = 0; s < n; ++s) {
      const Vec w{points[s][0] - a[0], points[s][1] - a[1], points[s][2] - a[2]};
      const double t = std::clamp((w[0] * d[0] + w[1] * d[1] + w[2] * d[2]) * inv_dd, 0.0, 1.0);
      const double ex = w[0] - t * d[0], ey = w[1] - t * d[1], ez = w[2] - t * d[2];
      best[s] = std::min(best[s], ex * ex + ey * ey + ez * ez);
    }
  };
  if (path.size() == 1) consider(path[0], Vec{}, 0.0);
  for (size_t i = 0; i + 1 < path.size(); ++i) {
    const Vec d{path[i + 1][0] - path[i][0], path[i + 1][1] - path[i][1],
                path[i + 1][2] - path[i][2]};
    const double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    consider(path[i], d, dd > 0 ? 1.0 / dd : 0.0);
  }
  for (double& b : best) b = std::sqrt(b);
  return best;
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

// A chord on its way to its voxel. Records are made in line order and along each line, and
// every later step moves them stably, so a voxel's chords end up in the canonical order (line
// id, then along the line) without a sort.
struct Record {
  uint32_t voxel, line;
  uint32_t word0, word1;
  float weight;
};

// A fixed run of lines walked by one task. Fixed by the data, not the thread count, so sums
// over a block (error, and the order of records) are the same for any number of threads.
struct Block {
  size_t first_line = 0, end_line = 0;
  std::vector<Record> records;
  double error_max = 0, error_sum = 0;
  uint64_t error_samples = 0;
};

class Voxelizer {
 public:
  Voxelizer(const LineSet& lines, const VoxelOptions& options, VoxelGrid& grid)
      : lines_(lines), options_(options), grid_(grid) {}
  void build(const ProgressFn& progress);

 private:
  void place_grid();
  template <class Emit>
  void walk(size_t line, std::vector<Vec>& path, Emit&& emit) const;
  void emit(const Piece& piece, uint32_t line, Block& block) const;
  Vec to_grid(uint64_t point) const {
    Vec g{};
    for (int k = 0; k < 3; ++k)
      g[k] = (double(lines_.positions[3 * point + k]) - grid_.origin[k]) / grid_.voxel_size;
    return g;
  }
  float attribute_at(uint64_t point) const { return attribute_ ? (*attribute_)[point] : 0.0f; }
  uint8_t to_unorm8(float v) const {
    const float lo = grid_.attribute_range[0], span = grid_.attribute_range[1] - lo;
    if (!(span > 0) || !std::isfinite(v)) return 0;
    return uint8_t(std::clamp((v - lo) / span, 0.0f, 1.0f) * 255 + 0.5f);
  }

  const LineSet& lines_;
  const VoxelOptions& options_;
  VoxelGrid& grid_;
  const std::vector<float>* attribute_ = nullptr;
};

void Voxelizer::place_grid() {
  const Bounds b = compute_bounds(lines_);
  if (b.empty) throw Error("voxels: the line set has no finite point");
  std::array<double, 3> extent{};
  for (int k = 0; k < 3; ++k) extent[k] = std::max(double(b.max[k]) - b.min[k], 0.0);
  const double longest = std::max({extent[0], extent[1], extent[2]});
  const double span = longest > 0 ? longest : 1.0;
  // No padding: points on the upper bound belong to the last voxel (cells are clamped).
  for (int k = 0; k < 3; ++k) grid_.origin[k] = b.min[k];
  if (options_.resolution) {
    const auto& r = *options_.resolution;
    double h = 0;
    for (int k = 0; k < 3; ++k) {
      if (r[k] == 0 || r[k] > 4096) throw Error("voxels: resolution per axis must be 1..4096");
      h = std::max(h, extent[k] / r[k]);
    }
    grid_.voxel_size = float(h > 0 ? h : 1.0);
    grid_.resolution = r;
  } else {
    const uint32_t longest_res =
        options_.grid ? options_.grid : automatic_grid_resolution(lines_.segment_count());
    if (longest_res == 0 || longest_res > 4096)
      throw Error("voxels: grid resolution must be 1..4096");
    grid_.voxel_size = float(span / longest_res);
    for (int k = 0; k < 3; ++k)
      grid_.resolution[k] = std::clamp<uint32_t>(
          uint32_t(std::ceil(extent[k] / grid_.voxel_size - 1e-6)), 1, longest_res);
  }
}

// Walks a line through the grid (Amanatides-Woo per segment) and emits one piece per stay in
// a voxel: from where the line entered (a face, or its first point) to where it left (a face,
// or its last point). Pieces shorter than 1e-9 voxels (a line crossing an edge or corner) are
// not emitted.
template <class Emit>
void Voxelizer::walk(size_t line, std::vector<Vec>& path, Emit&& emit) const {
  const uint64_t first = lines_.line_offsets[line], last = lines_.line_offsets[line + 1];
  if (last - first < 2) return;
  const auto& res = grid_.resolution;
  Piece piece;
  piece.path = &path;
  const Vec start = to_grid(first);
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
          grid_.index(uint32_t(piece.cell[0]), uint32_t(piece.cell[1]), uint32_t(piece.cell[2]));
      emit(piece);
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
    const Vec b = to_grid(i + 1);
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
void Voxelizer::emit(const Piece& p, uint32_t line, Block& block) const {
  const uint32_t q = grid_.quantization;
  std::array<float, 3> entry{}, exit{};
  for (int k = 0; k < 3; ++k) {
    entry[k] = float(std::clamp(p.entry[k] - double(p.cell[k]), 0.0, 1.0));
    exit[k] = float(std::clamp(p.exit[k] - double(p.cell[k]), 0.0, 1.0));
  }
  const ChordEnd start = quantise_end(entry, p.entry_face, q);
  const ChordEnd end = quantise_end(exit, p.exit_face, q);
  const uint8_t a0 = to_unorm8(p.entry_attribute), a1 = to_unorm8(p.exit_attribute);
  const auto words = pack_chord(start, end, line, a0, a1, q);
  const float weight = float(p.length) * (attribute_ ? (float(a0) + float(a1)) / 510.0f : 1.0f);
  block.records.push_back({uint32_t(p.voxel), line, words[0], words[1], weight});

  const std::array<float, 3> s = decode_end(start, q), e = decode_end(end, q);
  std::array<Vec, 5> samples;
  for (size_t i = 0; i < samples.size(); ++i)
    for (int k = 0; k < 3; ++k)
      samples[i][k] = double(p.cell[k]) + s[k] + (e[k] - s[k]) * (double(i) / 4.0);
  double error_max = block.error_max, error_sum = block.error_sum;
  for (const double d : distances_to_path(samples, *p.path)) {
    error_max = std::max(error_max, d);
    error_sum += d;
  }
  block.error_max = error_max;
  block.error_sum = error_sum;
  block.error_samples += samples.size();
}

void Voxelizer::build(const ProgressFn& progress) {
  const uint32_t q = options_.quantization;
  if (q != 16 && q != 32 && q != 64) throw Error("voxels: quantisation must be 16, 32 or 64");
  if (options_.max_chords_per_voxel == 0 || options_.max_chords_per_voxel > 65535)
    throw Error("voxels: the chord cap per voxel must be 1..65535");
  grid_.quantization = q;
  grid_.max_chords_per_voxel = options_.max_chords_per_voxel;
  grid_.segments = lines_.segment_count();
  if (options_.attribute != "none") {
    const Attribute* a = options_.attribute.empty()
                             ? (lines_.attributes.empty() ? nullptr : &lines_.attributes[0])
                             : lines_.find_attribute(options_.attribute);
    if (!options_.attribute.empty() && !a)
      throw Error("voxels: no vertex attribute named '" + options_.attribute + "'");
    if (a) {
      attribute_ = &a->values;
      grid_.attribute = a->name;
      if (options_.attribute_range) {
        grid_.attribute_range = *options_.attribute_range;
      } else {
        const ValueRange r = compute_range(a->values);
        grid_.attribute_range = {r.min, r.max};
      }
    }
  }
  place_grid();
  const uint64_t voxels = grid_.voxel_count();
  const size_t line_count = lines_.line_count();
  if (voxels >= 0xFFFFFFFFull) throw Error("voxels: more than 2^32 - 1 voxels; use a coarser grid");
  if (line_count >= 0xFFFFFFFFull) throw Error("voxels: more than 2^32 - 1 lines");

  // 1. Walk every line once; each block of lines collects its chords and its error figures.
  std::vector<Block> blocks;
  {
    constexpr uint64_t kSegmentsPerBlock = 1 << 16;
    size_t first = 0;
    while (first < line_count) {
      size_t end = first;
      const uint64_t begin_point = lines_.line_offsets[first];
      while (end < line_count &&
             (end == first || lines_.line_offsets[end] - begin_point < kSegmentsPerBlock))
        ++end;
      blocks.push_back({first, end, {}, 0, 0, 0});
      first = end;
    }
  }
  std::atomic<size_t> blocks_done{0};
  const size_t progress_groups = std::clamp<size_t>(blocks.size() / 8, 1, 32);
  for (size_t g = 0; g < progress_groups; ++g) {
    const size_t begin = blocks.size() * g / progress_groups;
    const size_t end = blocks.size() * (g + 1) / progress_groups;
    tbb::parallel_for(size_t{begin}, end, [&](size_t b) {
      Block& block = blocks[b];
      block.records.reserve(
          2 * (lines_.line_offsets[block.end_line] - lines_.line_offsets[block.first_line]));
      std::vector<Vec> path;
      for (size_t l = block.first_line; l != block.end_line; ++l)
        walk(l, path, [&](const Piece& p) { emit(p, uint32_t(l), block); });
      blocks_done.fetch_add(1, std::memory_order_relaxed);
    });
    if (progress) progress(blocks_done.load(), 2 * blocks.size());
  }

  // 2. Each block sorts its records stably into buckets of consecutive voxels, small enough
  // that a bucket's per-voxel counters stay in cache. In place (through a per-thread scratch
  // buffer), so no second copy of all records is ever allocated.
  const uint32_t bucket_shift =
      uint32_t(std::max(0, int(std::bit_width(voxels)) - 10));  // at most 1024 buckets
  const uint64_t bucket_count = ((voxels - 1) >> bucket_shift) + 1;
  // bucket_ranges[b * (bucket_count + 1) + k]: where bucket k starts in block b's records.
  std::vector<uint32_t> bucket_ranges(blocks.size() * (bucket_count + 1), 0);
  tbb::enumerable_thread_specific<std::vector<Record>> scratch;
  tbb::parallel_for(size_t{0}, blocks.size(), [&](size_t b) {
    std::vector<Record>& records = blocks[b].records;
    if (records.size() > 0xFFFFFFFFull)
      throw Error("voxels: more than 2^32 chords; use a coarser grid");
    uint32_t* start = bucket_ranges.data() + b * (bucket_count + 1);
    for (const Record& r : records) ++start[(r.voxel >> bucket_shift) + 1];
    for (uint64_t k = 0; k < bucket_count; ++k) start[k + 1] += start[k];
    std::vector<Record>& sorted = scratch.local();
    sorted.resize(records.size());
    std::vector<uint32_t> cursor(start, start + bucket_count);
    for (const Record& r : records) sorted[cursor[r.voxel >> bucket_shift]++] = r;
    std::copy(sorted.begin(), sorted.end(), records.begin());
  });
  scratch.clear();
  const auto for_each_record = [&](uint64_t k, auto&& body) {
    for (size_t b = 0; b < blocks.size(); ++b) {
      const uint32_t* start = bucket_ranges.data() + b * (bucket_count + 1);
      const Record* records = blocks[b].records.data();
      for (uint32_t i = start[k]; i != start[k + 1]; ++i) body(records[i]);
    }
  };
  uint64_t total = 0;
  for (const Block& block : blocks) total += block.records.size();
  if (total > 0xFFFFFFFFull) throw Error("voxels: more than 2^32 chords; use a coarser grid");

  // 3. Per bucket: chords per voxel, density, distinct lines and the cap; then, once every
  // bucket knows how many chords it keeps, the offsets and the chords themselves.
  const uint32_t cap = options_.max_chords_per_voxel;
  const uint64_t bucket_span = uint64_t(1) << bucket_shift;
  grid_.density.emplace_back(voxels);
  grid_.line_counts = Array<uint8_t>(voxels);
  grid_.offsets = Array<uint32_t>(voxels + 1);
  struct BucketStats {
    uint64_t kept = 0, occupied = 0, overflowed = 0, dropped = 0;
  };
  std::vector<BucketStats> bucket_stats(bucket_count);
  tbb::parallel_for(uint64_t{0}, bucket_count, [&](uint64_t k) {
    const uint64_t base = k << bucket_shift;
    const uint64_t span = std::min(bucket_span, voxels - base);
    std::vector<uint32_t> n(span, 0), distinct(span, 0), last_line(span, 0xFFFFFFFFu);
    std::vector<float> density(span, 0.0f);
    for_each_record(k, [&](const Record& r) {
      const uint64_t v = r.voxel - base;
      ++n[v];
      density[v] += r.weight;
      if (last_line[v] != r.line) ++distinct[v], last_line[v] = r.line;
    });
    BucketStats& s = bucket_stats[k];
    for (uint64_t v = 0; v < span; ++v) {
      grid_.density[0][base + v] = density[v];
      grid_.line_counts[base + v] = uint8_t(std::min<uint32_t>(distinct[v], 255));
      const uint32_t kept = std::min(n[v], cap);
      grid_.offsets[base + v] = kept;  // a count for now; the start once every bucket is done
      s.kept += kept;
      s.occupied += n[v] > 0;
      s.overflowed += n[v] > cap;
      s.dropped += n[v] - kept;
    }
  });
  std::vector<uint64_t> kept_start(bucket_count + 1, 0);
  for (uint64_t k = 0; k < bucket_count; ++k) {
    kept_start[k + 1] = kept_start[k] + bucket_stats[k].kept;
    grid_.voxels_occupied += bucket_stats[k].occupied;
    grid_.voxels_overflowed += bucket_stats[k].overflowed;
    grid_.chords_dropped += bucket_stats[k].dropped;
  }
  grid_.offsets[voxels] = uint32_t(kept_start[bucket_count]);
  grid_.chords = Array<uint32_t>(2 * kept_start[bucket_count]);
  tbb::parallel_for(uint64_t{0}, bucket_count, [&](uint64_t k) {
    const uint64_t base = k << bucket_shift;
    const uint64_t span = std::min(bucket_span, voxels - base);
    // Per voxel: where its next kept chord goes and how many more it keeps.
    std::vector<uint32_t> cursor(span), room(span);
    uint32_t running = uint32_t(kept_start[k]);
    for (uint64_t v = 0; v < span; ++v) {
      room[v] = grid_.offsets[base + v];
      cursor[v] = grid_.offsets[base + v] = running;
      running += room[v];
    }
    for_each_record(k, [&](const Record& r) {
      const uint64_t v = r.voxel - base;
      if (room[v] == 0) return;  // over the cap: the first chords in canonical order stay
      --room[v];
      const uint64_t at = 2 * uint64_t(cursor[v]++);
      grid_.chords[at] = r.word0;
      grid_.chords[at + 1] = r.word1;
    });
  });
  for (Block& block : blocks) std::vector<Record>().swap(block.records);
  // Density mip levels: 2x2x2 means (missing children count as empty) down to one voxel.
  while (true) {
    const size_t level = grid_.density.size() - 1;
    const auto fine = grid_.level_resolution(level), coarse = grid_.level_resolution(level + 1);
    if (fine[0] == 1 && fine[1] == 1 && fine[2] == 1) break;
    Array<float> next(static_cast<uint64_t>(coarse[0]) * coarse[1] * coarse[2]);
    const Array<float>& src = grid_.density[level];
    tbb::parallel_for(uint32_t{0}, coarse[2], [&](uint32_t z) {
      for (uint32_t y = 0; y < coarse[1]; ++y)
        for (uint32_t x = 0; x < coarse[0]; ++x) {
          float sum = 0;
          for (uint32_t dz = 0; dz < 2; ++dz)
            for (uint32_t dy = 0; dy < 2; ++dy)
              for (uint32_t dx = 0; dx < 2; ++dx) {
                const uint32_t fx = 2 * x + dx, fy = 2 * y + dy, fz = 2 * z + dz;
                if (fx < fine[0] && fy < fine[1] && fz < fine[2])
                  sum += src[(uint64_t(fz) * fine[1] + fy) * fine[0] + fx];
              }
          next[(uint64_t(z) * coarse[1] + y) * coarse[0] + x] = sum / 8;
        }
    });
    grid_.density.push_back(std::move(next));
  }

  double sum = 0;
  uint64_t samples = 0;
  for (const Block& block : blocks) {
    grid_.max_error = std::max(grid_.max_error, block.error_max);
    sum += block.error_sum;
    samples += block.error_samples;
  }
  grid_.mean_error = samples ? sum / double(samples) : 0.0;
}

}  // namespace

uint32_t automatic_grid_resolution(uint64_t segments) {
  const double root = std::cbrt(double(std::max<uint64_t>(segments, 1)));
  const uint64_t pow2 = std::bit_ceil(uint64_t(std::ceil(root)));
  return uint32_t(std::clamp<uint64_t>(pow2 * 2, 64, 512));
}

void parse_grid(const std::string& text, VoxelOptions& options) {
  static const std::regex single(R"(\d{1,4})"), triple(R"((\d{1,4})x(\d{1,4})x(\d{1,4}))");
  std::smatch m;
  if (text == "auto") {
    options.grid = 0;
    options.resolution.reset();
  } else if (std::regex_match(text, single)) {
    options.grid = uint32_t(std::stoul(text));
    options.resolution.reset();
  } else if (std::regex_match(text, m, triple)) {
    options.resolution = std::array<uint32_t, 3>{
        uint32_t(std::stoul(m[1])), uint32_t(std::stoul(m[2])), uint32_t(std::stoul(m[3]))};
  } else {
    throw Error("--grid: expected auto, N or NxNxN, got '" + text + "'");
  }
}

VoxelGrid voxelize(const LineSet& lines, const VoxelOptions& options, const ProgressFn& progress) {
  VoxelGrid grid;
  Voxelizer(lines, options, grid).build(progress);
  return grid;
}

}  // namespace linebake
