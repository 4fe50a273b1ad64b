// linebake render <cache>: renders frames of a flight with the CPU ray tracer (technique
// `embree`, curves), the ground truth (technique `reference`, the triangle tube mesh) or one of
// the Vulkan rasterisation techniques (opaque, dp, ll, mlab, mlabdb, mboit, wboit), or voxel
// ray casting of the voxel line grid (vrc, CPU or Vulkan compute).

#include <cmath>
#include <iostream>
#include <nlohmann/json.hpp>

#include "accel/capsule_segments.hpp"
#include "accel/embree_scene.hpp"
#include "cache/cache.hpp"
#include "cache/embree_store.hpp"
#include "cache/line_store.hpp"
#include "cache/rtx_store.hpp"
#include "cache/tube_store.hpp"
#include "cache/voxel_store.hpp"
#include "commands.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/interrupt.hpp"
#include "core/progress.hpp"
#include "curve_defaults.hpp"
#include "flight_plan.hpp"
#include "pipeline/bake.hpp"
#include "render/ray_tracer.hpp"
#include "render/voxel_ray_caster.hpp"
#include "render/vulkan/raster_renderer.hpp"
#include "render/vulkan/rt_renderer.hpp"
#include "render/vulkan/rt_scene.hpp"
#include "render/vulkan/voxel_caster.hpp"
#include "tubes/tube_builder.hpp"

