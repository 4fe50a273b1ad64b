// tiles: exact transparency from compute shaders only (render/vulkan/tile_renderer.hpp), over
// the lines as capsule chains with the cached tubes' radius, as embree --embree-geometry capsules
// and rtx --rtx-geometry capsules draw them, or (--tiles-geometry triangles) over the cached tube
// mesh, as reference and the raster techniques draw it.

#include "accel/capsule_segments.hpp"
#include "cache/line_store.hpp"
#include "cache/tube_store.hpp"
#include "core/error.hpp"
#include "render/vulkan/radix_sort.hpp"
#include "render/vulkan/tile_renderer.hpp"
#include "techniques/curve_defaults.hpp"
#include "techniques/families.hpp"

namespace linebake {
namespace {

vk::TileStrips strips_of(const std::string& name) {
  if (name == "none") return vk::TileStrips::none;
  if (name == "crowded") return vk::TileStrips::crowded;
  if (name == "all") return vk::TileStrips::all;
  throw UsageError("tiles: the strips are none, crowded or all, not '" + name + "'");
}

class Tiles : public PreparedTechnique {
 public:
  Tiles(const TechniqueInfo& info, const CacheReader& cache, const std::string& cache_name,
        const TechniqueOptions& o)
      : info_(info), context_(o, false), triangles_(o.tiles_geometry == "triangles") {
    if (o.tiles_sort != "auto" && o.tiles_sort != "subgroups" && o.tiles_sort != "shared")
      throw UsageError("tiles: the sort is auto, subgroups or shared, not '" + o.tiles_sort + "'");
    options_.strips = strips_of(o.tiles_strips);
    // auto: the subgroup path where the device has it, except on lavapipe, whose subgroup
    // operations are emulated across its 8-lane SIMD units: there the shared-memory path sorts
    // 1.5 million keys in 122 ms against 198 (docs/tiles.md, "The sort's blocks").
    const bool sort_subgroups =
        o.tiles_sort == "subgroups" || (o.tiles_sort == "auto" && !context_->info().lavapipe);
    if (o.tiles_sort == "subgroups" && !vk::RadixSorter::subgroups_supported(context_->info()))
      throw Error("tiles --tiles-sort subgroups: " + context_->info().name +
                  " lacks what the sort's subgroup path needs (compute subgroups of 8 to 128 "
                  "invocations with basic, ballot and arithmetic operations, and full "
                  "subgroups); --tiles-sort shared or auto run everywhere");
    // Each mode's data is read only where it fits the budget; the context's allocations are held
    // within what is left once it is loaded, and again once the host's copies are let go.
    if (triangles_) {
      if (!cache.exists("/assets/tubes"))
        throw_missing_asset(cache_name, "tubes",
                            "tiles --tiles-geometry triangles draws the tube mesh");
      if (o.radius > 0 || !o.attribute.empty())
        throw UsageError(
            "--radius and --attribute are the capsules' (the tube mesh has its own); "
            "not with --tiles-geometry triangles");
      // The mesh a chunk at a time into the renderer's arrays, each chunk let go once copied.
      check_data_fits(info, o, cache, "/assets/tubes", "tube mesh's buffers");
      const TubeMesh description = load_tube_description(cache);
      radius_ = description.radius;
      context_.budget_host_memory(o);
      within_budget(info, [&] {
        renderer_.emplace(
            *context_, description, load_tube_counts(cache),
            [&](size_t c) {
              check_bytes_fit(info, o, tube_chunk_bytes(cache, description, c),
                              "tube mesh's buffers of chunk " + std::to_string(c) +
                                  " (bake --chunk-bytes sets a chunk's size)");
              return load_tube_chunk(cache, description, c);
            },
            0, 0, sort_subgroups);
      });
    } else {
      check_data_fits(info, o, cache, "/lines", "lines");
      const LineSet lines = load_lines(cache);
      const auto tube_provenance =
          cache.exists("/assets/tubes") ? cache.provenance("/assets/tubes") : std::nullopt;
      const auto [radius, attribute] =
          curve_defaults(o.radius, o.attribute, tube_provenance, lines);
      check_bytes_fit(
          info, o,
          capsule_segments_bytes(lines) +
              vk::TileRenderer::capsule_upload_bytes(lines.point_count(), lines.segment_count()),
          "capsule segments (with their copy for the upload)");
      const CapsuleSegments capsules = build_capsule_segments(lines, radius, attribute);
      context_.budget_host_memory(o);
      within_budget(info, [&] { renderer_.emplace(*context_, capsules, 0, 0, sort_subgroups); });
      radius_ = radius;
    }
    // The composites these options run, made before the frames' budget is taken: lavapipe's
    // compiler takes the machine's memory, which the budget then counts as held.
    options_.pixel_hits = o.tiles_pixel_hits;
    options_.late_shading = o.tiles_late_shading;
    within_budget(info, [&] { renderer_->make_pipelines(options_); });
    context_.budget_host_memory(o);
    // The frames' keys and states: where the device's memory is the machine's, what the budget
    // leaves now that the scene is held; elsewhere --memory-budget's bytes where given.
    if (context_->memory_is_host() && context_->host_budget() > 0)
      frame_budget_ = std::max<uint64_t>(context_->host_bytes_left(), 1);
    else
      frame_budget_ = o.memory_budget;
    options_.early_termination = o.early_termination;
    options_.most_keys_first = o.tiles_most_keys_first;
  }

