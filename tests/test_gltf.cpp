// glb export: the file parsed independently (GLB chunks + JSON), every array compared with the
// mesh it came from; Draco primitives decoded with libdraco.

#include <draco/compression/decode.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "formats/gltf.hpp"
#include "test_util.hpp"
#include "tubes/tube_builder.hpp"

namespace linebake {
namespace {

using nlohmann::json;

struct Glb {
  json doc;
  std::vector<unsigned char> bin;
};

uint32_t u32(const std::vector<unsigned char>& b, size_t at) {
  uint32_t v;
  std::memcpy(&v, b.data() + at, 4);
  return v;
}

std::vector<unsigned char> read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

Glb read_glb(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::vector<unsigned char> b((std::istreambuf_iterator<char>(in)), {});
  EXPECT_GE(b.size(), 20u);
  EXPECT_EQ(std::memcmp(b.data(), "glTF", 4), 0);
  EXPECT_EQ(u32(b, 4), 2u);
  EXPECT_EQ(u32(b, 8), b.size());
  const uint32_t json_length = u32(b, 12);
  EXPECT_EQ(u32(b, 16), 0x4E4F534Au);  // "JSON"
  EXPECT_EQ(json_length % 4, 0u);
  Glb glb;
  glb.doc = json::parse(b.begin() + 20, b.begin() + 20 + json_length);
  const size_t bin_at = 20 + json_length;
  if (bin_at < b.size()) {
    EXPECT_EQ(u32(b, bin_at + 4), 0x004E4942u);  // "BIN\0"
    glb.bin.assign(b.begin() + bin_at + 8, b.begin() + bin_at + 8 + u32(b, bin_at));
  }
  return glb;
}

// Bytes of an accessor's elements, de-strided.
template <class T>
std::vector<T> accessor_values(const Glb& glb, int index, int components) {
  const json& a = glb.doc["accessors"][index];
  const json& v = glb.doc["bufferViews"][a["bufferView"].get<int>()];
  const size_t stride = v.value("byteStride", size_t(sizeof(T) * components));
  const size_t base = v.value("byteOffset", size_t{0}) + a.value("byteOffset", size_t{0});
  const size_t count = a["count"];
  std::vector<T> out(count * components);
  for (size_t i = 0; i < count; ++i)
    std::memcpy(&out[i * components], glb.bin.data() + base + i * stride, sizeof(T) * components);
  return out;
}

LineSet spiral_lines(int count) {
  LineSet lines;
  lines.attributes.push_back({"temperature", {}});
  for (int l = 0; l < count; ++l) {
    for (int i = 0; i < 20 + l % 7; ++i) {
      const double t = 0.3 * i;
      lines.append_point(float(std::cos(t) + 3 * l), float(std::sin(t)), float(0.1 * t * l));
      lines.attributes[0].values.push_back(float(l * 100 + i));
    }
    lines.end_line();
  }
  return lines;
}

// The tubes of `lines` in chunks of at most 40 kB: several chunks, several primitives.
TubeMesh chunked_tubes(const LineSet& lines) {
  TubeOptions o;
  o.max_chunk_bytes = 40000;
  return build_tubes(lines, o);
}

// A plain primitive's POSITION, NORMAL and _ATTRIBUTE hold the chunk's arrays to the byte (raw
// axes).
void expect_chunk_arrays(const Glb& glb, const json& p, const TubeChunk& chunk) {
  const auto pos = accessor_values<float>(glb, p["attributes"]["POSITION"], 3);
  EXPECT_EQ(std::memcmp(pos.data(), chunk.positions.data(), chunk.positions.bytes()), 0);
  const auto nrm = accessor_values<float>(glb, p["attributes"]["NORMAL"], 3);
  EXPECT_EQ(std::memcmp(nrm.data(), chunk.normals.data(), chunk.normals.bytes()), 0);
  const auto attr = accessor_values<uint16_t>(glb, p["attributes"]["_ATTRIBUTE"], 1);
  EXPECT_EQ(std::memcmp(attr.data(), chunk.attribute.data(), chunk.attribute.bytes()), 0);
}

TEST(Gltf, PlainExportHoldsTheMeshExactly) {
  test::TempDir dir;
  const LineSet lines = spiral_lines(40);
  const TubeMesh mesh = chunked_tubes(lines);
  ASSERT_GT(mesh.chunks.size(), 2u);
  GltfOptions raw;
  raw.axes = GltfAxes::Raw;
  raw.line_strips = true;
  write_gltf(dir.file("t.glb"), &mesh, &lines, raw);
  const Glb glb = read_glb(dir.file("t.glb"));
  EXPECT_EQ(glb.doc["asset"]["version"], "2.0");
  const json& tubes = glb.doc["meshes"][0];
  EXPECT_EQ(tubes["extras"]["linebake_attribute"], "temperature");
  EXPECT_FLOAT_EQ(tubes["extras"]["linebake_attribute_range"][1].get<float>(),
                  mesh.attribute_range[1]);
  ASSERT_EQ(tubes["primitives"].size(), mesh.chunks.size());
  for (size_t c = 0; c < mesh.chunks.size(); ++c) {
    const json& p = tubes["primitives"][c];
    const TubeChunk& chunk = mesh.chunks[c];
    EXPECT_EQ(p["mode"], 4);
    expect_chunk_arrays(glb, p, chunk);
    EXPECT_TRUE(glb.doc["accessors"][p["attributes"]["_ATTRIBUTE"].get<int>()]["normalized"]);
    const auto idx = accessor_values<uint32_t>(glb, p["indices"], 1);
    EXPECT_EQ(std::memcmp(idx.data(), chunk.indices.data(), chunk.indices.bytes()), 0);
    // POSITION min/max are required and must bound the data.
    const json& a = glb.doc["accessors"][p["attributes"]["POSITION"].get<int>()];
    for (size_t v = 0; v < chunk.vertex_count(); ++v)
      for (int k = 0; k < 3; ++k) {
        EXPECT_GE(chunk.positions[3 * v + k], a["min"][k].get<float>());
        EXPECT_LE(chunk.positions[3 * v + k], a["max"][k].get<float>());
      }
  }
  // --line-strips: one LINE_STRIP per polyline over a shared, strided view.
  const json& strips = glb.doc["meshes"][1]["primitives"];
  ASSERT_EQ(strips.size(), lines.line_count());
  for (size_t l = 0; l < lines.line_count(); ++l) {
    EXPECT_EQ(strips[l]["mode"], 3);
    const auto pos = accessor_values<float>(glb, strips[l]["attributes"]["POSITION"], 3);
    EXPECT_EQ(
        std::memcmp(pos.data(), lines.positions.data() + 3 * lines.line_offsets[l], pos.size() * 4),
        0);
  }
}

double surface_area(const float* p, const uint32_t* idx, size_t triangles) {
  double area = 0;
  for (size_t t = 0; t < triangles; ++t) {
    const float* a = p + 3 * idx[3 * t];
    const float* b = p + 3 * idx[3 * t + 1];
    const float* c = p + 3 * idx[3 * t + 2];
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                         u[0] * v[1] - u[1] * v[0]};
    area += 0.5 * std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  }
  return area;
}

// A Draco primitive decoded with libdraco: its points' positions, its faces' indices, and the
// mesh (for its other attributes).
struct DecodedPrimitive {
  std::unique_ptr<draco::Mesh> mesh;
  std::vector<float> positions;
  std::vector<uint32_t> indices;
};
DecodedPrimitive decode_primitive(const Glb& glb, const json& primitive) {
  const json& ext = primitive["extensions"]["KHR_draco_mesh_compression"];
  const json& view = glb.doc["bufferViews"][ext["bufferView"].get<int>()];
  draco::DecoderBuffer buffer;
  buffer.Init(reinterpret_cast<const char*>(glb.bin.data()) + view.value("byteOffset", 0),
              view["byteLength"].get<size_t>());
  draco::Decoder decoder;
  auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
  if (!decoded.ok()) throw Error("Draco: " + decoded.status().error_msg_string());
  DecodedPrimitive out{std::move(decoded).value(), {}, {}};
  const draco::Mesh& d = *out.mesh;
  const draco::PointAttribute* pa =
      d.GetAttributeByUniqueId(ext["attributes"]["POSITION"].get<uint32_t>());
  if (!pa) throw Error("Draco: no POSITION");
  out.positions.resize(3 * d.num_points());
  for (uint32_t v = 0; v < d.num_points(); ++v)
    pa->GetMappedValue(draco::PointIndex(v), &out.positions[3 * v]);
  for (uint32_t f = 0; f < d.num_faces(); ++f)
    for (int k = 0; k < 3; ++k) out.indices.push_back(d.face(draco::FaceIndex(f))[k].value());
  return out;
}

// The tubes the Draco tests export: 6 sides with caps, in chunks of at most 60 kB.
TubeMesh capped_tubes() {
  TubeOptions o;
  o.sides = 6;
  o.caps = true;
  o.max_chunk_bytes = 60000;
  return build_tubes(spiral_lines(30), o);
}

TEST(Gltf, DracoPrimitivesDecodeToTheSameMesh) {
  test::TempDir dir;
  const TubeMesh mesh = capped_tubes();
  GltfOptions g;
  g.draco = true;
  write_gltf(dir.file("d.glb"), &mesh, nullptr, g);
  const Glb glb = read_glb(dir.file("d.glb"));
  EXPECT_EQ(glb.doc["extensionsRequired"][0], "KHR_draco_mesh_compression");
  const json& prims = glb.doc["meshes"][0]["primitives"];
  ASSERT_EQ(prims.size(), mesh.chunks.size());
  for (size_t c = 0; c < mesh.chunks.size(); ++c) {
    const TubeChunk& chunk = mesh.chunks[c];
    const json& ext = prims[c]["extensions"]["KHR_draco_mesh_compression"];
    const DecodedPrimitive decoded = decode_primitive(glb, prims[c]);
    const draco::Mesh& d = *decoded.mesh;
    EXPECT_EQ(d.num_faces(), chunk.triangle_count());
    EXPECT_EQ(glb.doc["accessors"][prims[c]["indices"].get<int>()]["count"].get<size_t>(),
              3 * d.num_faces());
    EXPECT_EQ(glb.doc["accessors"][prims[c]["attributes"]["POSITION"].get<int>()]["count"],
              d.num_points());
    // Same surface (order-free comparison), within 14-bit position quantisation.
    const std::vector<float>& pos = decoded.positions;
    const std::vector<uint32_t>& idx = decoded.indices;
    const double expected =
        surface_area(chunk.positions.data(), chunk.indices.data(), chunk.triangle_count());
    EXPECT_NEAR(surface_area(pos.data(), idx.data(), d.num_faces()), expected, 1e-3 * expected);
    EXPECT_NE(d.GetAttributeByUniqueId(ext["attributes"]["_ATTRIBUTE"].get<uint32_t>()), nullptr);
  }
}

// KHR_draco_mesh_compression: POSITION's min and max are the decompressed data's. At 4 bits the
// quantised positions reach well past the input's box (the input's bounds had been written).
TEST(Gltf, DracoPositionBoundsAreTheDecodedOnes) {
  test::TempDir dir;
  const TubeMesh mesh = capped_tubes();
  GltfOptions g;
  g.draco = true;
  g.draco_position_bits = 4;
  write_gltf(dir.file("d.glb"), &mesh, nullptr, g);
  const Glb glb = read_glb(dir.file("d.glb"));
  size_t past_the_input = 0;
  for (const json& primitive : glb.doc["meshes"][0]["primitives"]) {
    const json& accessor = glb.doc["accessors"][primitive["attributes"]["POSITION"].get<int>()];
    const std::vector<float> pos = decode_primitive(glb, primitive).positions;
    for (int k = 0; k < 3; ++k) {
      float lo = INFINITY, hi = -INFINITY;
      for (size_t i = size_t(k); i < pos.size(); i += 3)
        lo = std::min(lo, pos[i]), hi = std::max(hi, pos[i]);
      EXPECT_EQ(accessor["min"][k].get<double>(), double(lo)) << k;
      EXPECT_EQ(accessor["max"][k].get<double>(), double(hi)) << k;
    }
  }
  // The quantisation moved some bound past the input's own (what the test is about).
  const Bounds input = compute_bounds(mesh);
  for (const json& primitive : glb.doc["meshes"][0]["primitives"]) {
    const json& accessor = glb.doc["accessors"][primitive["attributes"]["POSITION"].get<int>()];
    for (int k = 0; k < 3; ++k)
      past_the_input += accessor["max"][k].get<double>() > double(input.max[size_t(k)]) + 1e-6 ||
                        accessor["min"][k].get<double>() < double(input.min[size_t(k)]) - 1e-6;
  }
  EXPECT_GT(past_the_input, 0u);
}

// A chunk larger than the pieces the plain export converts at a time (262,144 vertices) holds the
// mesh exactly, to the byte, with bounds that are the data's own: the pieces meet.
TEST(Gltf, PlainExportOfAChunkLargerThanItsPiecesIsExact) {
  test::TempDir dir;
  const LineSet lines = spiral_lines(4000);  // about 94,000 points, 3 ring vertices each
  const TubeMesh mesh = build_tubes(lines, {});
  ASSERT_EQ(mesh.chunks.size(), 1u);
  const TubeChunk& chunk = mesh.chunks[0];
  ASSERT_GT(chunk.vertex_count(), uint64_t{1} << 18);
  GltfOptions raw;
  raw.axes = GltfAxes::Raw;
  write_gltf(dir.file("t.glb"), &mesh, nullptr, raw);
  const Glb glb = read_glb(dir.file("t.glb"));
  const json& p = glb.doc["meshes"][0]["primitives"][0];
  expect_chunk_arrays(glb, p, chunk);
  const auto tex = accessor_values<uint16_t>(glb, p["attributes"]["TEXCOORD_0"], 2);
  for (uint64_t v = 0; v < chunk.vertex_count(); v += 9973) {
    EXPECT_EQ(tex[2 * v], chunk.attribute[v]);
    EXPECT_EQ(tex[2 * v + 1], 32768);
  }
  const json& a = glb.doc["accessors"][p["attributes"]["POSITION"].get<int>()];
  for (int k = 0; k < 3; ++k) {
    float lo = chunk.positions[k], hi = lo;
    for (uint64_t v = 0; v < chunk.vertex_count(); ++v)
      lo = std::min(lo, chunk.positions[3 * v + k]), hi = std::max(hi, chunk.positions[3 * v + k]);
    EXPECT_EQ(a["min"][k].get<float>(), lo);
    EXPECT_EQ(a["max"][k].get<float>(), hi);
  }
}

// Draco in pieces of at most N vertices, cut between lines: every piece decodes, together they
// hold every triangle and the same surface; with pieces of one vertex, one piece a line.
TEST(Gltf, DracoPiecesHoldTheMeshBetweenThem) {
  test::TempDir dir;
  const TubeMesh mesh = capped_tubes();
  uint64_t triangles = 0, line_count = 0;
  double area = 0;
  for (const TubeChunk& chunk : mesh.chunks) {
    triangles += chunk.triangle_count();
    line_count += chunk.line_count;
    area += surface_area(chunk.positions.data(), chunk.indices.data(), chunk.triangle_count());
  }
  for (const uint64_t piece : {uint64_t{1} << 19, uint64_t{300}, uint64_t{1}}) {
    GltfOptions g;
    g.draco = true;
    g.draco_piece_vertices = piece;
    write_gltf(dir.file("p.glb"), &mesh, nullptr, g);
    const Glb glb = read_glb(dir.file("p.glb"));
    const json& prims = glb.doc["meshes"][0]["primitives"];
    uint64_t faces = 0, most = 0;
    double decoded_area = 0;
    for (const json& prim : prims) {
      const DecodedPrimitive decoded = decode_primitive(glb, prim);
      const draco::Mesh& d = *decoded.mesh;
      const std::vector<float>& pos = decoded.positions;
      const std::vector<uint32_t>& idx = decoded.indices;
      faces += d.num_faces();
      most = std::max<uint64_t>(most, d.num_points());
      decoded_area += surface_area(pos.data(), idx.data(), d.num_faces());
      // The accessor's bounds hold the piece (glTF's min and max, in the output's axes).
      const json& position = glb.doc["accessors"][prim["attributes"]["POSITION"].get<int>()];
      for (uint32_t v = 0; v < d.num_points(); ++v)
        for (int k = 0; k < 3; ++k) {
          EXPECT_GE(pos[3 * v + k], position["min"][k].get<double>() - 1e-3);
          EXPECT_LE(pos[3 * v + k], position["max"][k].get<double>() + 1e-3);
        }
    }
    EXPECT_EQ(faces, triangles) << piece;
    EXPECT_NEAR(decoded_area, area, 1e-3 * area) << piece;
    if (piece == uint64_t{1} << 19) {
      EXPECT_EQ(prims.size(), mesh.chunks.size());
    }
    if (piece == 300) {
      EXPECT_GT(prims.size(), mesh.chunks.size());
      EXPECT_LT(prims.size(), line_count);
      EXPECT_LE(most, 300u);  // every line has fewer vertices: a cut always comes in time
    }
    if (piece == 1) {
      EXPECT_EQ(prims.size(), line_count);
    }
  }
}

// A piece that cannot be cut (a line longer than the piece) past the limit a budget sets is
// refused before it is encoded, and nothing is written.
TEST(Gltf, DracoPieceThatCannotBeCutPastItsLimitIsRefused) {
  test::TempDir dir;
  const TubeMesh mesh = build_tubes(spiral_lines(3), {});
  GltfOptions g;
  g.draco = true;
  g.draco_piece_vertices = 1;
  g.draco_max_piece_vertices = 10;  // every line has more
  EXPECT_THROW(write_gltf(dir.file("p.glb"), &mesh, nullptr, g), BudgetExceeded);
  EXPECT_TRUE(dir.entries().empty());
  g.draco_max_piece_vertices = 0;
  write_gltf(dir.file("p.glb"), &mesh, nullptr, g);
  EXPECT_EQ(dir.entries().size(), 1u);
}

// The default output: glTF's +y is the data's +z, COLOR_0 from the colour map, TEXCOORD_0 the
// normalised attribute, the lines one indexed LINES primitive. Written as .gltf + .bin, which
// must hold the same bytes a .glb holds.
TEST(Gltf, DefaultAxesColoursAndIndexedLines) {
  test::TempDir dir;
  const LineSet lines = spiral_lines(12);
  const TubeMesh mesh = chunked_tubes(lines);
  GltfOptions g;
  for (int i = 0; i < 256; ++i) g.colour_map.push_back({uint8_t(i), uint8_t(255 - i), 7});
  write_gltf(dir.file("d.gltf"), &mesh, &lines, g);
  write_gltf(dir.file("d.glb"), &mesh, &lines, g);
  Glb gltf;
  gltf.doc = json::parse(read_bytes(dir.file("d.gltf")));
  EXPECT_EQ(gltf.doc["buffers"][0]["uri"], "d.bin");
  gltf.bin = read_bytes(dir.file("d.bin"));
  EXPECT_EQ(gltf.doc["buffers"][0]["byteLength"].get<size_t>(), gltf.bin.size());
  const Glb glb = read_glb(dir.file("d.glb"));
  EXPECT_EQ(glb.bin, gltf.bin);
  EXPECT_EQ(glb.doc["accessors"], gltf.doc["accessors"]);

  const json& tubes = gltf.doc["meshes"][0]["primitives"];
  ASSERT_EQ(tubes.size(), mesh.chunks.size());
  for (size_t c = 0; c < mesh.chunks.size(); ++c) {
    const TubeChunk& chunk = mesh.chunks[c];
    const json& at = tubes[c]["attributes"];
    const auto pos = accessor_values<float>(gltf, at["POSITION"], 3);
    const auto nrm = accessor_values<float>(gltf, at["NORMAL"], 3);
    const auto uv = accessor_values<uint16_t>(gltf, at["TEXCOORD_0"], 2);
    const auto rgba = accessor_values<uint8_t>(gltf, at["COLOR_0"], 4);
    ASSERT_EQ(pos.size(), chunk.positions.size());
    for (size_t v = 0; v < chunk.vertex_count(); ++v) {
      // (x, y, z) -> (x, z, -y)
      EXPECT_EQ(pos[3 * v], chunk.positions[3 * v]);
      EXPECT_EQ(pos[3 * v + 1], chunk.positions[3 * v + 2]);
      EXPECT_EQ(pos[3 * v + 2], -chunk.positions[3 * v + 1]);
      EXPECT_EQ(nrm[3 * v + 1], chunk.normals[3 * v + 2]);
      EXPECT_EQ(nrm[3 * v + 2], -chunk.normals[3 * v + 1]);
      EXPECT_EQ(uv[2 * v], chunk.attribute[v]);
      EXPECT_EQ(uv[2 * v + 1], 32768);
      const int entry = int(std::lround(chunk.attribute[v] / 65535.0 * 255.0));
      EXPECT_EQ(rgba[4 * v], entry);
      EXPECT_EQ(rgba[4 * v + 1], 255 - entry);
      EXPECT_EQ(rgba[4 * v + 3], 255);
    }
  }
  // One LINES primitive: a segment for each pair of consecutive points of a polyline.
  const json& prims = gltf.doc["meshes"][1]["primitives"];
  ASSERT_EQ(prims.size(), 1u);
  EXPECT_EQ(prims[0]["mode"], 1);
  const auto idx = accessor_values<uint32_t>(gltf, prims[0]["indices"], 1);
  EXPECT_EQ(idx.size(), 2 * (lines.point_count() - lines.line_count()));
  size_t at = 0;
  for (size_t l = 0; l < lines.line_count(); ++l)
    for (uint64_t p = lines.line_offsets[l]; p + 1 < lines.line_offsets[l + 1]; ++p, at += 2) {
      EXPECT_EQ(idx[at], p);
      EXPECT_EQ(idx[at + 1], p + 1);
    }
  const auto uv = accessor_values<uint16_t>(gltf, prims[0]["attributes"]["TEXCOORD_0"], 2);
  const auto& values = lines.attributes[0].values;
  // A colour range of its own (a transfer function's): the lower half of the data spans the map,
  // the upper half takes its last colour.
  const float middle = 0.5f * (mesh.attribute_range[0] + mesh.attribute_range[1]);
  g.colour_range = {mesh.attribute_range[0], middle};
  write_gltf(dir.file("half.glb"), &mesh, nullptr, g);
  const Glb half = read_glb(dir.file("half.glb"));
  const json& first = half.doc["meshes"][0]["primitives"][0]["attributes"];
  const auto half_rgba = accessor_values<uint8_t>(half, first["COLOR_0"], 4);
  const TubeChunk& chunk = mesh.chunks[0];
  for (size_t v = 0; v < chunk.vertex_count(); ++v) {
    const double t = std::min(1.0, 2.0 * chunk.attribute[v] / 65535.0);
    EXPECT_NEAR(half_rgba[4 * v], t * 255.0, 0.5 + 1e-3) << v;
  }
  const float lo = *std::min_element(values.begin(), values.end());
  const float hi = *std::max_element(values.begin(), values.end());
  for (size_t p = 0; p < lines.point_count(); ++p)
    EXPECT_NEAR(uv[2 * p] / 65535.0, (values[p] - lo) / (hi - lo), 1.0 / 65535);
}

// A mesh given a chunk at a time: each chunk is read twice (laid out, then written) and never
// kept, Draco's chunks encoded once (kept in a spill file, which goes), the bytes those of the
// whole mesh's export; a chunk that changes between the passes is an error, and nothing is left.
// The lines' _ATTRIBUTE is stored as the tubes' is, normalised UNSIGNED_SHORT over the range in
// the mesh's extras (the finite values' range): it had been the raw floats, NaN and infinities
// included, which glTF forbids in accessor data. NaN takes the range's low end, infinities its
// ends. Both the LINES primitive and the strips.
TEST(Gltf, TheLinesAttributeIsNormalisedAndHoldsNoNaN) {
  test::TempDir dir;
  LineSet lines;
  lines.attributes.push_back({"a", {}});
  const float values[] = {1, std::nanf(""), 3, 4, std::numeric_limits<float>::infinity(), 2};
  for (int i = 0; i < 6; ++i) {
    lines.append_point(float(i), float(i % 2), 0);
    lines.attributes[0].values.push_back(values[i]);
    if (i == 3) lines.end_line();
  }
  lines.end_line();
  // Hand-computed over the range [1, 4]: (v - 1) / 3 x 65535, rounded.
  const std::vector<uint16_t> expected = {0, 0, 43690, 65535, 65535, 21845};
  for (const bool strips : {false, true}) {
    GltfOptions g;
    g.line_strips = strips;
    write_gltf(dir.file("l.glb"), static_cast<const TubeMesh*>(nullptr), &lines, g);
    const Glb glb = read_glb(dir.file("l.glb"));
    const json& mesh = glb.doc["meshes"][0];
    EXPECT_EQ(mesh["extras"]["linebake_attribute_range"], json::array({1.0, 4.0}));
    std::vector<uint16_t> got;
    for (const json& p : mesh["primitives"]) {
      const int index = p["attributes"]["_ATTRIBUTE"];
      const json& a = glb.doc["accessors"][index];
      EXPECT_EQ(a["componentType"], 5123);  // UNSIGNED_SHORT
      EXPECT_TRUE(a["normalized"]);
      const std::vector<uint16_t> v = accessor_values<uint16_t>(glb, index, 1);
      got.insert(got.end(), v.begin(), v.end());
    }
    EXPECT_EQ(got, expected) << (strips ? "strips" : "lines");
  }
}

// Beside tubes the lines carry the tubes' attribute over the tubes' range (a line attribute
// repeated along its line); they had carried the first point attribute over its own range.
TEST(Gltf, TheLinesCarryTheTubesAttribute) {
  test::TempDir dir;
  LineSet lines;
  lines.attributes = {{"first", {}}, {"chosen", {}}};
  lines.line_attributes = {{"per_line", {10, 30}}};
  for (int i = 0; i < 6; ++i) {
    lines.append_point(float(i), float(i % 2), 0);
    lines.attributes[0].values.push_back(float(100 + i));
    lines.attributes[1].values.push_back(float(i));
    if (i == 3) lines.end_line();
  }
  lines.end_line();
  struct Case {
    const char* attribute;
    std::array<float, 2> range;
    std::vector<uint16_t> expected;  // hand-computed: (v - lo) / (hi - lo) x 65535, rounded
  };
  const Case cases[] = {
      {"chosen", {0, 10}, {0, 6554, 13107, 19661, 26214, 32768}},
      {"per_line", {0, 40}, {16384, 16384, 16384, 16384, 49151, 49151}},
  };
  for (const Case& c : cases) {
    TubeOptions o;
    o.attribute = c.attribute;
    o.attribute_range = c.range;
    const TubeMesh mesh = build_tubes(lines, o);
    ASSERT_EQ(mesh.attribute, c.attribute);
    for (const bool strips : {false, true}) {
      GltfOptions g;
      g.line_strips = strips;
      write_gltf(dir.file("l.glb"), &mesh, &lines, g);
      const Glb glb = read_glb(dir.file("l.glb"));
      const json* line_mesh = nullptr;
      for (const json& m : glb.doc["meshes"])
        if (m["name"] == "lines") line_mesh = &m;
      ASSERT_NE(line_mesh, nullptr);
      EXPECT_EQ((*line_mesh)["extras"]["linebake_attribute"], c.attribute);
      EXPECT_EQ((*line_mesh)["extras"]["linebake_attribute_range"],
                json::array({double(c.range[0]), double(c.range[1])}));
      std::vector<uint16_t> got;
      for (const json& p : (*line_mesh)["primitives"]) {
        const std::vector<uint16_t> v =
            accessor_values<uint16_t>(glb, p["attributes"]["_ATTRIBUTE"], 1);
        got.insert(got.end(), v.begin(), v.end());
      }
      EXPECT_EQ(got, c.expected) << c.attribute << (strips ? " strips" : " lines");
    }
  }
}

TEST(Gltf, ChunksAreReadOneAtATimeInTwoPasses) {
  test::TempDir dir;
  const LineSet lines = spiral_lines(40);
  const TubeMesh mesh = chunked_tubes(lines);
  ASSERT_GT(mesh.chunks.size(), 2u);
  TubeMesh description = mesh;
  for (TubeChunk& chunk : description.chunks) {
    TubeChunk place;
    place.first_line = chunk.first_line;
    place.line_count = chunk.line_count;
    chunk = place;
  }
  std::vector<int> reads(mesh.chunks.size(), 0);
  TubeChunks chunks{description, [&](size_t index) {
                      ++reads.at(index);
                      return mesh.chunks.at(index);
                    }};
  for (const bool draco : {false, true}) {
    GltfOptions g;
    g.draco = draco;
    std::fill(reads.begin(), reads.end(), 0);
    write_gltf(dir.file("chunks.glb"), &chunks, &lines, g);
    EXPECT_EQ(reads, std::vector<int>(mesh.chunks.size(), draco ? 1 : 2)) << draco;
    write_gltf(dir.file("whole.glb"), &mesh, &lines, g);
    EXPECT_EQ(read_bytes(dir.file("chunks.glb")), read_bytes(dir.file("whole.glb"))) << draco;
  }
  EXPECT_EQ(dir.entries().size(), 2u);  // no spill file left

  // The second pass finds a chunk other than the first did: shorter, or of the same size with
  // one position moved (the accessors' bounds would no longer hold).
  TubeChunk shorter = mesh.chunks[1];
  shorter.indices =
      Array<uint32_t>(shorter.indices.owner(), shorter.indices.data(), shorter.indices.size() - 3);
  TubeChunk moved = mesh.chunks[1];
  moved.positions = Array<float>(mesh.chunks[1].positions.size());
  std::copy(mesh.chunks[1].positions.begin(), mesh.chunks[1].positions.end(),
            moved.positions.begin());
  moved.positions[4] += 1.0f;
  for (const TubeChunk* other : {&shorter, &moved}) {
    std::fill(reads.begin(), reads.end(), 0);
    const TubeChunks changing{description, [&](size_t index) {
                                return ++reads.at(index) == 2 && index == 1 ? *other
                                                                            : mesh.chunks.at(index);
                              }};
    try {
      write_gltf(dir.file("changed.glb"), &changing, nullptr);
      ADD_FAILURE() << "a chunk that changed between the passes was written";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("changed between the export's two passes"),
                std::string::npos)
          << e.what();
    }
    EXPECT_EQ(dir.entries().size(), 2u);
  }
}