namespace linebake::cli {
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

nlohmann::json to_json(const FrameStats& s, const Camera& c, int frame) {
  return {{"frame", frame},
          {"seconds", s.seconds},
          {"size", {s.width, s.height}},
          {"camera",
           {{"eye", {c.eye.x, c.eye.y, c.eye.z}},
            {"target", {c.target.x, c.target.y, c.target.z}},
            {"fov", c.fov_y_degrees}}},
          {"front_hits", s.counters.hits},
          {"composited_hits", s.counters.composited},
          {"duplicate_hits_removed", s.counters.duplicates},
          {"back_hits_rejected", s.counters.back_hits},
          {"depth_complexity",
           {{"max", s.max_depth_complexity},
            {"mean", s.mean_depth_complexity},
            {"mean_covered", s.mean_covered_depth_complexity}}},
          {"frame_bytes", s.frame_bytes}};
}

// The Vulkan techniques: the cached tube mesh rasterised headless.
template <class Args>
void render_raster(const Args& args, const CacheReader& cache, const TransferFunction& tf,
                   int width, int height) {
  if (!cache.exists("/assets/tubes"))
    throw Error(args.cache +
                ": the Vulkan techniques draw the tube mesh; bake --assets tubes first");
  const TubeMesh tubes = load_tubes(cache);
  vk::ContextOptions context_options;
  context_options.device = args.device;
  context_options.validation = args.validation;
  vk::Context context(context_options);
  vk::RasterRenderer renderer(context, tubes);
  vk::RasterOptions o;
  o.technique = vk::parse_raster_technique(args.technique);
  o.width = width, o.height = height;
  o.sort = vk::parse_list_sort(args.sort);
  o.capacity = args.capacity;
  o.early_termination = args.early;
  o.max_layers = args.max_layers;
  o.layers = args.layers;
  o.tau_alpha = args.tau_alpha, o.tau_opaque = args.tau_opaque;
  o.mboit_beta = args.beta;
  o.moment_basis = vk::parse_moment_basis(args.moment_basis);
  o.moments = args.moments;
  if (args.moment_bias >= 0) o.mboit_bias = args.moment_bias;
  o.wboit_weight = args.wboit_weight;
  o.interlock = !args.no_interlock;
  const FlightPlan plan = plan_flight(args.flight, args.frame_count, args.frame, args.frames,
                                      compute_bounds(tubes), width, height);
  const std::vector<Camera>& cameras = plan.cameras;
  const std::vector<int>& frames = plan.frames;
  const bool numbered = frames.size() > 1;
  nlohmann::json stats = {{"technique", args.technique},      {"device", context.info().name},
                          {"driver", context.info().driver},  {"transfer_function", tf.name},
                          {"flight", to_string(plan.kind)},   {"mesh_bytes", renderer.mesh_bytes()},
                          {"frames", nlohmann::json::array()}};
  if (o.technique == vk::RasterTechnique::LinkedLists) stats["sort"] = vk::to_string(o.sort);
  if (o.technique == vk::RasterTechnique::MlabBuckets)
    stats["tau"] = {{"alpha", o.tau_alpha}, {"opaque", o.tau_opaque}};
  if (o.technique == vk::RasterTechnique::Mboit) {
    stats["beta"] = o.mboit_beta;
    stats["moments"] = {
        {"basis", vk::to_string(o.moment_basis)},
        {"count", o.moments},
        {"bias", o.mboit_bias.value_or(vk::default_moment_bias(o.moment_basis, o.moments))}};
  }
  TerminalProgress progress("render");
  for (size_t i = 0; i < frames.size(); ++i) {
    throw_if_interrupted();  // between frames: finished frames are kept
    const vk::RasterFrame frame = renderer.render(cameras[size_t(frames[i])], tf, o);
    if (context.validation_errors() > 0)
      throw Error("Vulkan validation: " + std::to_string(context.validation_errors()) +
                  " error(s); last: " + context.last_validation_error());
    write_image(frame.image, frame_path(args.output, frames[i], numbered), args.png_bits);
    if (!args.depth_image.empty() && !frame.depth_complexity.empty())
      write_png_counts(frame.depth_complexity, width, height,
                       frame_path(args.depth_image, frames[i], numbered));
    nlohmann::json passes = nlohmann::json::object();
    for (const auto& [name, ms] : frame.stats.pass_ms) passes[name] = ms;
    const Camera& c = cameras[size_t(frames[i])];
    stats["frames"].push_back(
        {{"frame", frames[i]},
         {"seconds", frame.stats.seconds},
         {"gpu_ms", passes},
         {"size", {width, height}},
         {"camera",
          {{"eye", {c.eye.x, c.eye.y, c.eye.z}},
           {"target", {c.target.x, c.target.y, c.target.z}},
           {"fov", c.fov_y_degrees}}},
         {"fragments", frame.stats.fragments},
         {"node_capacity", frame.stats.capacity},
         {"regrows", frame.stats.regrows},
         {"depth_complexity",
          {{"max", frame.stats.max_depth_complexity}, {"mean", frame.stats.mean_depth_complexity}}},
         {"frame_bytes", frame.stats.frame_bytes}});
    if (frame.stats.layers > 0) {
      stats["frames"].back()["layers"] = frame.stats.layers;
      if (o.technique == vk::RasterTechnique::DepthPeeling)
        stats["frames"].back()["layers_capped"] = frame.stats.layers_capped;
    }
    if (!frame.stats.critical_section.empty())
      stats["frames"].back()["critical_section"] = frame.stats.critical_section;
    if (frame.stats.layers_capped)
      std::cerr << "warning: frame " << frames[i] << " needs " << frame.stats.max_depth_complexity
                << " layers; dp peeled " << frame.stats.layers << " (--max-layers)\n";
    progress.update(i + 1, frames.size());
    if (!TerminalProgress::enabled())
      std::cerr << "frame " << frames[i] << ": " << frame.stats.seconds << " s on "
                << context.info().name << "\n";
  }
  if (!args.stats.empty()) write_file_atomically(args.stats, stats.dump(2) + "\n");
}

// Voxel ray casting from the cached voxel line grid, on the CPU or with Vulkan compute. The
// flight frames the cached tube mesh's bounds when there is one (so frames compare with the
// reference's), else the lines' widened by the radius.
template <class Args>
void render_vrc(const Args& args, const CacheReader& cache, const TransferFunction& tf, int width,
                int height) {
  if (!cache.exists(kVoxelsGroup))
    throw Error(args.cache + ": vrc ray casts the voxel line grid; bake --assets voxels first");
  const VoxelGrid grid = load_voxels(cache);
  VrcOptions o;
  o.width = width, o.height = height;
  o.early_termination = !args.no_early_termination;
  o.skip_empty_space = !args.no_skip;
  Bounds bounds;
  const auto tube_provenance =
      cache.exists("/assets/tubes") ? cache.provenance("/assets/tubes") : std::nullopt;
  o.radius = args.radius;
  if (!(o.radius > 0) && tube_provenance && tube_provenance->stats.contains("radius_world"))
    o.radius = tube_provenance->stats["radius_world"].template get<double>();
  const double radius = vrc_radius(grid, o.radius);  // what the casters use
  if (tube_provenance) {
    bounds = compute_bounds(load_tubes(cache));
  } else {
    bounds = compute_bounds(load_lines(cache));
    for (int k = 0; k < 3; ++k) {
      bounds.min[size_t(k)] -= float(radius);
      bounds.max[size_t(k)] += float(radius);
    }
  }
  const bool gpu = args.on == "gpu";
  const OccupancyPyramid occupancy = build_occupancy(grid);
  std::optional<vk::Context> context;
  std::optional<vk::VoxelCaster> caster;
  if (gpu) {
    vk::ContextOptions context_options;
    context_options.device = args.device;
    context_options.validation = args.validation;
    context.emplace(context_options);
    caster.emplace(*context, grid, occupancy);
  }
  const FlightPlan plan =
      plan_flight(args.flight, args.frame_count, args.frame, args.frames, bounds, width, height);
  const bool numbered = plan.frames.size() > 1;
  nlohmann::json stats = {{"technique", "vrc"},
                          {"on", args.on},
                          {"transfer_function", tf.name},
                          {"flight", to_string(plan.kind)},
                          {"grid",
                           {{"resolution", grid.resolution},
                            {"quantization", grid.quantization},
                            {"voxel_size", grid.voxel_size},
                            {"representation_bytes", grid.representation_bytes()}}},
                          {"occupancy_levels", occupancy.levels()},
                          {"occupancy_bytes", occupancy.bytes()},
                          {"radius", radius},
                          {"radius_clamped", o.radius > grid.voxel_size},
                          {"early_termination", o.early_termination},
                          {"skip_empty_space", o.skip_empty_space},
                          {"frames", nlohmann::json::array()}};
  if (gpu) stats["device"] = context->info().name;
  TerminalProgress progress("render");
  for (size_t i = 0; i < plan.frames.size(); ++i) {
    throw_if_interrupted();  // between frames: finished frames are kept
    const Camera& c = plan.cameras[size_t(plan.frames[i])];
    const VrcFrame frame =
        gpu ? caster->render(c, tf, o) : cast_voxel_frame(grid, occupancy, c, tf, o);
    if (gpu && context->validation_errors() > 0)
      throw Error("Vulkan validation: " + std::to_string(context->validation_errors()) +
                  " error(s); last: " + context->last_validation_error());
    write_image(frame.image, frame_path(args.output, plan.frames[i], numbered), args.png_bits);
    if (!args.depth_image.empty())
      write_png_counts(frame.depth_complexity, width, height,
                       frame_path(args.depth_image, plan.frames[i], numbered));
    const VrcStats& s = frame.stats;
    stats["frames"].push_back({{"frame", plan.frames[i]},
                               {"seconds", s.seconds},
                               {"size", {width, height}},
                               {"camera",
                                {{"eye", {c.eye.x, c.eye.y, c.eye.z}},
                                 {"target", {c.target.x, c.target.y, c.target.z}},
                                 {"fov", c.fov_y_degrees}}},
                               {"hits", s.hits},
                               {"depth_complexity", {{"max", s.max_depth_complexity}}},
                               {"voxels_visited", s.voxels_visited},
                               {"cells_skipped", s.cells_skipped},
                               {"chords_tested", s.chords_tested},
                               {"frame_bytes", s.frame_bytes}});
    if (gpu) stats["frames"].back()["gpu_ms"] = caster->last_gpu_ms();
    progress.update(i + 1, plan.frames.size());
    if (!TerminalProgress::enabled())
      std::cerr << "frame " << plan.frames[i] << ": " << s.seconds << " s\n";
  }
  if (!args.stats.empty()) write_file_atomically(args.stats, stats.dump(2) + "\n");
}

// Vulkan ray tracing. The BLAS come from the cache's /assets/rtx when they were serialised on this
// driver from the same geometry; otherwise (or with --rebuild) they are built here, and the stats
// say which and why.
template <class Args>
void render_rtx(const Args& args, const CacheReader& cache, const TransferFunction& tf, int width,
                int height) {
  vk::ContextOptions context_options;
  context_options.device = args.device;
  context_options.validation = args.validation;
  context_options.ray_tracing = true;
  std::optional<vk::Context> context;
  try {
    context.emplace(context_options);
  } catch (const vk::RayTracingUnsupported& e) {
    throw vk::RayTracingUnsupported(std::string("rtx: ") + e.what());
  }
  // The geometry: the flag, else what the cache's BLAS were built over, else triangles.
  std::optional<StoredRtx> stored;
  if (cache.exists(kRtxGroup)) stored = load_rtx(cache);
  const std::string geometry = !args.rt_geometry.empty() ? args.rt_geometry
                               : stored                  ? stored->geometry
                                                         : "triangles";
  const bool has_tubes = cache.exists("/assets/tubes");
  const auto tube_provenance = has_tubes ? cache.provenance("/assets/tubes") : std::nullopt;
  TubeMesh tubes;
  CapsuleSegments capsules;
  LineSet lines;
  std::optional<vk::RtScene> scene;
  std::string source;
  Bounds bounds;
  if (geometry == "triangles") {
    if (!has_tubes)
      throw Error(args.cache +
                  ": rtx traces the tube mesh's triangles; bake --assets tubes first "
                  "(or --rt-geometry capsules)");
    tubes = load_tubes(cache);
    bounds = compute_bounds(tubes);
    scene.emplace(*context, tubes);
    source = tube_provenance ? tube_provenance->key : "";
  } else {
    lines = load_lines(cache);
    const auto [radius, attribute] =
        curve_defaults(args.radius, args.attribute, tube_provenance, lines);
    capsules = build_capsule_segments(lines, radius, attribute);
    bounds = compute_bounds(lines);
    for (size_t k = 0; k < 3; ++k) bounds.min[k] -= radius, bounds.max[k] += radius;
    scene.emplace(*context, capsules);
    const auto lines_provenance = cache.provenance("/lines");
    source = rtx_capsules_source(
        lines_provenance ? lines_provenance->stats.value("content_hash", "") : "", radius,
        attribute);
  }
  // Cached BLAS, else a build.
  std::string rebuild_reason;
  if (args.rebuild)
    rebuild_reason = "--rebuild";
  else if (!stored)
    rebuild_reason = "the cache has no serialised BLAS (bake --assets rtx)";
  else if (stored->geometry != geometry)
    rebuild_reason = "the cached BLAS are over " + stored->geometry + ", not " + geometry;
  else if (stored->source != source)
    rebuild_reason = "the cached BLAS were built from other " +
                     std::string(geometry == "triangles" ? "tubes" : "capsules");
  else if (auto problem = scene->load(stored->blobs))
    rebuild_reason = *problem;
  if (!rebuild_reason.empty()) {
    if (stored && !args.rebuild)
      std::cerr << "linebake: rtx: cached BLAS not used (" << rebuild_reason << "); rebuilding\n";
    scene->build(!args.no_compaction);
  }
  vk::RtRenderer renderer(*context);
  vk::RtOptions o;
  o.width = width, o.height = height;
  o.early_termination = args.early;
  o.max_iterations = uint32_t(args.max_iterations);
  o.hits = vk::parse_rt_hits(args.hits);
  const FlightPlan plan =
      plan_flight(args.flight, args.frame_count, args.frame, args.frames, bounds, width, height);
  const bool numbered = plan.frames.size() > 1;
  nlohmann::json stats = {{"technique", "rtx"},
                          {"device", context->info().name},
                          {"driver", context->info().driver},
                          {"transfer_function", tf.name},
                          {"flight", to_string(plan.kind)},
                          {"acceleration_structures", vk::to_json(scene->figures())},
                          {"blas_source", rebuild_reason.empty() ? "cache" : "built"},
                          {"rebuild_reason", rebuild_reason},
                          {"early_termination", o.early_termination},
                          {"max_iterations", o.max_iterations},
                          {"hit_collection", vk::to_string(o.hits)},
                          {"frames", nlohmann::json::array()}};
  TerminalProgress progress("render");
  for (size_t i = 0; i < plan.frames.size(); ++i) {
    throw_if_interrupted();  // between frames: finished frames are kept
    const Camera& c = plan.cameras[size_t(plan.frames[i])];
    const vk::RtFrame frame = renderer.render(*scene, c, tf, o);
    if (context->validation_errors() > 0)
      throw Error("Vulkan validation: " + std::to_string(context->validation_errors()) +
                  " error(s); last: " + context->last_validation_error());
    write_image(frame.image, frame_path(args.output, plan.frames[i], numbered), args.png_bits);
    if (!args.depth_image.empty())
      write_png_counts(frame.depth_complexity, width, height,
                       frame_path(args.depth_image, plan.frames[i], numbered));
    const vk::RtStats& s = frame.stats;
    stats["frames"].push_back({{"frame", plan.frames[i]},
                               {"seconds", s.seconds},
                               {"gpu_ms", s.gpu_ms},
                               {"size", {width, height}},
                               {"camera",
                                {{"eye", {c.eye.x, c.eye.y, c.eye.z}},
                                 {"target", {c.target.x, c.target.y, c.target.z}},
                                 {"fov", c.fov_y_degrees}}},
                               {"hits", s.hits},
                               {"back_hits", s.back_hits},
                               {"seam_hits", s.seam_hits},
                               {"traces", s.traces},
                               {"truncated_pixels", s.truncated_pixels},
                               {"depth_complexity", {{"max", s.max_depth_complexity}}},
                               {"frame_bytes", s.frame_bytes}});
    if (s.truncated_pixels > 0)
      std::cerr << "linebake: rtx: frame " << plan.frames[i] << ": " << s.truncated_pixels
                << " pixels stopped at --max-iterations " << o.max_iterations << "\n";
    progress.update(i + 1, plan.frames.size());
    if (!TerminalProgress::enabled())
      std::cerr << "frame " << plan.frames[i] << ": " << s.seconds << " s (GPU " << s.gpu_ms
                << " ms)\n";
  }
  if (!args.stats.empty()) write_file_atomically(args.stats, stats.dump(2) + "\n");
}
}  // namespace

