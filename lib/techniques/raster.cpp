// The Vulkan rasterisation techniques (opaque, dp, ll, mlab, mlabdb, mboit, wboit): the cached
// tube mesh drawn headless by vk::RasterRenderer.

#include <array>

#include "cache/tube_store.hpp"
#include "core/error.hpp"
#include "render/vulkan/raster_renderer.hpp"
#include "techniques/families.hpp"

namespace linebake {
namespace {

class Raster : public PreparedTechnique {
 public:
  Raster(const TechniqueInfo& info, const CacheReader& cache, const std::string& cache_name,
         const TechniqueOptions& o)
      : info_(info), context_(o, false) {
    if (!cache.exists("/assets/tubes"))
      throw_missing_asset(cache_name, "tubes", "the Vulkan techniques draw the tube mesh");
    // The mesh goes to the device a chunk at a time, each read from the cache and let go once
    // uploaded: the host holds one chunk, never the whole mesh beside the device's copy. Where
    // that copy is in the machine's memory too (lavapipe, integrated GPUs) the budget refuses the
    // allocation that would pass it.
    const TubeMesh description = load_tube_description(cache);
    const uint64_t compile = (*context_).first_draw_compile_bytes();
    context_.budget_host_memory(o, compile);
    within_budget(info_, [&] {
      renderer_ = std::make_unique<vk::RasterRenderer>(*context_, description, [&](size_t c) {
        check_bytes_fit(info_, o, tube_chunk_bytes(cache, description, c),
                        "tube mesh's buffers of chunk " + std::to_string(c) +
                            " (bake --chunk-bytes sets a chunk's size)");
        return load_tube_chunk(cache, description, c);
      });
    });
    context_.budget_host_memory(o, compile);  // again, now that the last chunk is let go
    options_.technique = vk::parse_raster_technique(info.name);
    options_.width = o.width, options_.height = o.height;
    options_.sort = vk::parse_list_sort(o.sort);
    options_.capacity = given_capacity_ = o.capacity;
    options_.node_bytes = o.node_bytes;
    options_.early_termination = o.early_termination;
    options_.max_layers = o.max_layers;
    options_.layers = o.layers;
    options_.tau_alpha = o.tau_alpha, options_.tau_opaque = o.tau_opaque;
    options_.mboit_beta = o.beta;
    options_.moment_basis = vk::parse_moment_basis(o.moment_basis);
    options_.moments = o.moments;
    if (o.moment_bias >= 0) options_.mboit_bias = o.moment_bias;
    options_.wboit_weight = o.wboit_weight;
    options_.interlock = o.interlock;
  }

  TechniqueFrame render(const Camera& camera, const TransferFunction& tf, int width,
                        int height) override {
    if (capacity_size_ != std::array<int, 2>{width, height}) options_.capacity = given_capacity_;
    options_.width = width, options_.height = height;
    vk::RasterFrame frame =
        within_budget(info_, [&] { return renderer_->render(camera, tf, options_); });
    (*context_).drop_compile_reserve();  // the first draw compiled; what stays of it is resident
    context_.check_validation();
    const vk::RasterStats& s = frame.stats;
    // A given --capacity is where the first frame starts; later frames of the size start from
    // what it grew to (each had started from the given size again, overflowed and drawn twice).
    if (options_.capacity > 0 && s.capacity > options_.capacity) {
      options_.capacity = s.capacity;
      capacity_size_ = {width, height};
    }
    const bool counted = !frame.depth_complexity.empty();  // dp and ll count fragments
    TechniqueFrame out = technique_frame(std::move(frame.image), std::move(frame.depth_complexity),
                                         s.seconds, s.frame_bytes);
    nlohmann::json passes = nlohmann::json::object();
    for (const auto& [name, ms] : s.pass_ms) {
      passes[name] = ms;
      out.gpu_ms[name] = ms;
    }
    out.stats = {{"gpu_ms", passes},
                 {"node_capacity", s.capacity},
                 {"regrows", s.regrows},
                 {"frame_bytes", s.frame_bytes}};
    // Where the technique does not count them, no figures (they had been zeros).
    if (counted) {
      out.stats["fragments"] = s.fragments;
      out.stats["depth_complexity"] = {{"max", s.max_depth_complexity},
                                       {"mean", s.mean_depth_complexity}};
    }
    if (s.layers > 0) {
      out.stats["layers"] = s.layers;
      if (options_.technique == vk::RasterTechnique::DepthPeeling)
        out.stats["layers_capped"] = s.layers_capped;
    }
    if (!s.critical_section.empty()) out.stats["critical_section"] = s.critical_section;
    if (options_.technique == vk::RasterTechnique::LinkedLists)
      out.stats["node_bytes"] = options_.node_bytes;
    // ll's node pool and mlab's/mlabdb's per-pixel nodes are split across storage buffers.
    if (s.node_buffers > 0) out.stats["node_buffers"] = s.node_buffers;
    if (s.layers_capped)
      out.warnings.push_back("needs " + std::to_string(s.max_depth_complexity) +
                             " layers; dp peeled " + std::to_string(s.layers) + " (--max-layers)");
    out.note = "on " + context_->info().name;
    return out;
  }

  nlohmann::json stats() const override {
    nlohmann::json j = {{"device", context_->info().name},
                        {"driver", context_->info().driver},
                        {"mesh_bytes", renderer_->mesh_bytes()}};
    const vk::RasterOptions& o = options_;
    if (o.technique == vk::RasterTechnique::LinkedLists) j["sort"] = vk::to_string(o.sort);
    if (o.technique == vk::RasterTechnique::MlabBuckets)
      j["tau"] = {{"alpha", o.tau_alpha}, {"opaque", o.tau_opaque}};
    if (o.technique == vk::RasterTechnique::Mboit) {
      j["beta"] = o.mboit_beta;
      j["moments"] = {
          {"basis", vk::to_string(o.moment_basis)},
          {"count", o.moments},
          {"bias", o.mboit_bias.value_or(vk::default_moment_bias(o.moment_basis, o.moments))}};
    }
    return j;
  }

  std::string device() const override { return context_->info().name; }

 private:
  TechniqueInfo info_;
  ContextHolder context_;
  std::unique_ptr<vk::RasterRenderer> renderer_;
  vk::RasterOptions options_;
  uint64_t given_capacity_ = 0;             // --capacity (0: the renderer's own start)
  std::array<int, 2> capacity_size_{0, 0};  // the size options_.capacity grew for
};

}  // namespace

uint64_t raster_frame_bytes(const TechniqueInfo& info, const TechniqueOptions& o) {
  const uint64_t pixels = uint64_t(o.width) * uint64_t(o.height);
  const std::string& name = info.name;
  if (name == "ll") return (o.capacity ? o.capacity : 20 * pixels) * o.node_bytes + pixels * 4;
  if (name == "mlab" || name == "mlabdb")
    return pixels * uint64_t(o.layers ? o.layers : name == "mlab" ? 8 : 4) * 20 + pixels * 12;
  if (name == "dp") return pixels * (2 * 4 + 16);
  if (name == "mboit") return pixels * (uint64_t(o.moments + 1) * 4 + 16);
  if (name == "wboit") return pixels * 32;
  return pixels * 16;
}

std::unique_ptr<PreparedTechnique> prepare_raster(const TechniqueInfo& info,
                                                  const CacheReader& cache,
                                                  const std::string& cache_name,
                                                  const TechniqueOptions& options) {
  return std::make_unique<Raster>(info, cache, cache_name, options);
}

}  // namespace linebake
