// rtx: Vulkan ray tracing. The BLAS come from the cache's /assets/rtx when they were serialised
// on this driver from the same geometry; otherwise (or with rebuild) they are built here, and
// the stats say which and why.

#include "accel/capsule_segments.hpp"
#include "cache/line_store.hpp"
#include "cache/rtx_store.hpp"
#include "cache/tube_store.hpp"
#include "core/error.hpp"
#include "render/vulkan/rt_renderer.hpp"
#include "render/vulkan/rt_scene.hpp"
#include "techniques/curve_defaults.hpp"
#include "techniques/families.hpp"

namespace linebake {
namespace {

class Rtx : public PreparedTechnique {
 public:
  Rtx(const TechniqueInfo& info, const CacheReader& cache, const std::string& cache_name,
      const TechniqueOptions& o)
      : info_(info), context_(make_context(o)) {
    // The geometry: the option, else what the cache's BLAS were built over, else triangles.
    std::optional<StoredRtx> stored;
    if (cache.exists(kRtxGroup)) stored = load_rtx_description(cache);
    const std::string geometry = !o.rt_geometry.empty() ? o.rt_geometry
                                 : stored               ? stored->geometry
                                                        : "triangles";
    const bool has_tubes = cache.exists("/assets/tubes");
    const auto tube_provenance = has_tubes ? cache.provenance("/assets/tubes") : std::nullopt;
    std::string source;
    if (geometry == "triangles") {
      if (!has_tubes)
        throw_missing_asset(cache_name, "tubes",
                            "rtx traces the tube mesh's triangles (or --rtx-geometry capsules)");
      check_data_fits(info, o, cache, "/assets/tubes", "tube mesh's buffers");
      tubes_ = load_tubes(cache);
      context_.budget_host_memory(o);
      within_budget(info, [&] { scene_.emplace(*context_, tubes_); });
      source = tube_provenance ? tube_provenance->key : "";
    } else if (geometry == "capsules") {
      check_data_fits(info, o, cache, "/lines", "lines");
      lines_ = load_lines(cache);
      const auto [radius, attribute] =
          curve_defaults(o.radius, o.attribute, tube_provenance, lines_);
      check_bytes_fit(info, o, capsule_segments_bytes(lines_), "capsule segments");
      capsules_ = build_capsule_segments(lines_, radius, attribute);
      context_.budget_host_memory(o);
      within_budget(info, [&] { scene_.emplace(*context_, capsules_); });
      const auto lines_provenance = cache.provenance("/lines");
      source = rtx_capsules_source(
          lines_provenance ? lines_provenance->stats.value("content_hash", "") : "", radius,
          attribute);
    } else {
      throw Error("rtx: --rtx-geometry triangles or capsules, not '" + geometry + "'");
    }
    // Cached BLAS, else a build.
    if (o.rebuild)
      rebuild_reason_ = "--rebuild";
    else if (!stored)
      rebuild_reason_ = "the cache has no serialised BLAS (linebake bake CACHE --assets rtx)";
    else if (stored->geometry != geometry)
      rebuild_reason_ = "the cached BLAS are over " + stored->geometry + ", not " + geometry;
    else if (stored->source != source)
      rebuild_reason_ = "the cached BLAS were built from other " +
                        std::string(geometry == "triangles" ? "tubes" : "capsules");
    else if (auto why = data_does_not_fit(o, stored->blob_bytes + stored->largest_blob_bytes,
                                          "cached BLAS"))
      rebuild_reason_ = *why;  // a build on the device instead: its host memory is counted
    else {
      load_rtx_blobs(cache, *stored);
      if (auto problem = within_budget(info, [&] { return scene_->load(stored->blobs); }))
        rebuild_reason_ = *problem;
      stored->blobs = {};
    }
    if (!rebuild_reason_.empty()) {
      if (stored && !o.rebuild)
        warnings.push_back("cached BLAS not used (" + rebuild_reason_ + "); rebuilding");
      within_budget(info, [&] { scene_->build(o.compaction); });
    }
    within_budget(info, [&] { renderer_.emplace(*context_); });
    options_.width = o.width, options_.height = o.height;
    options_.early_termination = o.early_termination;
    options_.max_iterations = uint32_t(o.max_iterations);
    options_.hits = vk::parse_rt_hits(o.hits);
  }

  TechniqueFrame render(const Camera& camera, const TransferFunction& tf, int width,
                        int height) override {
    options_.width = width, options_.height = height;
    vk::RtFrame frame =
        within_budget(info_, [&] { return renderer_->render(*scene_, camera, tf, options_); });
    context_.check_validation();
    const vk::RtStats& s = frame.stats;
    TechniqueFrame out = technique_frame(std::move(frame.image), std::move(frame.depth_complexity),
                                         s.seconds, s.frame_bytes);
    out.gpu_ms["trace"] = s.gpu_ms;
    out.stats = {{"gpu_ms", s.gpu_ms},
                 {"hits", s.hits},
                 {"back_hits", s.back_hits},
                 {"seam_hits", s.seam_hits},
                 {"traces", s.traces},
                 {"truncated_pixels", s.truncated_pixels},
                 {"depth_complexity", {{"max", s.max_depth_complexity}}},
                 {"frame_bytes", s.frame_bytes}};
    if (s.truncated_pixels > 0)
      out.warnings.push_back(std::to_string(s.truncated_pixels) +
                             " pixels stopped at --max-iterations " +
                             std::to_string(options_.max_iterations));
    out.note = "GPU " + std::to_string(s.gpu_ms) + " ms on " + context_->info().name;
    return out;
  }

  nlohmann::json stats() const override {
    return {{"device", context_->info().name},
            {"driver", context_->info().driver},
            {"acceleration_structures", vk::to_json(scene_->figures())},
            {"blas_source", rebuild_reason_.empty() ? "cache" : "built"},
            {"rebuild_reason", rebuild_reason_},
            {"early_termination", options_.early_termination},
            {"max_iterations", options_.max_iterations},
            {"hit_collection", vk::to_string(options_.hits)}};
  }

  std::string device() const override { return context_->info().name; }

 private:
  static ContextHolder make_context(const TechniqueOptions& o) {
    try {
      return ContextHolder(o, true);
    } catch (const vk::RayTracingUnsupported& e) {
      throw vk::RayTracingUnsupported(std::string("rtx: ") + e.what());
    }
  }

  TechniqueInfo info_;
  ContextHolder context_;
  TubeMesh tubes_;
  LineSet lines_;
  CapsuleSegments capsules_;
  std::optional<vk::RtScene> scene_;
  std::optional<vk::RtRenderer> renderer_;
  vk::RtOptions options_;
  std::string rebuild_reason_;
};

}  // namespace

std::unique_ptr<PreparedTechnique> prepare_rtx(const TechniqueInfo& info, const CacheReader& cache,
                                               const std::string& cache_name,
                                               const TechniqueOptions& options) {
  return std::make_unique<Rtx>(info, cache, cache_name, options);
}

}  // namespace linebake