Command add_render(CLI::App& app) {
  auto* sub = app.add_subcommand("render", "Render frames of a flight from an asset cache");
  struct Args {
    std::string cache, technique = "embree", geometry = "linear", tf = "semi",
                       flight = "orbit-zoom";
    std::string frames, output, stats, depth_image, size = "1280x720", attribute,
                                                    quality = "medium", hits = "filter";
    std::string sort = "heap", device, on = "cpu";
    bool no_early_termination = false, no_skip = false;
    std::string rt_geometry;
    bool rebuild = false, no_compaction = false;
    int max_iterations = 1024;
    uint64_t capacity = 0;
    bool validation = false, no_interlock = false;
    int max_layers = 2000, layers = 0, wboit_weight = 0, moments = 4;
    double tau_alpha = 0.2, tau_opaque = 0.98, beta = 0.1, moment_bias = -1;
    std::string moment_basis = "power";
    int frame = 0, frame_count = 64, png_bits = 8;
    float radius = 0;
    bool early = false, packets = false;
    std::string memory_budget;
  };
  auto args = std::make_shared<Args>();
  sub->add_option("cache", args->cache, "Asset cache (.lbc.h5)")
      ->required()
      ->check(CLI::ExistingFile);
  sub->add_option("--technique", args->technique,
                  "embree (CPU ray tracing of curves) | reference (exact, the tube mesh) | "
                  "opaque | dp | ll | mlab | mlabdb | mboit | wboit (Vulkan rasterisation of "
                  "the tube mesh) | vrc (voxel ray casting of the voxel line grid) | rtx "
                  "(Vulkan ray tracing; needs a device with VK_KHR_ray_tracing_pipeline)")
      ->check(CLI::IsMember({"embree", "reference", "opaque", "dp", "ll", "mlab", "mlabdb", "mboit",
                             "wboit", "vrc", "rtx"}));
  sub->add_option("--on", args->on, "vrc: cpu (TBB, default) | gpu (Vulkan compute)")
      ->check(CLI::IsMember({"cpu", "gpu"}));
  sub->add_flag("--no-early-termination", args->no_early_termination,
                "vrc: composite every hit (default: stop at opacity 0.99, as the paper's VRC)");
  sub->add_flag("--no-skip", args->no_skip,
                "vrc: walk every voxel (default: skip cells empty in the occupancy mips)");
  sub->add_option("--rt-geometry", args->rt_geometry,
                  "rtx: triangles (the tube mesh, default) | capsules (AABBs with an analytic "
                  "intersection shader); default: what the cached BLAS were built over")
      ->check(CLI::IsMember({"triangles", "capsules"}));
  sub->add_flag("--rebuild", args->rebuild,
                "rtx: build the BLAS even if the cache holds serialised ones for this device");
  sub->add_flag("--no-compaction", args->no_compaction, "rtx: do not compact rebuilt BLAS");
  sub->add_option("--max-iterations", args->max_iterations,
                  "rtx: traces per pixel at most (default 1024); pixels that run out are counted")
      ->check(CLI::Range(1, 1 << 20));
  sub->add_option("--sort", args->sort,
                  "ll: per-pixel sort insertion | shell | heap (default) | quick-hybrid")
      ->check(CLI::IsMember({"insertion", "shell", "heap", "quick-hybrid"}));
  sub->add_option("--capacity", args->capacity,
                  "ll: fragment nodes to start with (default 20 x pixels; grows on overflow)");
  sub->add_option("--max-layers", args->max_layers, "dp: peel at most this many layers (2000)")
      ->check(CLI::Range(1, 100000));
  sub->add_option("--layers", args->layers,
                  "mlab: nodes per pixel (default 8); mlabdb: 1 front + k-1 back (default 4)")
      ->check(CLI::Range(1, 64));
  sub->add_option("--tau-alpha", args->tau_alpha,
                  "mlabdb: opacity above which the back bucket starts (0.2)")
      ->check(CLI::Range(0.0, 1.0));
  sub->add_option("--tau-opaque", args->tau_opaque,
                  "mlabdb: opacity from which fragments hide what is behind (0.98)")
      ->check(CLI::Range(0.0, 1.0));
  sub->add_option("--beta", args->beta, "mboit: overestimation (0.1; MBOIT's authors: 0.25)")
      ->check(CLI::Range(0.0, 1.0));
  sub->add_option("--moments", args->moments,
                  "mboit: real moments beyond b0, 4 (default), 6 or 8 (trigonometric: 2, 3, 4 "
                  "complex moments)")
      ->check(CLI::IsMember({4, 6, 8}));
  sub->add_option("--moment-basis", args->moment_basis, "mboit: power (default) | trigonometric")
      ->check(CLI::IsMember({"power", "trigonometric"}));
  sub->add_option("--moment-bias", args->moment_bias,
                  "mboit: moment bias (default by basis and count for float32, e.g. 5e-7 for "
                  "4 power moments)")
      ->check(CLI::Range(0.0, 0.5));
  sub->add_option("--wboit-weight", args->wboit_weight,
                  "wboit: 0 (the public code's, default) or McGuire & Bavoil's equation 7, 8, 9")
      ->check(CLI::IsMember({0, 7, 8, 9}));
  sub->add_flag("--no-interlock", args->no_interlock,
                "mlab, mlabdb: use the per-pixel spin lock even where interlock exists");
  sub->add_option("--device", args->device,
                  "Vulkan device: part of its name (default: a discrete GPU, else the first)");
  sub->add_flag("--validation", args->validation,
                "Vulkan: enable the Khronos validation layer; validation errors fail the run");
  sub->add_option("--geometry", args->geometry,
                  "embree: linear (default) | bezier curves | capsules (user geometry)")
      ->check(CLI::IsMember({"linear", "bezier", "capsules"}));
  sub->add_option("--quality", args->quality, "Embree build quality: low | medium | high")
      ->check(CLI::IsMember({"low", "medium", "high"}));
  sub->add_option("--tf", args->tf, "Transfer function: opaque | semi | transparent | FILE.json");
  sub->add_option("--attribute", args->attribute,
                  "Vertex attribute for the curves (default: the tube mesh's, else the first)");
  sub->add_option(
      "--radius", args->radius,
      "Curve radius in world units (default: the cached tubes', else 0.001 x diagonal)");
  sub->add_option("--flight", args->flight, "orbit-zoom (default) | orbit | KEYFRAMES.json");
  sub->add_option("--frame-count", args->frame_count, "Frames in the flight (default 64)")
      ->check(CLI::Range(1, 100000));
  sub->add_option("--frame", args->frame, "Frame to render (default 0)")
      ->check(CLI::NonNegativeNumber);
  sub->add_option("--frames", args->frames, "all: render every frame (outputs get _NNN)")
      ->check(CLI::IsMember({"all"}));
  sub->add_option("--size", args->size, "Image size WxH (default 1280x720)");
  sub->add_option("-o,--output", args->output, "Image: .png (sRGB) or .pfm (linear float)")
      ->required();
  sub->add_option("--png-bits", args->png_bits, "8 (default) or 16")->check(CLI::IsMember({8, 16}));
  sub->add_option("--stats", args->stats, "Frame statistics as JSON");
  sub->add_option("--depth-complexity", args->depth_image,
                  "16-bit grey PNG of front hits per pixel");
  sub->add_option("--hits", args->hits,
                  "embree, rtx: how hits are found: filter (every hit, collected by a filter or "
                  "any-hit shader; default) | stepping (closest-hit queries from just past the "
                  "last hit)")
      ->check(CLI::IsMember({"filter", "stepping"}));
  sub->add_flag("--packets", args->packets,
                "Trace 4x2 ray packets (rtcIntersect8) instead of single rays (filter hits)");
  sub->add_flag("--early-termination", args->early,
                "Stop compositing at opacity 0.99 (never for ground truth)");
  sub->add_option("--memory-budget", args->memory_budget,
                  "Refuse a frame whose estimated memory exceeds this, e.g. 8G (default: half of "
                  "physical memory)");
  const auto body = [args] {
    const auto [width, height] = parse_size(args->size);
    check_frame_memory(args->technique, args->size, uint64_t(width) * uint64_t(height),
                       args->capacity, args->layers, args->moments, args->memory_budget);
    const bool reference = args->technique == "reference";
    if (args->early && args->technique != "embree" && args->technique != "ll" &&
        args->technique != "vrc" && args->technique != "rtx")
      throw Error("--early-termination: only embree, ll, vrc and rtx stop early (" +
                  args->technique + " does not)");
    const TransferFunction tf = resolve_transfer_function(args->tf);
    const CacheReader cache(args->cache);
    const bool rtx_flags = !args->rt_geometry.empty() || args->rebuild || args->no_compaction ||
                           args->max_iterations != 1024;
    if (rtx_flags && args->technique != "rtx")
      throw Error("--rt-geometry, --rebuild, --no-compaction, --max-iterations: rtx options (not " +
                  args->technique + ")");
    if (args->technique == "rtx") {
      render_rtx(*args, cache, tf, width, height);
      return;
    }
    if (args->technique == "vrc") {
      render_vrc(*args, cache, tf, width, height);
      return;
    }
    if (args->on != "cpu" || args->no_early_termination || args->no_skip)
      throw Error("--on, --no-early-termination, --no-skip: vrc options (not " + args->technique +
                  ")");
    if (vk::is_raster_technique(args->technique)) {
      render_raster(*args, cache, tf, width, height);
      return;
    }
    const bool has_tubes = cache.exists("/assets/tubes");
    EmbreeOptions options;
    options.quality = parse_build_quality(args->quality);
    LineSet lines;
    TubeMesh tubes;
    // The curves take the cached tubes' radius and attribute, from their provenance (the mesh
    // itself is only loaded for the reference).
    const auto tube_provenance = has_tubes ? cache.provenance("/assets/tubes") : std::nullopt;
    std::optional<EmbreeScene> scene;
    bool from_cache = false;  // built from the cache's prepared Embree buffers
    if (reference) {
      if (!has_tubes)
        throw Error(args->cache +
                    ": the reference renders the tube mesh; bake --assets tubes first");
      tubes = load_tubes(cache);
      scene.emplace(EmbreeScene::from_tubes(tubes, options));
    } else {
      lines = load_lines(cache);
      options.geometry = parse_embree_geometry(args->geometry);
      const auto [radius, attribute] =
          curve_defaults(args->radius, args->attribute, tube_provenance, lines);
      // Bake's prepared buffers, when they are these curves, spare the preparation.
      std::optional<StoredCurves> stored;
      if (cache.exists(kEmbreeGroup)) {
        stored = load_embree(cache);
        if (stored->geometry != options.geometry || stored->radius != radius ||
            stored->attribute != attribute)
          stored.reset();
      }
      if (stored)
        scene.emplace(
            EmbreeScene::from_prepared(lines, std::move(stored->parts), attribute, options));
      else
        scene.emplace(EmbreeScene::from_lines(lines, radius, attribute, options));
      from_cache = stored.has_value();
    }
    TraceOptions trace;
    trace.width = width, trace.height = height;
    trace.early_termination = args->early;
    trace.collection = parse_hit_collection(args->hits);
    trace.packets = args->packets;
    if (trace.packets && trace.collection != HitCollection::Filter)
      throw Error("--packets: packets collect hits with the filter, not by stepping");
    const FlightPlan plan = plan_flight(args->flight, args->frame_count, args->frame, args->frames,
                                        scene->bounds(), width, height);
    const std::vector<Camera>& cameras = plan.cameras;
    const std::vector<int>& frames = plan.frames;
    const bool numbered = frames.size() > 1;
    nlohmann::json stats = {{"technique", args->technique},
                            {"transfer_function", tf.name},
                            {"hit_collection", to_string(trace.collection)},
                            {"packets", trace.packets},
                            {"flight", to_string(plan.kind)},
                            {"bvh", to_json(scene->stats())},
                            {"bvh_from_cached_buffers", from_cache},
                            {"frames", nlohmann::json::array()}};
    TerminalProgress progress("render");
    for (size_t i = 0; i < frames.size(); ++i) {
      throw_if_interrupted();  // between frames: finished frames are kept
      const Frame frame = trace_frame(*scene, cameras[frames[i]], tf, trace);
      write_image(frame.image, frame_path(args->output, frames[i], numbered), args->png_bits);
      if (!args->depth_image.empty())
        write_png_counts(frame.depth_complexity, width, height,
                         frame_path(args->depth_image, frames[i], numbered));
      stats["frames"].push_back(to_json(frame.stats, cameras[frames[i]], frames[i]));
      progress.update(i + 1, frames.size());
      if (!TerminalProgress::enabled())
        std::cerr << "frame " << frames[i] << ": " << frame.stats.seconds
                  << " s, depth complexity max " << frame.stats.max_depth_complexity << "\n";
    }
    if (!args->stats.empty()) write_file_atomically(args->stats, stats.dump(2) + "\n");
  };
  // Every output of the command (an image and its --stats, each frame, both exports) is
  // renamed into place at the end, or none is: a failure or an interruption leaves nothing.
  return [body] {
    OutputGroup outputs;
    body();
    outputs.commit();
  };
}

}  // namespace linebake::cli
