#include "tubes/tube_mesh.hpp"

#include <algorithm>
#include <cmath>

#include "core/error.hpp"

namespace linebake {

const char* to_string(NormalEncoding encoding) {
  return encoding == NormalEncoding::Oct16 ? "oct16" : "float32";
}

NormalEncoding parse_normal_encoding(const std::string& name) {
  if (name == "float32") return NormalEncoding::Float32;
  if (name == "oct16") return NormalEncoding::Oct16;
  throw Error("unknown normal encoding '" + name + "' (float32 | oct16)");
}

uint64_t TubeMesh::vertex_count() const {
  uint64_t n = 0;
  for (const TubeChunk& c : chunks) n += c.vertex_count();
  return n;
}

uint64_t TubeMesh::triangle_count() const {
  uint64_t n = 0;
  for (const TubeChunk& c : chunks) n += c.triangle_count();
  return n;
}

uint64_t TubeMesh::bytes() const {
  uint64_t n = 0;
  for (const TubeChunk& c : chunks) n += c.bytes();
  return n;
}

uint64_t tube_vertex_bytes(NormalEncoding normals, bool has_attribute) {
  return 12 + (normals == NormalEncoding::Oct16 ? 4 : 12) + (has_attribute ? 2 : 0);
}

static int16_t to_snorm16(float v) {
  const float scaled = std::clamp(v, -1.0f, 1.0f) * 32767.0f;  // round half away from zero
  return static_cast<int16_t>(scaled >= 0 ? scaled + 0.5f : scaled - 0.5f);
}

std::array<int16_t, 2> encode_octahedral(float x, float y, float z) {
  const float l1 = std::fabs(x) + std::fabs(y) + std::fabs(z);
  float u = x / l1, v = y / l1;
  if (z < 0) {
    const float fu = (1 - std::fabs(v)) * (u >= 0 ? 1.0f : -1.0f);
    const float fv = (1 - std::fabs(u)) * (v >= 0 ? 1.0f : -1.0f);
    u = fu;
    v = fv;
  }
  return {to_snorm16(u), to_snorm16(v)};
}

std::array<float, 3> decode_octahedral(int16_t su, int16_t sv) {
  const float u = std::max(float(su) / 32767.0f, -1.0f), v = std::max(float(sv) / 32767.0f, -1.0f);
  float x = u, y = v;
  const float z = 1 - std::fabs(u) - std::fabs(v);
  if (z < 0) {
    x = (1 - std::fabs(v)) * (u >= 0 ? 1.0f : -1.0f);
    y = (1 - std::fabs(u)) * (v >= 0 ? 1.0f : -1.0f);
  }
  const float len = std::sqrt(x * x + y * y + z * z);
  return {x / len, y / len, z / len};
}

Bounds compute_bounds(const TubeMesh& mesh) {
  Bounds b;
  for (const TubeChunk& chunk : mesh.chunks)
    include_points(b, std::span<const float>(chunk.positions.data(), chunk.positions.size()));
  return b;
}

}  // namespace linebake
