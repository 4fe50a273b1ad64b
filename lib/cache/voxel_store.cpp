#include "cache/voxel_store.hpp"

#include "core/error.hpp"

namespace linebake {

static std::string density_name(size_t level) {
  return std::string(kVoxelsGroup) + "/density_" + std::to_string(level);
}

void store_voxels(CacheWriter& cache, const VoxelGrid& g, Provenance provenance) {
  cache.create_group(kVoxelsGroup);
  const std::string base = kVoxelsGroup;
  uint64_t disk = cache.write(base + "/offsets", g.offsets.data(), g.offsets.size());
  disk += cache.write(base + "/chords", g.chords.data(), g.chord_count(), 2);
  disk += cache.write(base + "/line_counts", g.line_counts.data(), g.line_counts.size());
  for (size_t level = 0; level < g.density.size(); ++level)
    disk += cache.write(density_name(level), g.density[level].data(), g.density[level].size());
  const nlohmann::json description = {{"resolution", g.resolution},
                                      {"origin", g.origin},
                                      {"voxel_size", g.voxel_size},
                                      {"quantization", g.quantization},
                                      {"max_chords_per_voxel", g.max_chords_per_voxel},
                                      {"attribute", g.attribute},
                                      {"attribute_range", g.attribute_range},
                                      {"density_levels", g.density.size()},
                                      {"segments", g.segments},
                                      {"chords_dropped", g.chords_dropped},
                                      {"voxels_overflowed", g.voxels_overflowed},
                                      {"voxels_occupied", g.voxels_occupied},
                                      {"max_error", g.max_error},
                                      {"mean_error", g.mean_error}};
  cache.write_attribute(kVoxelsGroup, "grid", description.dump());
  provenance.disk_bytes = disk;
  provenance.memory_bytes = g.representation_bytes();
  cache.write_provenance(kVoxelsGroup, provenance);
}

VoxelGrid load_voxels(const CacheReader& cache) {
  const std::string where = std::string("group ") + kVoxelsGroup;
  const auto text = cache.attribute(kVoxelsGroup, "grid");
  if (!text)
    throw InputError(cache.path(), where, "no voxel grid in this cache (bake --assets voxels)");
  VoxelGrid g;
  size_t levels = 0;
  try {
    const auto j = nlohmann::json::parse(*text);
    g.resolution = j.at("resolution");
    g.origin = j.at("origin");
    g.voxel_size = j.at("voxel_size");
    g.quantization = j.at("quantization");
    g.max_chords_per_voxel = j.at("max_chords_per_voxel");
    g.attribute = j.at("attribute");
    g.attribute_range = j.at("attribute_range");
    levels = j.at("density_levels");
    g.segments = j.at("segments");
    g.chords_dropped = j.at("chords_dropped");
    g.voxels_overflowed = j.at("voxels_overflowed");
    g.voxels_occupied = j.at("voxels_occupied");
    g.max_error = j.at("max_error");
    g.mean_error = j.at("mean_error");
  } catch (const std::exception& e) {
    throw InputError(cache.path(), where, std::string("bad grid description: ") + e.what());
  }
  if (g.quantization != 16 && g.quantization != 32 && g.quantization != 64)
    throw InputError(cache.path(), where, "quantization must be 16, 32 or 64");
  const uint64_t voxels = g.voxel_count();
  const std::string base = kVoxelsGroup;
  g.offsets = cache.read<uint32_t>(base + "/offsets", voxels + 1);
  g.chords = cache.read<uint32_t>(base + "/chords");
  if (g.offsets[0] != 0 || 2 * uint64_t(g.offsets[voxels]) != g.chords.size())
    throw InputError(cache.path(), "dataset " + base + "/offsets",
                     "does not match the " + std::to_string(g.chords.size() / 2) + " chords");
  for (uint64_t v = 0; v < voxels; ++v)
    if (g.offsets[v + 1] < g.offsets[v])
      throw InputError(cache.path(), "dataset " + base + "/offsets",
                       "decreasing at voxel " + std::to_string(v));
  g.line_counts = cache.read<uint8_t>(base + "/line_counts", voxels);
  for (size_t level = 0; level < levels; ++level) {
    const auto r = g.level_resolution(level);
    g.density.push_back(cache.read<float>(density_name(level), uint64_t(r[0]) * r[1] * r[2]));
  }
  return g;
}

}  // namespace linebake
