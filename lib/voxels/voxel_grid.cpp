#include "voxels/voxel_grid.hpp"

#include <algorithm>
#include <bit>
#include <cmath>

namespace linebake {

static uint32_t bits_of(uint32_t quantization) {
  return uint32_t(std::countr_zero(quantization));
}

DecodedChord unpack_chord(uint32_t w0, uint32_t w1, uint32_t quantization) {
  const uint32_t b = bits_of(quantization), mask = quantization - 1;
  DecodedChord c;
  const uint32_t start_face = w0 & 7, end_face = (w0 >> 3) & 7;
  c.start = decode_end({start_face, (w0 >> 6) & mask, (w0 >> (6 + b)) & mask, (w1 >> 21) & 31},
                       quantization);
  c.end = decode_end(
      {end_face, (w0 >> (6 + 2 * b)) & mask, (w0 >> (6 + 3 * b)) & mask, (w1 >> 26) & 31},
      quantization);
  c.line_bits = w1 & 31;
  c.attribute_start = uint8_t((w1 >> 5) & 255);
  c.attribute_end = uint8_t((w1 >> 13) & 255);
  return c;
}

std::array<uint32_t, 3> VoxelGrid::level_resolution(size_t level) const {
  std::array<uint32_t, 3> r = resolution;
  for (size_t l = 0; l < level; ++l)
    for (uint32_t& n : r) n = (n + 1) / 2;
  return r;
}

size_t VoxelGrid::density_level_count() const {
  size_t level = 0;
  for (auto r = resolution; r[0] > 1 || r[1] > 1 || r[2] > 1; r = level_resolution(level)) ++level;
  return level + 1;
}

uint64_t VoxelGrid::bytes() const {
  uint64_t n = representation_bytes() + line_counts.bytes();
  for (const Array<float>& d : density) n += d.bytes();
  return n;
}

void GridPieces::offsets(uint64_t first, uint64_t count, uint32_t* out) {
  std::copy_n(grid_.offsets.data() + first, count, out);
}
void GridPieces::line_counts(uint64_t first, uint64_t count, uint8_t* out) {
  std::copy_n(grid_.line_counts.data() + first, count, out);
}
void GridPieces::density(uint64_t first, uint64_t count, float* out) {
  std::copy_n(grid_.density.at(0).data() + first, count, out);
}
void GridPieces::chords(uint64_t first, uint64_t count, uint32_t* out) {
  std::copy_n(grid_.chords.data() + 2 * first, 2 * count, out);
}

}  // namespace linebake
