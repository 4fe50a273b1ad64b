// embree and reference: the CPU ray tracer over Embree curves built from the cached lines (or
// from bake's prepared buffers when they are these curves), or over the cached tube mesh.

#include "accel/embree_scene.hpp"
#include "cache/embree_store.hpp"
#include "cache/line_store.hpp"
#include "cache/tube_store.hpp"
#include "core/error.hpp"
#include "core/measure.hpp"
#include "core/memory_budget.hpp"
#include "render/ray_tracer.hpp"
#include "techniques/curve_defaults.hpp"
#include "techniques/families.hpp"

namespace linebake {

uint64_t cpu_tracing_frame_bytes(const TechniqueInfo&, const TechniqueOptions& o) {
  return uint64_t(o.width) * uint64_t(o.height) * 16;  // hit lists of a tile, alpha, counts
}

namespace {

nlohmann::json to_json(const BvhStats& s) {
  return {{"geometry", to_string(s.geometry)},
          {"primitives", s.primitives},
          {"parts", s.parts},
          {"instanced", s.instanced},
          {"prepare_s", s.prepare_s},
          {"commit_s", s.commit_s},
          {"buffer_bytes", s.buffer_bytes},
          {"bvh_bytes", s.bvh_bytes},
          {"bvh_peak_bytes", s.bvh_peak_bytes}};
}

// What the memory budget leaves the Embree scene (its buffers and BVH) once the process holds
// its data (render --memory-budget; none given: half of physical memory), less the frame's own
// buffers; and the figures behind it, for a refusal.
struct SceneBudget {
  uint64_t bytes = 0;  // 0: unlimited
  std::string figures;
};

SceneBudget scene_budget(const TechniqueInfo& info, const TechniqueOptions& o,
                         const std::string& data) {
  if (o.memory_unlimited) return {};
  trimmed_rss_bytes();  // memory freed but still resident in the heap is not held
  const MemoryBudget budget(process_budget(o));
  const std::string figures =
      format_bytes(budget.total()) +
      (o.memory_budget > 0 ? ""
                           : ", the default: half of physical memory or of the process's limits") +
      "; the process held " + format_bytes(budget.baseline()) + " with the " + data + " loaded";
  const uint64_t frame = frame_output_bytes(o) + cpu_tracing_frame_bytes(info, o);
  if (budget.available() <= frame)
    throw BudgetExceeded(info.name + ": nothing is left for Embree's BVH; raise --memory-budget (" +
                         figures + ")");
  return {budget.available() - frame, figures};
}

// Builds the scene, naming the technique and the budget's figures where it is refused.
template <class Build>
void build_within(const TechniqueInfo& info, const SceneBudget& budget, Build&& build) {
  try {
    build();
  } catch (const BudgetExceeded& e) {
    throw BudgetExceeded(info.name + ": " + e.what() + " (" + budget.figures + ")");
  }
}

class CpuTracing : public PreparedTechnique {
 public:
  CpuTracing(const TechniqueInfo& info, const CacheReader& cache, const std::string& cache_name,
             const TechniqueOptions& o) {
    const bool has_tubes = cache.exists("/assets/tubes");
    EmbreeOptions options;
    options.quality = parse_build_quality(o.quality);
    if (info.name == "reference") {
      if (!has_tubes)
        throw_missing_asset(cache_name, "tubes", "the reference renders the tube mesh");
      check_data_fits(info, o, cache, "/assets/tubes", "tube mesh's buffers");
      tubes_ = load_tubes(cache);
      const SceneBudget budget = scene_budget(info, o, "tube mesh");
      options.max_memory_bytes = budget.bytes;
      build_within(info, budget, [&] { scene_.emplace(EmbreeScene::from_tubes(tubes_, options)); });
    } else {
      // The curves take the cached tubes' radius and attribute, from their provenance.
      check_data_fits(info, o, cache, "/lines", "lines");
      lines_ = load_lines(cache);
      const SceneBudget budget = scene_budget(info, o, "lines");
      options.max_memory_bytes = budget.bytes;
      options.geometry = parse_embree_geometry(o.geometry);
      const auto tube_provenance = has_tubes ? cache.provenance("/assets/tubes") : std::nullopt;
      // Named, not a structured binding: the build's lambda below uses them (clang 14 cannot
      // capture a binding).
      const std::pair<float, std::string> curves =
          curve_defaults(o.radius, o.attribute, tube_provenance, lines_);
      const float radius = curves.first;
      const std::string& attribute = curves.second;
      // Bake's prepared buffers, when they are these curves, spare the preparation.
      std::optional<StoredCurves> stored;
      if (cache.exists(kEmbreeGroup)) {
        // Read only where they fit what the budget leaves (the provenance's figure, which
        // includes the BVH where bake built it).
        check_data_fits(info, o, cache, kEmbreeGroup, "cache's Embree buffers");
        stored = load_embree(cache);
        if (stored->geometry != options.geometry || stored->radius != radius ||
            stored->attribute != attribute)
          stored.reset();
      }
      from_cache_ = stored.has_value();
      build_within(info, budget, [&] {
        if (stored)
          scene_.emplace(
              EmbreeScene::from_prepared(lines_, std::move(stored->parts), attribute, options));
        else
          scene_.emplace(EmbreeScene::from_lines(lines_, radius, attribute, options));
      });
    }
    trace_.width = o.width, trace_.height = o.height;
    trace_.early_termination = o.early_termination;
    trace_.collection = parse_hit_collection(o.hits);
    trace_.packets = o.packets;
    trace_.every_hit = o.every_hit;
    if (trace_.packets && trace_.collection != HitCollection::Filter)
      throw UsageError("--packets: packets collect hits with the filter, not by stepping");
  }

