#pragma once
// The quantized voxel line grid of Kanzler et al. 2018 (techniques.md section 8), the
// representation the VRC technique ray casts. Each voxel holds the chords of the lines that pass
// through it: straight pieces from the point where a line enters the voxel to where it leaves,
// each endpoint quantised to a Q x Q cell of the voxel face it lies on (or, for a line end inside
// the voxel, to a cell of the voxel interior), packed in two uint32 words.

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "core/array.hpp"

namespace linebake {

// Face ids 0..5 are 2 * axis + side (side 1: the face at the voxel's upper coordinate);
// kInteriorFace marks a line end inside the voxel.
constexpr uint32_t kInteriorFace = 6;

// Chord word layout, for Q = 2^b (b = 4, 5, 6):
//   word 0: [0,3) start face, [3,6) end face, then start u, start v, end u, end v (b bits each)
//   word 1: [0,5) line id mod 32, [5,13) start attribute (unorm8), [13,21) end attribute,
//           [21,26) start w, [26,31) end w (interior ends only: the third coordinate, quantised
//           to min(Q, 32) levels)
// u, v are the two coordinates other than the face's axis in ascending axis order (x,y,z for an
// interior end: u = x, v = y, w = z).
struct ChordEnd {
  uint32_t face = 0;
  uint32_t u = 0, v = 0, w = 0;  // quantised cells
};

struct DecodedChord {
  std::array<float, 3> start{}, end{};  // voxel-local coordinates in [0, 1]
  uint32_t line_bits = 0;               // line id mod 32
  uint8_t attribute_start = 0, attribute_end = 0;
};

inline uint32_t interior_levels(uint32_t quantization) {
  return quantization < 32 ? quantization : 32;
}
// Inline: the voxelizer packs one chord per stay of a line in a voxel (10^8 for a large set).
inline std::array<uint32_t, 2> pack_chord(const ChordEnd& start, const ChordEnd& end, uint32_t line,
                                          uint8_t attribute_start, uint8_t attribute_end,
                                          uint32_t quantization) {
  const uint32_t b = uint32_t(std::countr_zero(quantization));
  uint32_t w0 = start.face | end.face << 3;
  w0 |= start.u << 6 | start.v << (6 + b) | end.u << (6 + 2 * b) | end.v << (6 + 3 * b);
  uint32_t w1 = (line & 31) | uint32_t(attribute_start) << 5 | uint32_t(attribute_end) << 13;
  w1 |= start.w << 21 | end.w << 26;
  return {w0, w1};
}
// Decodes at cell centres ((q + 0.5) / Q), which halves the quantisation bias.
DecodedChord unpack_chord(uint32_t word0, uint32_t word1, uint32_t quantization);
// One end, decoded the same way (voxel-local coordinates in [0, 1]).
inline std::array<float, 3> decode_end(const ChordEnd& e, uint32_t quantization) {
  const float inv_q = 1.0f / float(quantization);  // powers of two: exact
  if (e.face == kInteriorFace)
    return {(float(e.u) + 0.5f) * inv_q, (float(e.v) + 0.5f) * inv_q,
            (float(e.w) + 0.5f) / float(interior_levels(quantization))};
  const uint32_t axis = e.face / 2;
  std::array<float, 3> p{};
  p[axis] = float(e.face & 1);
  p[axis == 0 ? 1 : 0] = (float(e.u) + 0.5f) * inv_q;
  p[axis == 2 ? 1 : 2] = (float(e.v) + 0.5f) * inv_q;
  return p;
}
// Voxel-local point -> quantised end on the given face (or kInteriorFace).
inline uint32_t quantise_cell(float x, uint32_t levels) {
  const float scaled = std::floor(x * float(levels));
  return uint32_t(std::clamp(scaled, 0.0f, float(levels - 1)));
}
inline ChordEnd quantise_end(const std::array<float, 3>& local, uint32_t face,
                             uint32_t quantization) {
  ChordEnd e;
  e.face = face;
  if (face == kInteriorFace) {
    e.u = quantise_cell(local[0], quantization);
    e.v = quantise_cell(local[1], quantization);
    e.w = quantise_cell(local[2], interior_levels(quantization));
    return e;
  }
  const uint32_t axis = face / 2;
  e.u = quantise_cell(local[axis == 0 ? 1 : 0], quantization);
  e.v = quantise_cell(local[axis == 2 ? 1 : 2], quantization);
  return e;
}

struct VoxelGrid {
  std::array<uint32_t, 3> resolution{};  // voxels per axis
  std::array<float, 3> origin{};         // world position of the grid's lower corner
  float voxel_size = 1;                  // cubic voxels, world units
  uint32_t quantization = 32;
  uint32_t max_chords_per_voxel = 32;
  std::string attribute;                   // what the 8-bit chord attributes encode ("" if none)
  std::array<float, 2> attribute_range{};  // value mapped to unorm8 0 and 255

