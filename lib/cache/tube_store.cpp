#include "cache/tube_store.hpp"

#include <cstdio>

#include "core/error.hpp"

namespace linebake {

static std::string chunk_group(size_t c) {
  char name[32];
  std::snprintf(name, sizeof name, "/chunk_%06zu", c);
  return kTubesGroup + std::string(name);
}

void store_tubes(CacheWriter& cache, const TubeMesh& mesh, Provenance provenance) {
  cache.create_group(kTubesGroup);
  uint64_t disk = 0;
  for (size_t c = 0; c < mesh.chunks.size(); ++c) {
    const TubeChunk& chunk = mesh.chunks[c];
    const std::string g = chunk_group(c);
    cache.create_group(g);
    const uint64_t v = chunk.vertex_count();
    disk += cache.write(g + "/positions", chunk.positions.data(), v, 3);
    if (mesh.normals == NormalEncoding::Float32)
      disk += cache.write(g + "/normals", chunk.normals.data(), v, 3);
    else
      disk += cache.write(g + "/normals_oct", chunk.normals_oct.data(), v, 2);
    if (!chunk.attribute.empty()) disk += cache.write(g + "/attribute", chunk.attribute.data(), v);
    disk += cache.write(g + "/indices", chunk.indices.data(), chunk.triangle_count(), 3);
    cache.write_attribute(g, "lines", nlohmann::json{chunk.first_line, chunk.line_count}.dump());
  }
  const nlohmann::json description = {{"sides", mesh.sides},
                                      {"radius", mesh.radius},
                                      {"caps", mesh.caps},
                                      {"normals", to_string(mesh.normals)},
                                      {"attribute", mesh.attribute},
                                      {"attribute_range", mesh.attribute_range},
                                      {"lines_dropped", mesh.lines_dropped},
                                      {"points_skipped", mesh.points_skipped},
                                      {"chunks", mesh.chunks.size()}};
  cache.write_attribute(kTubesGroup, "mesh", description.dump());
  provenance.disk_bytes = disk;
  provenance.memory_bytes = mesh.bytes();
  cache.write_provenance(kTubesGroup, provenance);
}

TubeMesh load_tubes(const CacheReader& cache) {
  const std::string where = std::string("group ") + kTubesGroup;
  const auto text = cache.attribute(kTubesGroup, "mesh");
  if (!text) throw InputError(cache.path(), where, "no tube mesh in this cache (run bake)");
  TubeMesh mesh;
  size_t chunks = 0;
  try {
    const auto j = nlohmann::json::parse(*text);
    mesh.sides = j.at("sides");
    mesh.radius = j.at("radius");
    mesh.caps = j.at("caps");
    mesh.normals = parse_normal_encoding(j.at("normals"));
    mesh.attribute = j.at("attribute");
    mesh.attribute_range = j.at("attribute_range");
    mesh.lines_dropped = j.at("lines_dropped");
    mesh.points_skipped = j.at("points_skipped");
    chunks = j.at("chunks");
  } catch (const std::exception& e) {
    throw InputError(cache.path(), where, std::string("bad mesh description: ") + e.what());
  }
  mesh.chunks.resize(chunks);
  for (size_t c = 0; c < chunks; ++c) {
    TubeChunk& chunk = mesh.chunks[c];
    const std::string g = chunk_group(c);
    const auto lines = cache.attribute(g, "lines");
    if (!lines) throw InputError(cache.path(), "group " + g, "missing");
    try {
      const auto j = nlohmann::json::parse(*lines);
      chunk.first_line = j.at(0);
      chunk.line_count = j.at(1);
    } catch (const std::exception& e) {
      throw InputError(cache.path(), "group " + g, std::string("bad line range: ") + e.what());
    }
    chunk.positions = cache.read<float>(g + "/positions");
    if (chunk.positions.size() % 3)
      throw InputError(cache.path(), "dataset " + g + "/positions", "not 3 floats per vertex");
    const uint64_t v = chunk.vertex_count();
    if (mesh.normals == NormalEncoding::Float32)
      chunk.normals = cache.read<float>(g + "/normals", 3 * v);
    else
      chunk.normals_oct = cache.read<int16_t>(g + "/normals_oct", 2 * v);
    if (!mesh.attribute.empty()) chunk.attribute = cache.read<uint16_t>(g + "/attribute", v);
    chunk.indices = cache.read<uint32_t>(g + "/indices");
    if (chunk.indices.size() % 3)
      throw InputError(cache.path(), "dataset " + g + "/indices", "not 3 indices per triangle");
    // The hash guards the bytes; this guards a renderer against a cache written wrongly.
    for (size_t i = 0; i < chunk.indices.size(); ++i)
      if (chunk.indices[i] >= v)
        throw InputError(cache.path(), "dataset " + g + "/indices",
                         "index " + std::to_string(chunk.indices[i]) + " at " + std::to_string(i) +
                             " is past the " + std::to_string(v) + " vertices");
  }
  return mesh;
}

}  // namespace linebake
