#include "voxels/voxelizer.hpp"

#include <tbb/blocked_range.h>
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

double distance_to_path(const Vec& p, const std::vector<Vec>& path) {
  double best = 1e300;
  for (size_t i = 0; i + 1 < path.size(); ++i) {
    Vec d{}, w{};
    double dd = 0, wd = 0;
    for (int k = 0; k < 3; ++k) {
      d[k] = path[i + 1][k] - path[i][k];
      w[k] = p[k] - path[i][k];
      dd += d[k] * d[k];
      wd += w[k] * d[k];
    }
    const double t = dd > 0 ? std::clamp(wd / dd, 0.0, 1.0) : 0.0;
    double e = 0;
    for (int k = 0; k < 3; ++k) e += (w[k] - t * d[k]) * (w[k] - t * d[k]);
    best = std::min(best, e);
  }
  if (path.size() == 1)
    best = (p[0] - path[0][0]) * (p[0] - path[0][0]) + (p[1] - path[0][1]) * (p[1] - path[0][1]) +
           (p[2] - path[0][2]) * (p[2] - path[0][2]);
  return std::sqrt(best);
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

struct Record {
  uint64_t key;  // line << 32 | chord number along the line
  uint32_t word0, word1;
  float weight;
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
  const size_t batches = std::clamp<size_t>(line_count / 4096, 1, 32);
  const auto in_batches = [&](auto&& body, uint64_t progress_base) {
    for (size_t b = 0; b < batches; ++b) {
      const size_t begin = line_count * b / batches, end = line_count * (b + 1) / batches;
      tbb::parallel_for(tbb::blocked_range<size_t>(begin, end, 16), [&](auto range) {
        std::vector<Vec> path;
        for (size_t l = range.begin(); l != range.end(); ++l) body(l, path);
      });
      if (progress) progress(progress_base + end, 2 * line_count);
    }
  };

  // Count chords per voxel.
  Array<uint32_t> counts(voxels);
  std::fill(counts.begin(), counts.end(), 0u);
  in_batches(
      [&](size_t l, std::vector<Vec>& path) {
        walk(l, path, [&](const Piece& p) {
          std::atomic_ref<uint32_t>(counts[p.voxel]).fetch_add(1, std::memory_order_relaxed);
        });
      },
      0);
  // Prefix sum -> where each voxel's records start.
  Array<uint64_t> starts(voxels + 1);
  starts[0] = 0;
  for (uint64_t v = 0; v < voxels; ++v) starts[v + 1] = starts[v] + counts[v];
  const uint64_t total = starts[voxels];
  if (total > 0xFFFFFFFFull) throw Error("voxels: more than 2^32 chords; use a coarser grid");

  // Fill: slots come from per-voxel cursors, so records land in any order within a voxel;
  // the sort below makes the order canonical.
  std::vector<Record> records(total);
  std::fill(counts.begin(), counts.end(), 0u);
  std::vector<double> line_error_max(line_count, 0), line_error_sum(line_count, 0);
  std::vector<uint64_t> line_samples(line_count, 0);
  in_batches(
      [&](size_t l, std::vector<Vec>& path) {
        uint32_t sequence = 0;
        walk(l, path, [&](const Piece& p) {
          std::array<float, 3> entry{}, exit{};
          for (int k = 0; k < 3; ++k) {
            entry[k] = float(std::clamp(p.entry[k] - double(p.cell[k]), 0.0, 1.0));
            exit[k] = float(std::clamp(p.exit[k] - double(p.cell[k]), 0.0, 1.0));
          }
          const uint8_t a0 = to_unorm8(p.entry_attribute), a1 = to_unorm8(p.exit_attribute);
          const auto words = pack_chord(quantise_end(entry, p.entry_face, q),
                                        quantise_end(exit, p.exit_face, q), uint32_t(l), a0, a1, q);
          const float weight =
              float(p.length) * (attribute_ ? (float(a0) + float(a1)) / 510.0f : 1.0f);
          const uint32_t slot =
              std::atomic_ref<uint32_t>(counts[p.voxel]).fetch_add(1, std::memory_order_relaxed);
          records[starts[p.voxel] + slot] = {uint64_t(l) << 32 | sequence++, words[0], words[1],
                                             weight};
          // Quantisation + chord error: the decoded chord sampled at five points against the
          // polyline inside the voxel.
          const DecodedChord c = unpack_chord(words[0], words[1], q);
          for (int s = 0; s <= 4; ++s) {
            Vec x{};
            for (int k = 0; k < 3; ++k)
              x[k] = double(p.cell[k]) + c.start[k] + (c.end[k] - c.start[k]) * (s / 4.0);
            const double e = distance_to_path(x, *p.path);
            line_error_max[l] = std::max(line_error_max[l], e);
            line_error_sum[l] += e;
          }
          line_samples[l] += 5;
        });
      },
      line_count);

  // Per voxel: canonical order, density, distinct lines, the cap.
  grid_.density.emplace_back(voxels);
  grid_.line_counts = Array<uint8_t>(voxels);
  Array<uint32_t> kept(voxels);
  const uint32_t cap = options_.max_chords_per_voxel;
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, voxels, 4096), [&](auto range) {
    for (uint64_t v = range.begin(); v != range.end(); ++v) {
      Record* begin = records.data() + starts[v];
      Record* end = records.data() + starts[v + 1];
      std::sort(begin, end, [](const Record& x, const Record& y) { return x.key < y.key; });
      float density = 0;
      uint32_t distinct = 0;
      for (Record* r = begin; r != end; ++r) {
        density += r->weight;
        distinct += r == begin || (r->key >> 32) != (r[-1].key >> 32);
      }
      grid_.density[0][v] = density;
      grid_.line_counts[v] = uint8_t(std::min<uint32_t>(distinct, 255));
      kept[v] = std::min<uint32_t>(uint32_t(end - begin), cap);
    }
  });
  grid_.offsets = Array<uint32_t>(voxels + 1);
  grid_.offsets[0] = 0;
  for (uint64_t v = 0; v < voxels; ++v) {
    grid_.offsets[v + 1] = grid_.offsets[v] + kept[v];
    const uint64_t n = starts[v + 1] - starts[v];
    grid_.voxels_occupied += n > 0;
    if (n > cap) {
      grid_.voxels_overflowed += 1;
      grid_.chords_dropped += n - cap;
    }
  }
  grid_.chords = Array<uint32_t>(2 * uint64_t(grid_.offsets[voxels]));
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, voxels, 4096), [&](auto range) {
    for (uint64_t v = range.begin(); v != range.end(); ++v) {
      uint32_t* out = grid_.chords.data() + 2 * uint64_t(grid_.offsets[v]);
      for (uint32_t i = 0; i < kept[v]; ++i) {
        const Record& r = records[starts[v] + i];
        out[2 * i] = r.word0;
        out[2 * i + 1] = r.word1;
      }
    }
  });

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
  for (size_t l = 0; l < line_count; ++l) {
    grid_.max_error = std::max(grid_.max_error, line_error_max[l]);
    sum += line_error_sum[l];
    samples += line_samples[l];
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
