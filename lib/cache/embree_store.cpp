#include "cache/embree_store.hpp"

#include <cstdio>

#include "core/error.hpp"

namespace linebake {

static std::string part_group(size_t i) {
  char name[32];
  std::snprintf(name, sizeof name, "/part_%06zu", i);
  return std::string(kEmbreeGroup) + name;
}

void store_embree(CacheWriter& cache, const StoredCurves& curves, Provenance provenance) {
  cache.create_group(kEmbreeGroup);
  uint64_t disk = 0;
  for (size_t i = 0; i < curves.parts.size(); ++i) {
    const PreparedCurves& p = curves.parts[i];
    const std::string g = part_group(i);
    cache.create_group(g);
    disk += cache.write(g + "/vertices", p.vertices.data(), p.vertices.size() / 4, 4);
    disk += cache.write(g + "/indices", p.indices.data(), p.indices.size());
    if (!p.flags.empty()) disk += cache.write(g + "/flags", p.flags.data(), p.flags.size());
  }
  const nlohmann::json description = {{"geometry", to_string(curves.geometry)},
                                      {"radius", curves.radius},
                                      {"attribute", curves.attribute},
                                      {"parts", curves.parts.size()}};
  cache.write_attribute(kEmbreeGroup, "curves", description.dump());
  provenance.disk_bytes = disk;
  cache.write_provenance(kEmbreeGroup, provenance);
}

StoredCurves load_embree(const CacheReader& cache) {
  const std::string where = std::string("group ") + kEmbreeGroup;
  const auto text = cache.attribute(kEmbreeGroup, "curves");
  if (!text)
    throw InputError(cache.path(), where, "no Embree buffers in this cache (bake --assets embree)");
  StoredCurves c;
  size_t parts = 0;
  try {
    const auto j = nlohmann::json::parse(*text);
    c.geometry = parse_embree_geometry(j.at("geometry").get<std::string>());
    c.radius = j.at("radius");
    c.attribute = j.at("attribute");
    parts = j.at("parts");
  } catch (const std::exception& e) {
    throw InputError(cache.path(), where, std::string("bad curve description: ") + e.what());
  }
  // Linear curves and capsules: a vertex per point and neighbour flags.
  const bool point_layout = c.geometry != EmbreeGeometry::BezierCurve;
  for (size_t i = 0; i < parts; ++i) {
    const std::string g = part_group(i);
    PreparedCurves p;
    p.vertices = cache.read<float>(g + "/vertices");
    p.indices = cache.read<uint32_t>(g + "/indices");
    if (point_layout) p.flags = cache.read<uint8_t>(g + "/flags", p.indices.size());
    const uint64_t vertices = p.vertices.size() / 4;
    for (uint64_t s = 0; s < p.indices.size(); ++s)
      // Past the last real vertex (the stored buffer ends with one padding vertex).
      if (uint64_t(p.indices[s]) + (point_layout ? 3 : 5) > vertices)
        throw InputError(cache.path(), "dataset " + g + "/indices",
                         "segment " + std::to_string(s) + " points past the vertices");
    c.parts.push_back(std::move(p));
  }
  return c;
}

}  // namespace linebake
