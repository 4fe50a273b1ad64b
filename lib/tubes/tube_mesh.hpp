#pragma once
// The tube mesh: what the rasterisation techniques and the triangle ray tracers draw. Each
// polyline point carries a ring of `sides` shared vertices; each segment is 2*sides triangles.
// Stored the way the paper stores it (32-bit positions, normals and indices, a 16-bit attribute)
// and cut into chunks at line boundaries so 32-bit indices and 4 GiB buffers suffice.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "core/array.hpp"
#include "lines/line_set.hpp"

namespace linebake {

enum class NormalEncoding { Float32, Oct16 };
const char* to_string(NormalEncoding encoding);
NormalEncoding parse_normal_encoding(const std::string& name);  // "float32" | "oct16"

struct TubeChunk {
  uint64_t first_line = 0;  // source lines [first_line, first_line + line_count)
  uint64_t line_count = 0;
  Array<float> positions;      // x y z per vertex
  Array<float> normals;        // x y z per vertex (NormalEncoding::Float32)
  Array<int16_t> normals_oct;  // octahedral snorm16 pair per vertex (NormalEncoding::Oct16)
  Array<uint16_t> attribute;   // unorm16 over TubeMesh::attribute_range; empty without attribute
  Array<uint32_t> indices;     // 3 per triangle, counter-clockwise seen from outside

  uint64_t vertex_count() const { return positions.size() / 3; }
  uint64_t triangle_count() const { return indices.size() / 3; }
  uint64_t bytes() const {
    return positions.bytes() + normals.bytes() + normals_oct.bytes() + attribute.bytes() +
           indices.bytes();
  }
};

struct TubeMesh {
  int sides = 3;
  float radius = 0;  // world units (per-point radii are scaled from it)
  bool caps = false;
  NormalEncoding normals = NormalEncoding::Float32;
  std::string attribute;                   // name of the stored attribute, "" if none
  std::array<float, 2> attribute_range{};  // value mapped to unorm 0 and 65535
  uint64_t lines_dropped = 0;              // lines with fewer than two distinct points
  uint64_t points_skipped = 0;  // points closer than min_point_distance to the previous one
  std::vector<TubeChunk> chunks;

  uint64_t vertex_count() const;
  uint64_t triangle_count() const;
  uint64_t bytes() const;
};

// A mesh's size without its arrays (cache/tube_store.hpp's load_tube_counts).
struct TubeCounts {
  uint64_t vertices = 0, triangles = 0;
};

// Bounding box of every vertex position (the tube surface, radius included).
Bounds compute_bounds(const TubeMesh& mesh);

// Vertex bytes for a layout, used for chunk budgets and reports.
uint64_t tube_vertex_bytes(NormalEncoding normals, bool has_attribute);

// Octahedral normal encoding (Cigolle et al. 2014), snorm16 per component.
std::array<int16_t, 2> encode_octahedral(float x, float y, float z);
std::array<float, 3> decode_octahedral(int16_t u, int16_t v);

// Unpacks the stored attribute value back to the data range.
inline float decode_unorm16(uint16_t value, std::array<float, 2> range) {
  return range[0] + (range[1] - range[0]) * (float(value) / 65535.0f);
}

}  // namespace linebake
