#pragma once
// The families of techniques registry.cpp lists, one file each: each prepares a technique of its
// family (info.name says which) from a cache.

#include <optional>
#include <string>

#include "core/error.hpp"
#include "render/vulkan/context.hpp"
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

// The process's memory budget a technique works within: --memory-budget's bytes, half of
// physical memory when none was given, 0 for unlimited.
uint64_t process_budget(const TechniqueOptions& options);
// Why `bytes` of `data` do not fit what the budget leaves the process now ("the DATA take ...
// in memory, more than the memory budget leaves (... of ...)"), or nullopt.
std::optional<std::string> data_does_not_fit(const TechniqueOptions& options, uint64_t bytes,
                                             const std::string& data);
// Refuses, before it is read, data whose size in memory (the provenance of the cache's `group`)
// does not fit what the budget leaves the process: BudgetExceeded naming the technique and `data`.
void check_data_fits(const TechniqueInfo& info, const TechniqueOptions& options,
                     const CacheReader& cache, const std::string& group, const std::string& data);
// Refuses, before they are built, `bytes` of `data` that do not fit what the budget leaves the
// process: BudgetExceeded as check_data_fits.
void check_bytes_fit(const TechniqueInfo& info, const TechniqueOptions& options, uint64_t bytes,
                     const std::string& data);
// Runs `work`, naming the technique in the refusal of a Vulkan allocation past what
// ContextHolder::budget_host_memory allows (the renderers' own refusals name it already).
template <class Work>
decltype(auto) within_budget(const TechniqueInfo& info, Work&& work) {
  try {
    return work();
  } catch (const vk::HostBudgetExceeded& e) {
    throw BudgetExceeded(info.name + ": " + e.what() + "; raise --memory-budget");
  }
}

// A Vulkan context for a technique: the shared one when given, else one of its own.
class ContextHolder {
 public:
  ContextHolder(const TechniqueOptions& options, bool ray_tracing);
  ~ContextHolder();
  ContextHolder(const ContextHolder&) = delete;
  ContextHolder& operator=(const ContextHolder&) = delete;
  vk::Context& operator*() const { return *context_; }
  vk::Context* operator->() const { return context_; }
  // Throws when the validation layer reported errors (they fail the frame).
  void check_validation() const;
  // Holds the context's allocations of host memory (all of them on lavapipe and integrated GPUs,
  // where device memory is the machine's) within the process's budget, less the frame's image
  // (vk::Context::set_host_budget). Called once the technique's data is loaded, so that what the
  // process holds then counts. On a context it shares, the budget it found is put back when it
  // goes, unless a technique prepared since has set its own (vk::Context::restore_host_budget).
  // `compile`: what the driver takes to compile at the first draw, kept until the technique has
  // drawn (vk::Context::first_draw_compile_bytes, drop_compile_reserve).
  void budget_host_memory(const TechniqueOptions& options, uint64_t compile = 0);

 private:
  std::unique_ptr<vk::Context> owned_;
  vk::Context* context_ = nullptr;
  uint64_t budget_serial_ = 0;     // the budget it set on the context (0: none)
  vk::Context::HostBudget found_;  // the one in force before, put back when it goes
};

}  // namespace linebake