  TechniqueFrame render(const Camera& camera, const TransferFunction& tf, int width,
                        int height) override {
    trace_.width = width, trace_.height = height;
    Frame frame = trace_frame(*scene_, camera, tf, trace_);
    const FrameStats& s = frame.stats;
    TechniqueFrame out = technique_frame(std::move(frame.image), std::move(frame.depth_complexity),
                                         s.seconds, s.frame_bytes);
    out.stats = {{"every_hit", s.every_hit},
                 {"front_hits", s.counters.hits},
                 {"composited_hits", s.counters.composited},
                 {"duplicate_hits_removed", s.counters.duplicates},
                 {"back_hits_rejected", s.counters.back_hits},
                 {"traversals", s.counters.traversals},
                 {"rays_stopped_opaque", s.counters.stopped},
                 {"frame_bytes", s.frame_bytes}};
    if (s.every_hit) {
      out.stats["depth_complexity"] = {{"max", s.max_depth_complexity},
                                       {"mean", s.mean_depth_complexity},
                                       {"mean_covered", s.mean_covered_depth_complexity}};
      out.note = "depth complexity max " + std::to_string(s.max_depth_complexity);
    } else {
      out.note = std::to_string(s.counters.stopped) + " rays stopped opaque";
    }
    return out;
  }

  nlohmann::json stats() const override {
    return {{"hit_collection", to_string(trace_.collection)},
            {"packets", trace_.packets},
            {"bvh", to_json(scene_->stats())},
            {"bvh_from_cached_buffers", from_cache_}};
  }

 private:
  LineSet lines_;   // the scene shares these (curves) ...
  TubeMesh tubes_;  // ... or this (reference)
  std::optional<EmbreeScene> scene_;
  bool from_cache_ = false;
  TraceOptions trace_;
};

}  // namespace

std::unique_ptr<PreparedTechnique> prepare_cpu_tracing(const TechniqueInfo& info,
                                                       const CacheReader& cache,
                                                       const std::string& cache_name,
                                                       const TechniqueOptions& options) {
  return std::make_unique<CpuTracing>(info, cache, cache_name, options);
}

}  // namespace linebake
