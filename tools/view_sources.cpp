#include "view_sources.hpp"

#include "accel/embree_scene.hpp"
#include "cache/line_store.hpp"
#include "cache/tube_store.hpp"
#include "cache/voxel_store.hpp"
#include "core/error.hpp"
#include "curve_defaults.hpp"
#include "render/ray_tracer.hpp"
#include "render/voxel_ray_caster.hpp"
#include "render/vulkan/raster_renderer.hpp"
#include "render/vulkan/voxel_caster.hpp"
#include "voxels/occupancy.hpp"

namespace linebake::cli {
namespace {

TubeMesh require_tubes(const CacheReader& cache, const std::string& technique) {
  if (!cache.exists("/assets/tubes"))
    throw Error(technique + " draws the tube mesh; bake --assets tubes first");
  return load_tubes(cache);
}

class EmbreeSource : public ViewSource {
 public:
  EmbreeSource(const CacheReader& cache, bool reference) {
    if (reference) {
      scene_.emplace(EmbreeScene::from_tubes(require_tubes(cache, "reference"), {}));
      return;
    }
    const LineSet lines = load_lines(cache);
    const auto provenance =
        cache.exists("/assets/tubes") ? cache.provenance("/assets/tubes") : std::nullopt;
    const auto [radius, attribute] = curve_defaults(0, "", provenance, lines);
    scene_.emplace(EmbreeScene::from_lines(lines, radius, attribute, {}));
  }
  ViewFrame render(const Camera& camera, const TransferFunction& tf, int width,
                   int height) override {
    TraceOptions options;
    options.width = width, options.height = height;
    Frame frame = trace_frame(*scene_, camera, tf, options);
    return {std::move(frame.image), frame.stats.seconds, frame.stats.frame_bytes};
  }
  Bounds bounds() const override { return scene_->bounds(); }

 private:
  std::optional<EmbreeScene> scene_;
};

class RasterSource : public ViewSource {
 public:
  RasterSource(const CacheReader& cache, vk::Context& context, const std::string& technique)
      : tubes_(require_tubes(cache, technique)), renderer_(context, tubes_) {
    options_.technique = vk::parse_raster_technique(technique);
  }
  ViewFrame render(const Camera& camera, const TransferFunction& tf, int width,
                   int height) override {
    options_.width = width, options_.height = height;
    vk::RasterFrame frame = renderer_.render(camera, tf, options_);
    return {std::move(frame.image), frame.stats.seconds, frame.stats.frame_bytes};
  }
  Bounds bounds() const override { return compute_bounds(tubes_); }

 private:
  TubeMesh tubes_;
  vk::RasterRenderer renderer_;
  vk::RasterOptions options_;
};

class VoxelSource : public ViewSource {
 public:
  VoxelSource(const CacheReader& cache, vk::Context& context, bool gpu)
      : grid_(load_voxels_checked(cache)), occupancy_(build_occupancy(grid_)) {
    // As `render --technique vrc`: the tube mesh's bounds, else the lines' widened by the radius.
    if (cache.exists("/assets/tubes")) {
      const auto provenance = cache.provenance("/assets/tubes");
      if (provenance && provenance->stats.contains("radius_world"))
        options_.radius = provenance->stats["radius_world"].get<double>();
      bounds_ = compute_bounds(load_tubes(cache));
    } else {
      bounds_ = compute_bounds(load_lines(cache));
      const float radius = float(vrc_radius(grid_, options_.radius));
      for (size_t k = 0; k < 3; ++k) {
        bounds_.min[k] -= radius;
        bounds_.max[k] += radius;
      }
    }
    if (gpu) caster_.emplace(context, grid_, occupancy_);
  }
  ViewFrame render(const Camera& camera, const TransferFunction& tf, int width,
                   int height) override {
    options_.width = width, options_.height = height;
    VrcFrame frame = caster_ ? caster_->render(camera, tf, options_)
                             : cast_voxel_frame(grid_, occupancy_, camera, tf, options_);
    return {std::move(frame.image), frame.stats.seconds, frame.stats.frame_bytes};
  }
  Bounds bounds() const override { return bounds_; }

 private:
  static VoxelGrid load_voxels_checked(const CacheReader& cache) {
    if (!cache.exists(kVoxelsGroup))
      throw Error("vrc ray casts the voxel line grid; bake --assets voxels first");
    return load_voxels(cache);
  }
  VoxelGrid grid_;
  OccupancyPyramid occupancy_;
  Bounds bounds_;
  VrcOptions options_;
  std::optional<vk::VoxelCaster> caster_;
};

}  // namespace

const std::vector<std::string>& view_techniques() {
  static const std::vector<std::string> names{"reference", "embree", "opaque", "dp",
                                              "ll",        "mlab",   "mlabdb", "mboit",
                                              "wboit",     "vrc",    "vrc-gpu"};
  return names;
}

std::unique_ptr<ViewSource> make_view_source(const std::string& technique, const CacheReader& cache,
                                             vk::Context& context) {
  if (technique == "reference" || technique == "embree")
    return std::make_unique<EmbreeSource>(cache, technique == "reference");
  if (technique == "vrc" || technique == "vrc-gpu")
    return std::make_unique<VoxelSource>(cache, context, technique == "vrc-gpu");
  if (vk::is_raster_technique(technique))
    return std::make_unique<RasterSource>(cache, context, technique);
  if (technique == "rtx")
    throw Error("rtx is not in the viewer yet; use linebake render --technique rtx");
  throw Error("unknown technique '" + technique + "'");
}

}  // namespace linebake::cli
