#include "accel/capsule_segments.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.hpp"

namespace linebake {

uint64_t CapsuleSegments::segment_count() const {
  uint64_t n = 0;
  for (const CapsuleChunk& c : chunks) n += c.segment_count();
  return n;
}

uint64_t CapsuleSegments::bytes() const {
  uint64_t n = 0;
  for (const CapsuleChunk& c : chunks) n += c.bytes();
  return n;
}

uint64_t capsule_segments_bytes(const LineSet& lines) {
  return 4 * (4 * uint64_t(lines.point_count()) + 7 * lines.segment_count());
}

CapsuleSegments build_capsule_segments(const LineSet& lines, float radius,
                                       const std::string& attribute,
                                       uint64_t max_segments_per_chunk) {
  if (!(radius > 0)) throw Error("capsules: the radius must be positive");
  if (max_segments_per_chunk < 1) throw Error("capsules: at least one segment per chunk");
  const Attribute* values = nullptr;
  // A usage error listing the names, as embree's (it had been exit 4 naming none).
  if (!attribute.empty() && !(values = lines.find_attribute(attribute)))
    throw_unknown_attribute(lines, "--attribute", attribute, true);
  CapsuleSegments out;
  out.radius = radius;
  out.attribute = attribute;
  if (values) {
    float lo = std::numeric_limits<float>::infinity(), hi = -lo;
    for (float v : values->values)
      if (std::isfinite(v)) lo = std::min(lo, v), hi = std::max(hi, v);
    if (lo <= hi) out.attribute_range = {lo, hi};
  }
  constexpr uint64_t kMaxLocalPoints = uint64_t{1} << 30;  // 30 bits in the segment word
  size_t line = 0;
  while (line < lines.line_count()) {
    CapsuleChunk chunk;
    chunk.first_line = line;
    const uint64_t first_point = lines.line_offsets[line];
    uint64_t segments = 0;
    while (line < lines.line_count()) {
      const uint64_t n = lines.line_size(line) > 1 ? lines.line_size(line) - 1 : 0;
      const uint64_t points_after = lines.line_offsets[line + 1] - first_point;
      if (chunk.line_count > 0 &&
          (segments + n > max_segments_per_chunk || points_after > kMaxLocalPoints))
        break;
      if (points_after > kMaxLocalPoints)
        throw Error("capsules: line " + std::to_string(line) + " has more than 2^30 points");
      segments += n;
      ++chunk.line_count;
      ++line;
    }
    const uint64_t point_count = lines.line_offsets[line] - first_point;
    chunk.points.resize(4 * point_count);
    for (uint64_t p = 0; p < point_count; ++p) {
      for (uint64_t k = 0; k < 3; ++k)
        chunk.points[4 * p + k] = lines.positions[3 * (first_point + p) + k];
      chunk.points[4 * p + 3] = values ? values->values[first_point + p] : 0.0f;
    }
    chunk.segments.reserve(segments);
    chunk.aabbs.reserve(6 * segments);
    for (uint64_t l = chunk.first_line; l < line; ++l) {
      const uint64_t begin = lines.line_offsets[l], end = lines.line_offsets[l + 1];
      for (uint64_t p = begin; p + 1 < end; ++p) {
        const uint64_t local = p - first_point;
        const uint32_t flags =
            (p > begin ? kCapsuleHasPrevious : 0u) | (p + 2 < end ? kCapsuleHasNext : 0u);
        chunk.segments.push_back(uint32_t(local << 2) | flags);
        // The capsule's box: both end spheres, padded against float rounding.
        const float* a = &chunk.points[4 * local];
        const float* b = a + 4;
        for (int k = 0; k < 3; ++k) {
          const float pad = radius * 1.001f + 1e-6f * std::max(std::fabs(a[k]), std::fabs(b[k]));
          chunk.aabbs.push_back(std::min(a[k], b[k]) - pad);
        }
        for (int k = 0; k < 3; ++k) {
          const float pad = radius * 1.001f + 1e-6f * std::max(std::fabs(a[k]), std::fabs(b[k]));
          chunk.aabbs.push_back(std::max(a[k], b[k]) + pad);
        }
      }
    }
    if (!chunk.segments.empty()) out.chunks.push_back(std::move(chunk));
  }
  return out;
}

}  // namespace linebake