  // Chords of voxel i (x fastest, then y, then z) are chords[2*offsets[i] .. 2*offsets[i+1]),
  // ordered by line id and then along the line.
  Array<uint32_t> offsets;  // voxel count + 1
  Array<uint32_t> chords;   // 2 words per chord
  // Distinct lines per voxel among all its chords (saturating at 255), for exports and stats.
  Array<uint8_t> line_counts;
  // density[0]: per voxel, polyline length inside it (voxel units) x the chord's mean attribute
  // normalised to [0, 1] (1 without attribute); density[k + 1]: 2x2x2 means of density[k].
  std::vector<Array<float>> density;

  // Build statistics.
  uint64_t segments = 0;
  uint64_t chords_dropped = 0;  // over max_chords_per_voxel
  uint64_t voxels_overflowed = 0;
  uint64_t voxels_occupied = 0;
  double max_error = 0;  // voxel units: decoded chords against the original polyline
  double mean_error = 0;

  uint64_t voxel_count() const { return uint64_t(resolution[0]) * resolution[1] * resolution[2]; }
  uint64_t chord_count() const { return chords.size() / 2; }
  uint64_t index(uint32_t x, uint32_t y, uint32_t z) const {
    return (uint64_t(z) * resolution[1] + y) * resolution[0] + x;
  }
  std::array<uint32_t, 3> level_resolution(size_t level) const;
  // Density levels a build makes: level 0 and the 2x2x2 means down to one voxel.
  size_t density_level_count() const;
  // What VRC renders from: offsets and chords.
  uint64_t representation_bytes() const { return offsets.bytes() + chords.bytes(); }
  // Everything, with the density mip levels and line counts.
  uint64_t bytes() const;
};

// A grid's arrays read a piece at a time, each from its start on: what a consumer that need not
// hold the whole grid reads (write_vdb), from a grid in memory or from a cache (voxel_store.hpp).
class VoxelPieces {
 public:
  virtual ~VoxelPieces() = default;
  // The grid without its arrays: placement, attribute, statistics.
  virtual const VoxelGrid& description() const = 0;
  // offsets[first, first + count) (up to voxel count + 1), line_counts and density level 0
  // [first, first + count), chords [first, first + count) (two words each).
  virtual void offsets(uint64_t first, uint64_t count, uint32_t* out) = 0;
  virtual void line_counts(uint64_t first, uint64_t count, uint8_t* out) = 0;
  virtual void density(uint64_t first, uint64_t count, float* out) = 0;
  virtual void chords(uint64_t first, uint64_t count, uint32_t* out) = 0;
  // After the last piece of every array: throws where what was read is not sound (a cache's
  // hashes; offsets that do not end at the chord count).
  virtual void finish() {}
};

// The pieces of a grid in memory.
class GridPieces : public VoxelPieces {
 public:
  explicit GridPieces(const VoxelGrid& grid) : grid_(grid) {}
  const VoxelGrid& description() const override { return grid_; }
  void offsets(uint64_t first, uint64_t count, uint32_t* out) override;
  void line_counts(uint64_t first, uint64_t count, uint8_t* out) override;
  void density(uint64_t first, uint64_t count, float* out) override;
  void chords(uint64_t first, uint64_t count, uint32_t* out) override;

 private:
  const VoxelGrid& grid_;
};

}  // namespace linebake
