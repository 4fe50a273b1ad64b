#pragma once
// The families of techniques registry.cpp lists, one file each: each prepares a technique of its
// family (info.name says which) from a cache.

#include "techniques/technique.hpp"

namespace linebake {

// embree (curves) and reference (the tube mesh): the CPU ray tracer, lib/render/ray_tracer.hpp.
std::unique_ptr<PreparedTechnique> prepare_cpu_tracing(const TechniqueInfo& info,
                                                       const CacheReader& cache,
                                                       const std::string& cache_name,
                                                       const TechniqueOptions& options);
// opaque, dp, ll, mlab, mlabdb, mboit, wboit: lib/render/vulkan/raster_renderer.hpp.
std::unique_ptr<PreparedTechnique> prepare_raster(const TechniqueInfo& info,
                                                  const CacheReader& cache,
                                                  const std::string& cache_name,
                                                  const TechniqueOptions& options);
// vrc on the CPU (lib/render/voxel_ray_caster.hpp) or the GPU (render/vulkan/voxel_caster.hpp).
std::unique_ptr<PreparedTechnique> prepare_vrc(const TechniqueInfo& info, const CacheReader& cache,
                                               const std::string& cache_name,
                                               const TechniqueOptions& options);
// rtx: lib/render/vulkan/rt_scene.hpp and rt_renderer.hpp.
std::unique_ptr<PreparedTechnique> prepare_rtx(const TechniqueInfo& info, const CacheReader& cache,
                                               const std::string& cache_name,
                                               const TechniqueOptions& options);

// tiles: lib/render/vulkan/tile_renderer.hpp.
std::unique_ptr<PreparedTechnique> prepare_tiles(const TechniqueInfo& info,
                                                 const CacheReader& cache,
                                                 const std::string& cache_name,
                                                 const TechniqueOptions& options);

// The per-frame buffers of each family (Technique::frame_bytes).
uint64_t cpu_tracing_frame_bytes(const TechniqueInfo& info, const TechniqueOptions& options);
uint64_t raster_frame_bytes(const TechniqueInfo& info, const TechniqueOptions& options);

// A frame's image, depth complexity, wall seconds and per-frame bytes, as every driver reports
// them; the family adds its stats, pass times and notes.
TechniqueFrame technique_frame(Image image, std::vector<uint32_t> depth_complexity, double seconds,
                               uint64_t frame_bytes);

// The cache lacks an asset the technique reads: an InputError (exit 2) naming the cache, the
// group and the command that adds the asset to that cache (a cache is its own line source).
[[noreturn]] void throw_missing_asset(const std::string& cache_name, const std::string& asset,
                                      const std::string& why);

// A Vulkan context for a technique: the shared one when given, else one of its own.
class ContextHolder {
 public:
  ContextHolder(const TechniqueOptions& options, bool ray_tracing);
  vk::Context& operator*() const { return *context_; }
  vk::Context* operator->() const { return context_; }
  // Throws when the validation layer reported errors (they fail the frame).
  void check_validation() const;

 private:
  std::unique_ptr<vk::Context> owned_;
  vk::Context* context_ = nullptr;
};

}  // namespace linebake
