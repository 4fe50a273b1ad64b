#pragma once
// Embree's prepared curve buffers in the cache: group /assets/embree (docs/cache.md). Embree
// BVHs cannot be serialised, so the cache keeps what a rebuild needs, and the provenance keeps
// what the build cost (prepare and commit time, BVH bytes from Embree's memory monitor).

#include <string>
#include <vector>

#include "accel/embree_scene.hpp"
#include "cache/cache.hpp"

namespace linebake {

constexpr const char* kEmbreeGroup = "/assets/embree";

struct StoredCurves {
  EmbreeGeometry geometry = EmbreeGeometry::LinearCurve;
  float radius = 0;
  std::string attribute;
  std::vector<PreparedCurves> parts;
};

// Writes the buffers and the provenance; fills provenance.disk_bytes.
void store_embree(CacheWriter& cache, const StoredCurves& curves, Provenance provenance);
StoredCurves load_embree(const CacheReader& cache);

}  // namespace linebake