  TechniqueFrame render(const Camera& camera, const TransferFunction& tf, int width,
                        int height) override {
    options_.width = width, options_.height = height;
    // What the budget leaves once the image's own buffers are counted: a quarter for the pixels'
    // states (tiles composited in groups that fit), the rest for the keys (bands that fit).
    const uint64_t image_bytes = uint64_t(width) * uint64_t(height) * (16 + 4);
    if (frame_budget_ > 0) {
      const uint64_t left = frame_budget_ > image_bytes ? frame_budget_ - image_bytes : 4;
      options_.max_state_bytes = std::max<uint64_t>(left / 4, 1);
      options_.max_key_bytes = left - left / 4;
    }
    vk::TileFrame frame =
        within_budget(info_, [&] { return renderer_->render(camera, tf, options_); });
    context_.check_validation();
    const vk::TileStats& s = frame.stats;
    TechniqueFrame out = technique_frame(std::move(frame.image), std::move(frame.depth_complexity),
                                         s.seconds, s.frame_bytes);
    out.gpu_ms["bin"] = s.bin_ms;
    out.gpu_ms["sort"] = s.sort_ms;
    out.gpu_ms["composite"] = s.composite_ms;
    out.stats = {
        {"hits", s.hits},
        {"keys", s.keys},
        {"tiles", s.tiles},
        {triangles_ ? "triangles" : "segments", s.primitives},
        {triangles_ ? "binned_triangles" : "binned_segments", s.binned_primitives},
        {"window_overflows", s.window_overflows},
        {"walks", s.walks},
        {"walk_ms", s.walk_ms},
        {"walk_tiles", s.walk_tiles},
        {"walk_skipped_keys", s.walk_skipped_keys},
        {"redone_tiles", s.redone_tiles},
        {"redone_ms", s.redone_ms},
        {"max_tile_keys", s.max_tile_keys},
        {"crowded_tiles", s.crowded_tiles},
        {"composite_workgroups", s.composite_workgroups},
        {"groups", s.groups},
        {"rebins", s.rebins},
        {"slices", s.slices},
        {"resliced", s.resliced},
        {"bands", s.bands},
        {"gpu_ms", {{"bin", s.bin_ms}, {"sort", s.sort_ms}, {"composite", s.composite_ms}}},
        {"depth_complexity", {{"max", s.max_depth_complexity}}},
        {"frame_bytes", s.frame_bytes}};
    if (options_.late_shading) out.stats["late_misses"] = s.late_misses;
    out.note = std::to_string(s.keys) + " keys on " + context_->info().name;
    return out;
  }

  nlohmann::json stats() const override {
    return {{"device", context_->info().name},
            {"geometry", triangles_ ? "triangles" : "capsules"},
            {"radius", radius_},
            {"early_termination", options_.early_termination},
            {"sort_subgroup_size", renderer_->sort_subgroup_size()},
            {"primitive_buffers", renderer_->primitive_buffers()}};
  }
  std::string device() const override { return context_->info().name; }

 private:
  TechniqueInfo info_;
  ContextHolder context_;
  bool triangles_ = false;
  float radius_ = 0;
  std::optional<vk::TileRenderer> renderer_;
  vk::TileOptions options_;
  uint64_t frame_budget_ = 0;  // the frames' memory (0: none)
};

}  // namespace

std::unique_ptr<PreparedTechnique> prepare_tiles(const TechniqueInfo& info,
                                                 const CacheReader& cache,
                                                 const std::string& cache_name,
                                                 const TechniqueOptions& options) {
  return std::make_unique<Tiles>(info, cache, cache_name, options);
}

}  // namespace linebake