TEST(Gltf, NothingToExportIsAnError) {
  test::TempDir dir;
  EXPECT_THROW(write_gltf(dir.file("x.glb"), static_cast<const TubeMesh*>(nullptr), nullptr),
               Error);
  EXPECT_THROW(write_gltf(dir.file("x.glb"), static_cast<const TubeChunks*>(nullptr), nullptr),
               Error);
  EXPECT_TRUE(dir.entries().empty());
}

// Lines with an origin (lines/origin.hpp): the vertices stay float32 relative to it, and every
// node carries it as its translation, in the output's axes; none without one.
TEST(Gltf, NodesCarryTheLinesOriginAsTheirTranslation) {
  test::TempDir dir;
  const LineSet lines = spiral_lines(3);
  const TubeMesh mesh = chunked_tubes(lines);
  GltfOptions options;
  write_gltf(dir.file("none.glb"), &mesh, &lines, options);
  for (const json& node : read_glb(dir.file("none.glb")).doc["nodes"])
    EXPECT_FALSE(node.contains("translation"));
  options.origin = {500000.25, 5400000.5, -12};
  write_gltf(dir.file("z.glb"), &mesh, &lines, options);
  const Glb z = read_glb(dir.file("z.glb"));
  ASSERT_EQ(z.doc["nodes"].size(), 2u);  // the tubes and the lines
  for (const json& node : z.doc["nodes"])
    EXPECT_EQ(node["translation"].get<std::vector<double>>(),
              (std::vector<double>{500000.25, -12, -5400000.5}));  // glTF (x, y, z) = (x, z, -y)
  options.axes = GltfAxes::Raw;
  write_gltf(dir.file("raw.glb"), &mesh, &lines, options);
  const Glb raw = read_glb(dir.file("raw.glb"));
  EXPECT_EQ(raw.doc["nodes"][0]["translation"].get<std::vector<double>>(),
            (std::vector<double>{500000.25, 5400000.5, -12}));
  // The vertices are the chunks' own, unmoved.
  expect_chunk_arrays(raw, raw.doc["meshes"][0]["primitives"][0], mesh.chunks[0]);
}

}  // namespace
}  // namespace linebake
