// linebake render <cache>: renders frames of a flight with any technique of the registry
// (lib/techniques/technique.hpp): the ground truth (reference), CPU ray tracing of curves
// (embree), the Vulkan rasterisation techniques (opaque, dp, ll, mlab, mlabdb, mboit, wboit),
// voxel ray casting (vrc, CPU or Vulkan compute) or Vulkan ray tracing (rtx).

#include <algorithm>
#include <iostream>
#include <nlohmann/json.hpp>

#include "cache/cache.hpp"
#include "cli_contract.hpp"
#include "commands.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/interrupt.hpp"
#include "core/json_file.hpp"
#include "core/memory_budget.hpp"
#include "core/progress.hpp"
#include "flight_plan.hpp"
#include "render_option_ranges.hpp"
#include "techniques/framing.hpp"
#include "techniques/technique.hpp"

namespace linebake::cli {
namespace {

// Renders the flight's frames with any technique of the registry (lib/techniques): images,
// depth-complexity images and --stats with the technique's own fields.
template <class Args>
void render_frames(const Args& args, const CacheReader& cache, const TransferFunction& tf,
                   const TechniqueOptions& options) {
  const Technique& technique = find_technique(args.technique);
  std::unique_ptr<PreparedTechnique> prepared =
      technique.prepare(technique.info, cache, args.cache, options);
  for (const std::string& w : prepared->warnings) warn(args.technique + ": " + w);
  FlightPlan plan = plan_flight(args.flight, args.frame_count, args.frame, args.frames,
                                flight_bounds(cache), options.width, options.height);
  // A --radius past the cached one draws past the framed box: the clip planes hold it (embree's
  // rays had been cut at them, leaving a capsule's near half, or all of it, undrawn).
  if (options.radius > 0)
    for (Camera& camera : plan.cameras)
      hold_in_clip_planes(camera, drawn_bounds(cache, options.radius));
  const bool numbered = plan.frames.size() > 1;
  nlohmann::json stats = prepared->stats();
  stats["technique"] = args.technique;
  stats["transfer_function"] = tf.name;
  stats["flight"] = to_string(plan.kind);
  stats["frames"] = nlohmann::json::array();
  // The first frame of a Vulkan technique compiles its pipelines (lavapipe: LLVM), and any
  // technique's fills the caches: a frame or two first keeps that out of the timed frames.
  for (int i = 0; i < args.warm_up; ++i) {
    throw_if_interrupted();
    prepared->render(plan.cameras[size_t(plan.frames.front())], tf, options.width, options.height);
  }
  stats["warm_up_frames"] = args.warm_up;
  TerminalProgress progress("render");
  std::vector<double> seconds;
  std::string last_note;
  for (size_t i = 0; i < plan.frames.size(); ++i) {
    throw_if_interrupted();  // between frames: finished frames are kept
    const int number = plan.frames[i];
    const Camera& c = plan.cameras[size_t(number)];
    const TechniqueFrame frame = prepared->render(c, tf, options.width, options.height);
    throw_if_interrupted();  // during the frame: it is not written, the finished ones are kept
    write_image(frame.image, frame_path(args.output, number, numbered), args.png_bits);
    if (!args.depth_image.empty() && !frame.depth_complexity.empty())
      write_png_counts(frame.depth_complexity, options.width, options.height,
                       frame_path(args.depth_image, number, numbered));
    if (!args.depth_image.empty() && frame.depth_complexity.empty() && i == 0)
      warn(args.technique + ": counts no hits per pixel, so --depth-complexity writes nothing " +
           "(`linebake depth-complexity` counts the tube mesh's fragments)");
    nlohmann::json entry = frame.stats;
    entry["frame"] = number;
    entry["seconds"] = frame.seconds;
    entry["size"] = {options.width, options.height};
    entry["camera"] = {{"eye", {c.eye.x, c.eye.y, c.eye.z}},
                       {"target", {c.target.x, c.target.y, c.target.z}},
                       {"fov", c.fov_y_degrees}};
    stats["frames"].push_back(std::move(entry));
    for (const std::string& w : frame.warnings)
      warn(args.technique + ": frame " + std::to_string(number) + ": " + w);
    progress.update(i + 1, plan.frames.size());
    seconds.push_back(frame.seconds);
    last_note = frame.note;
    if (!TerminalProgress::enabled())
      std::cerr << "frame " << number << ": " << format_seconds(frame.seconds)
                << (frame.note.empty() ? "" : ", " + frame.note) << "\n";
  }
  progress.finish();
  if (!args.stats.empty()) write_file_atomically(args.stats, json_text(stats, 2) + "\n");
  if (args.json) std::cout << json_text(stats, 2) << "\n";
  // What stays on the terminal after the bar.
  std::vector<double> sorted = seconds;
  std::sort(sorted.begin(), sorted.end());
  const std::string first = frame_path(args.output, plan.frames.front(), numbered);
  const std::string last = frame_path(args.output, plan.frames.back(), numbered);
  if (plan.frames.size() == 1)
    say(args.technique + ": 1 frame in " + format_seconds(sorted[0]) +
        (last_note.empty() ? "" : ", " + last_note) + ": " + first);
  else
    say(args.technique + ": " + std::to_string(plan.frames.size()) + " frames, median " +
        format_seconds(median(seconds)) + " per frame: " + first + " .. " + last);
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
    std::string rt_geometry, tiles_geometry = "capsules", tiles_sort = "auto";
    std::string tiles_strips = "none";
    bool rebuild = false, no_compaction = false;
    int max_iterations = 1024;
    uint64_t capacity = 0;
    uint32_t node_bytes = 24;
    bool validation = false, no_interlock = false;
    int max_layers = 2000, layers = 0, wboit_weight = 0, moments = 4;
    double tau_alpha = 0.2, tau_opaque = 0.98, beta = 0.1, moment_bias = -1;
    std::string moment_basis = "power";
    int frame = 0, frame_count = 64, png_bits = 8, warm_up = 0;
    float radius = 0;
    bool early = false, packets = false, json = false;
    std::string memory_budget;
  };
  auto args = std::make_shared<Args>();
  sub->add_option("cache", args->cache, "Asset cache (.lbc.h5)")->required();
  sub->add_option("--technique", args->technique,
                  "embree (CPU ray tracing of curves) | reference (exact, the tube mesh) | "
                  "opaque | dp | ll | mlab | mlabdb | mboit | wboit (Vulkan rasterisation of "
                  "the tube mesh) | vrc (voxel ray casting of the voxel line grid) | rtx "
                  "(Vulkan ray tracing; needs a device with VK_KHR_ray_tracing_pipeline) | tiles "
                  "(exact, Vulkan compute only: capsules binned into tiles and sorted); default "
                  "embree")
      ->check(render_option_check("--technique"));
  sub->add_option("--on", args->on, "vrc: cpu (TBB, default) | gpu (Vulkan compute)")
      ->check(render_option_check("--on"));
  auto* no_early = sub->add_flag("--no-early-termination", args->no_early_termination,
                                 "Composite every hit (the default, except for vrc, which stops "
                                 "at opacity 0.99 as the paper's VRC)");
  sub->add_flag("--no-skip", args->no_skip,
                "vrc: walk every voxel (default: skip cells empty in the occupancy mips)");
  sub->add_option("--rtx-geometry", args->rt_geometry,
                  "rtx: triangles (the tube mesh, default) | capsules (AABBs with an analytic "
                  "intersection shader); default: what the cached BLAS were built over")
      ->check(render_option_check("--rtx-geometry"));
  sub->add_option("--tiles-geometry", args->tiles_geometry,
                  "tiles: capsules (the lines with the tubes' radius, default) | triangles (the "
                  "cached tube mesh, as reference and the raster techniques)")
      ->check(render_option_check("--tiles-geometry"));
  sub->add_option("--tiles-sort", args->tiles_sort,
                  "tiles: the key sort's path: auto (subgroups where the device has them, "
                  "except lavapipe; default) | subgroups | shared (shared memory only); the same "
                  "order either way")
      ->check(render_option_check("--tiles-sort"));
  sub->add_option("--tiles-strips", args->tiles_strips,
                  "tiles: the tiles composited by four workgroups of 64, a strip of 16x4 pixels "
                  "each, instead of one of 256: none (default) | crowded (the crowded tiles and "
                  "the walks over fewer than 512 tiles) | all; the same image either way")
      ->check(render_option_check("--tiles-strips"));
  sub->add_flag("--rebuild", args->rebuild,
                "rtx: build the BLAS even if the cache holds serialised ones for this device");
  sub->add_flag("--rtx-no-compaction", args->no_compaction, "rtx: do not compact rebuilt BLAS");
  sub->add_option("--max-iterations", args->max_iterations,
                  "rtx: traces per pixel at most (default 1024); pixels that run out are counted")
      ->check(render_option_check("--max-iterations"));
  sub->add_option("--sort", args->sort,
                  "ll: per-pixel sort insertion | shell | heap (default) | quick-hybrid")
      ->check(render_option_check("--sort"));
  sub->add_option("--node-bytes", args->node_bytes,
                  "ll: 24 (float colour, default) or 12 (RGBA8 colour, as LineVis) bytes per node")
      ->check(render_option_check("--node-bytes"));
  sub->add_option("--capacity", args->capacity,
                  "ll: fragment nodes to start with (default 20 x pixels; grows on overflow)")
      ->check(render_option_check("--capacity"));
  sub->add_option("--max-layers", args->max_layers, "dp: peel at most this many layers (2000)")
      ->check(render_option_check("--max-layers"));
  sub->add_option(
         "--layers", args->layers,
         "mlab: nodes per pixel (default 8); mlabdb: 1 front + k-1 back, k >= 2 (default 4)")
      ->check(render_option_check("--layers"));
  sub->add_option("--tau-alpha", args->tau_alpha,
                  "mlabdb: opacity above which the back bucket starts (0.2)")
      ->check(render_option_check("--tau-alpha"));
  sub->add_option("--tau-opaque", args->tau_opaque,
                  "mlabdb: opacity from which fragments hide what is behind (0.98)")
      ->check(render_option_check("--tau-opaque"));
  sub->add_option("--beta", args->beta, "mboit: overestimation (0.1; MBOIT's authors: 0.25)")
      ->check(render_option_check("--beta"));
  sub->add_option("--moments", args->moments,
                  "mboit: real moments beyond b0, 4 (default), 6 or 8 (trigonometric: 2, 3, 4 "
                  "complex moments)")
      ->check(render_option_check("--moments"));
  sub->add_option("--moment-basis", args->moment_basis, "mboit: power (default) | trigonometric")
      ->check(render_option_check("--moment-basis"));
  sub->add_option("--moment-bias", args->moment_bias,
                  "mboit: moment bias (default by basis and count for float32, e.g. 5e-7 for "
                  "4 power moments)")
      ->check(render_option_check("--moment-bias"));
  sub->add_option("--wboit-weight", args->wboit_weight,
                  "wboit: 0 (the public code's, default) or McGuire & Bavoil's equation 7, 8, 9")
      ->check(render_option_check("--wboit-weight"));
  sub->add_flag("--no-interlock", args->no_interlock,
                "mlab, mlabdb: use the per-pixel spin lock even where interlock exists");
  sub->add_option("--device", args->device,
                  "Vulkan device: part of its name (default: a discrete GPU, else the first)");
  sub->add_flag("--validation", args->validation,
                "Vulkan: enable the Khronos validation layer; validation errors fail the run");
  sub->add_option("--embree-geometry", args->geometry,
                  "embree: linear (default) | bezier curves | capsules (user geometry)")
      ->check(render_option_check("--embree-geometry"));
  sub->add_option("--embree-quality", args->quality,
                  "embree, reference: Embree build quality: low | medium (default) | high")
      ->check(render_option_check("--embree-quality"));
  sub->add_option("--tf", args->tf,
                  "Transfer function: opaque | semi (default) | transparent | FILE.json");
  sub->add_option("--attribute", args->attribute,
                  "embree, rtx, tiles: vertex attribute of the curves and capsules (default: the "
                  "tube mesh's, else the first)");
  sub->add_option("--radius", args->radius,
                  "embree, rtx, tiles, vrc: curve and capsule radius in world units (default: the "
                  "cached tubes', else 0.001 x diagonal; vrc: half a voxel)")
      ->check(render_option_check("--radius"));
  sub->add_option("--flight", args->flight, "orbit-zoom (default) | orbit | KEYFRAMES.json");
  sub->add_option("--frame-count", args->frame_count, "Frames in the flight (default 64)")
      ->check(render_option_check("--frame-count"));
  auto* frame =
      sub->add_option("--frame", args->frame, "Frame to render, 0 .. frame count - 1 (default 0)")
          ->check(render_option_check("--frame"));
  auto* frames =
      sub->add_option("--frames", args->frames, "all: render every frame (outputs get _NNN)")
          ->check(render_option_check("--frames"));
  frame->excludes(frames);
  sub->add_option("--size", args->size, "Image size WxH (default 1280x720)")
      ->check(render_option_check("--size"));
  sub->add_option("-o,--output", args->output, "Image: .png (sRGB) or .pfm (linear float)")
      ->required();
  sub->add_option("--warm-up", args->warm_up,
                  "Frames rendered first from the first frame's camera, neither timed nor "
                  "written: shaders compiled and caches filled before the timed frames "
                  "(default 0)")
      ->check(CLI::Range(0, 100));
  sub->add_option("--png-bits", args->png_bits, "8 (default) or 16")
      ->check(render_option_check("--png-bits"));
  sub->add_option("--stats", args->stats, "Frame statistics as JSON");
  sub->add_option("--depth-complexity", args->depth_image,
                  "16-bit grey PNG of front hits per pixel");
  sub->add_option(
         "--hits", args->hits,
         "embree, reference, rtx: how hits are found: filter (every hit, collected by a filter or "
         "any-hit shader; default) | stepping (closest-hit queries from just past the "
         "last hit)")
      ->check(render_option_check("--hits"));
  sub->add_flag("--packets", args->packets,
                "Trace 4x2 ray packets (rtcIntersect8) instead of single rays (filter hits)");
  sub->add_flag("--early-termination", args->early,
                "Stop compositing at opacity 0.99 (vrc's default; never for ground truth)")
      ->excludes(no_early);
  sub->add_flag("--json", args->json, "Print the --stats JSON on stdout");
  sub->add_option("--memory-budget", args->memory_budget,
                  "Refuse a frame whose estimated memory exceeds this, e.g. 8G (default: "
                  "half of physical memory, or of the cgroup's or ulimit -v's limit when less)")
      ->check(render_option_check("--memory-budget"));
  const auto body = [args, sub] {
    // An option the technique does not read is a mistake, not a no-op.
    check_technique_options(find_technique(args->technique).info, given_options(sub));
    check_cache_input(args->cache);
    const auto [width, height] = parse_image_size(args->size);
    if (args->frames.empty() && args->frame >= args->frame_count)
      throw UsageError("--frame " + std::to_string(args->frame) + ": the flight has " +
                       std::to_string(args->frame_count) + " frames, 0 to " +
                       std::to_string(args->frame_count - 1) + " (--frame-count)");
    // Every output before any work: an image format, directories that exist and take files.
    check_image_output(args->output);
    // A PFM holds floats: --png-bits with it would be read by nothing (it had been taken).
    refuse_unless(sub, {"png-bits"}, is_png_path(args->output), "with a .png image (-o)");
    check_output_location(args->stats);
    check_depth_image_output(args->depth_image);
    check_frame_outputs({args->output, args->depth_image}, {args->stats},
                        planned_frames(args->frame_count, args->frame, args->frames),
                        {args->cache, args->tf, args->flight});
    TechniqueOptions o;
    o.width = width, o.height = height;
    o.early_termination = args->early;
    o.device = args->device;
    o.validation = args->validation;
    o.hits = args->hits;
    o.geometry = args->geometry, o.quality = args->quality;
    o.packets = args->packets;
    o.radius = args->radius;
    o.attribute = args->attribute;
    o.sort = args->sort;
    o.capacity = args->capacity;
    o.node_bytes = args->node_bytes;
    o.max_layers = args->max_layers, o.layers = args->layers;
    o.wboit_weight = args->wboit_weight, o.moments = args->moments;
    o.tau_alpha = args->tau_alpha, o.tau_opaque = args->tau_opaque;
    o.beta = args->beta, o.moment_bias = args->moment_bias;
    o.moment_basis = args->moment_basis;
    o.interlock = !args->no_interlock;
    o.on = args->on;
    o.vrc_early_termination = !args->no_early_termination;
    o.skip_empty_space = !args->no_skip;
    o.rt_geometry = args->rt_geometry;
    o.tiles_geometry = args->tiles_geometry;
    o.tiles_sort = args->tiles_sort;
    o.tiles_strips = args->tiles_strips;
    o.rebuild = args->rebuild, o.compaction = !args->no_compaction;
    o.max_iterations = args->max_iterations;
    // The depth complexity costs embree and reference every hit of every ray: only when shown.
    o.every_hit = !args->stats.empty() || args->json || !args->depth_image.empty();
    set_memory_budget(o, args->memory_budget);
    check_frame_memory(args->technique, args->size,
                       estimate_frame_bytes(find_technique(args->technique), o),
                       args->memory_budget);
    const TransferFunction tf = resolve_transfer_function(args->tf);
    const CacheReader cache(args->cache);
    render_frames(*args, cache, tf, o);
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
