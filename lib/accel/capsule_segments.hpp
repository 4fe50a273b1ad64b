#pragma once
// The analytic tube primitive for hardware ray tracing (`rtx --rtx-geometry capsules`): the same
// capsule chains as Embree's `capsules` geometry (accel/capsule_chain.hpp), laid out for a
// Vulkan AABB BLAS and its intersection shader (shaders/capsule.glsl). Lines are split at line
// boundaries into chunks, one BLAS each.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "lines/line_set.hpp"

namespace linebake {

// Segment word: first point (chunk-local) << 2 | neighbour flags.
constexpr uint32_t kCapsuleHasPrevious = 1;  // the segment before shares the first point
constexpr uint32_t kCapsuleHasNext = 2;      // the segment after shares the last point

struct CapsuleChunk {
  uint64_t first_line = 0, line_count = 0;
  std::vector<float> points;       // x, y, z, attribute value per point (0 without attribute)
  std::vector<uint32_t> segments;  // one word per segment (above)
  std::vector<float> aabbs;        // min xyz, max xyz per segment (VkAabbPositionsKHR)

  uint64_t segment_count() const { return segments.size(); }
  uint64_t bytes() const { return 4 * (points.size() + segments.size() + aabbs.size()); }
};

struct CapsuleSegments {
  float radius = 0;
  std::string attribute;
  std::array<float, 2> attribute_range{};  // min and max of the attribute's finite values
  std::vector<CapsuleChunk> chunks;
  uint64_t segment_count() const;
  uint64_t bytes() const;
};

// What build_capsule_segments holds for `lines` (points with their values, segment words,
// boxes), to check against a memory budget before building.
uint64_t capsule_segments_bytes(const LineSet& lines);

// Throws Error for a non-positive radius, an unknown attribute or max_segments_per_chunk < 1;
// a single line longer than the chunk limit gets a chunk of its own (2^30 segments at most).
CapsuleSegments build_capsule_segments(const LineSet& lines, float radius,
                                       const std::string& attribute,
                                       uint64_t max_segments_per_chunk = uint64_t{1} << 28);

}  // namespace linebake
