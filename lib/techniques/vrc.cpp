// vrc: voxel ray casting of the cached voxel line grid, on the CPU (TBB) or with Vulkan compute.

#include "cache/voxel_store.hpp"
#include "core/error.hpp"
#include "render/voxel_ray_caster.hpp"
#include "render/vulkan/voxel_caster.hpp"
#include "techniques/families.hpp"
#include "voxels/occupancy.hpp"

namespace linebake {
namespace {

class Vrc : public PreparedTechnique {
 public:
  Vrc(const TechniqueInfo& info, const CacheReader& cache, const std::string& cache_name,
      const TechniqueOptions& o)
      : info_(info) {
    if (!cache.exists(kVoxelsGroup))
      throw_missing_asset(cache_name, "voxels", "vrc ray casts the voxel line grid");
    check_data_fits(info, o, cache, kVoxelsGroup, "voxel grid's arrays");
    grid_ = load_voxels(cache);
    options_.width = o.width, options_.height = o.height;
    options_.early_termination = o.vrc_early_termination;
    options_.skip_empty_space = o.skip_empty_space;
    const auto tube_provenance =
        cache.exists("/assets/tubes") ? cache.provenance("/assets/tubes") : std::nullopt;
    options_.radius = o.radius;
    if (!(options_.radius > 0) && tube_provenance &&
        tube_provenance->stats.contains("radius_world"))
      options_.radius = tube_provenance->stats["radius_world"].get<double>();
    radius_ = vrc_radius(grid_, options_.radius);  // what the casters use
    occupancy_ = build_occupancy(grid_);
    if (o.on == "gpu") {
      context_.emplace(o, false);
      context_->budget_host_memory(o);
      within_budget(info, [&] { caster_.emplace(**context_, grid_, occupancy_); });
      context_->budget_host_memory(o);
    } else if (o.on != "cpu") {
      throw Error("vrc: --on cpu or gpu, not '" + o.on + "'");
    }
  }

  TechniqueFrame render(const Camera& camera, const TransferFunction& tf, int width,
                        int height) override {
    options_.width = width, options_.height = height;
    VrcFrame frame =
        caster_ ? within_budget(info_, [&] { return caster_->render(camera, tf, options_); })
                : cast_voxel_frame(grid_, occupancy_, camera, tf, options_);
    if (context_) context_->check_validation();
    const VrcStats& s = frame.stats;
    TechniqueFrame out = technique_frame(std::move(frame.image), std::move(frame.depth_complexity),
                                         s.seconds, s.frame_bytes);
    out.stats = {{"hits", s.hits},
                 {"depth_complexity", {{"max", s.max_depth_complexity}}},
                 {"voxels_visited", s.voxels_visited},
                 {"cells_skipped", s.cells_skipped},
                 {"chords_tested", s.chords_tested},
                 {"frame_bytes", s.frame_bytes}};
    if (caster_) {
      out.stats["gpu_ms"] = caster_->last_gpu_ms();
      out.stats["slices"] = s.gpu_slices;            // dispatches
      out.stats["slice_steps"] = s.gpu_slice_steps;  // voxel steps a dispatch, 0: whole walks
      out.gpu_ms["cast"] = caster_->last_gpu_ms();
      out.note = "on " + (*context_)->info().name;
    }
    return out;
  }

  nlohmann::json stats() const override {
    nlohmann::json j = {{"on", caster_ ? "gpu" : "cpu"},
                        {"grid",
                         {{"resolution", grid_.resolution},
                          {"quantization", grid_.quantization},
                          {"voxel_size", grid_.voxel_size},
                          {"representation_bytes", grid_.representation_bytes()}}},
                        {"occupancy_levels", occupancy_.levels()},
                        {"occupancy_bytes", occupancy_.bytes()},
                        {"radius", radius_},
                        {"radius_clamped", options_.radius > grid_.voxel_size},
                        {"early_termination", options_.early_termination},
                        {"skip_empty_space", options_.skip_empty_space}};
    if (context_) j["device"] = (*context_)->info().name;
    return j;
  }

  std::string device() const override { return context_ ? (*context_)->info().name : ""; }

 private:
  TechniqueInfo info_;
  std::optional<ContextHolder> context_;
  VoxelGrid grid_;
  OccupancyPyramid occupancy_;
  VrcOptions options_;
  double radius_ = 0;
  std::optional<vk::VoxelCaster> caster_;
};

}  // namespace

std::unique_ptr<PreparedTechnique> prepare_vrc(const TechniqueInfo& info, const CacheReader& cache,
                                               const std::string& cache_name,
                                               const TechniqueOptions& options) {
  return std::make_unique<Vrc>(info, cache, cache_name, options);
}

}  // namespace linebake
