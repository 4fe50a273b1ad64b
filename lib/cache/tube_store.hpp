#pragma once
// The tube mesh in the cache: group /assets/tubes, one subgroup per chunk (docs/cache.md).

#include "cache/cache.hpp"
#include "tubes/tube_mesh.hpp"

namespace linebake {

constexpr const char* kTubesGroup = "/assets/tubes";

// Writes the mesh and its provenance; fills provenance.disk_bytes and memory_bytes.
void store_tubes(CacheWriter& cache, const TubeMesh& mesh, Provenance provenance);
// Loads the mesh; uncompressed chunks are views of the mapped file.
TubeMesh load_tubes(const CacheReader& cache);

}  // namespace linebake
