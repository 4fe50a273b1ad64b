// linebake depth-complexity <cache>: fragments per pixel along a flight (the paper's depth-
// complexity images), counted by one Vulkan draw of the tube mesh, or exactly by the CPU
// reference tracer (--on cpu). Writes a 16-bit grey PNG of the counts and statistics that size a
// linked-list buffer or a depth-peeling run: max, mean, mean over covered pixels, percentiles.

#include <algorithm>
#include <iostream>
#include <nlohmann/json.hpp>

#include "accel/embree_scene.hpp"
#include "cache/cache.hpp"
#include "cache/tube_store.hpp"
#include "cli_contract.hpp"
#include "commands.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/interrupt.hpp"
#include "core/json_file.hpp"
#include "core/measure.hpp"
#include "core/memory_budget.hpp"
#include "core/progress.hpp"
#include "flight_plan.hpp"
#include "render/ray_tracer.hpp"
#include "render/vulkan/raster_renderer.hpp"
#include "techniques/families.hpp"
#include "techniques/framing.hpp"

namespace linebake::cli {
namespace {

nlohmann::json summarise(std::vector<uint32_t> counts) {
  uint64_t total = 0, covered = 0;
  for (uint32_t c : counts) total += c, covered += c > 0;
  std::sort(counts.begin(), counts.end());
  const auto covered_percentile = [&](double q) -> uint32_t {
    if (covered == 0) return 0;
    const uint64_t first = counts.size() - covered;
    return counts[first + std::min<uint64_t>(covered - 1, uint64_t(q * double(covered)))];
  };
  return {{"max", counts.empty() ? 0u : counts.back()},
          {"mean", counts.empty() ? 0.0 : double(total) / double(counts.size())},
          {"mean_covered", covered ? double(total) / double(covered) : 0.0},
          {"covered_pixels", covered},
          {"fragments", total},
          {"covered_percentiles",
           {{"p50", covered_percentile(0.5)},
            {"p90", covered_percentile(0.9)},
            {"p99", covered_percentile(0.99)}}}};
}

}  // namespace

Command add_depth_complexity(CLI::App& app) {
  auto* sub = app.add_subcommand(
      "depth-complexity", "Depth-complexity images and statistics of a flight (fragments/pixel)");
  struct Args {
    std::string memory_budget;
    std::string cache, output, stats, tf = "semi", flight = "orbit-zoom", frames, size = "1280x720",
                                      on = "gpu", device;
    int frame = 0, frame_count = 64;
    bool validation = false, json = false;
  };
  auto args = std::make_shared<Args>();
  sub->add_option("cache", args->cache, "Asset cache (.lbc.h5) with tubes")->required();
  sub->add_option("-o,--output", args->output, "16-bit grey PNG of the counts");
  sub->add_option("--stats", args->stats, "Statistics as JSON (per frame)");
  sub->add_option("--on", args->on,
                  "gpu: count with one Vulkan draw (default) | cpu: the exact reference tracer")
      ->check(one_of({"gpu", "cpu"}));
  sub->add_option(
      "--tf", args->tf,
      "Transfer function (default semi; recorded: every front fragment counts, whatever its "
      "opacity)");
  sub->add_option("--flight", args->flight, "orbit-zoom (default) | orbit | KEYFRAMES.json");
  sub->add_option("--frame-count", args->frame_count, "Frames in the flight (default 64)")
      ->check(CLI::Range(1, 100000));
  auto* frame = sub->add_option("--frame", args->frame, "Frame, 0 .. frame count - 1 (default 0)")
                    ->check(CLI::Range(0, 99999));
  auto* frames = sub->add_option("--frames", args->frames, "all: every frame (outputs get _NNN)")
                     ->check(one_of({"all"}));
  frame->excludes(frames);
  sub->add_option("--size", args->size, "Image size WxH (default 1280x720)")
      ->check(image_size_check());
  sub->add_option("--memory-budget", args->memory_budget,
                  "Refuse a frame whose estimated memory exceeds this (default: half of "
                  "physical memory, or of the cgroup's or ulimit -v's limit when less)")
      ->check(memory_budget_size());
  sub->add_option("--device", args->device, "Vulkan device: part of its name");
  sub->add_flag("--validation", args->validation, "Vulkan: enable the Khronos validation layer");
  sub->add_flag("--json", args->json, "Print the statistics as JSON on stdout");
  check_when_parsed(sub, [sub, args] {
    refuse_unless(sub, {"device", "validation"}, args->on == "gpu", "with --on gpu");
    if (args->frames.empty() && args->frame >= args->frame_count)
      throw UsageError("--frame " + std::to_string(args->frame) + ": the flight has " +
                       std::to_string(args->frame_count) + " frames, 0 to " +
                       std::to_string(args->frame_count - 1) + " (--frame-count)");
  });
  const auto body = [args] {
    check_cache_input(args->cache);
    const auto [width, height] = parse_image_size(args->size);
    check_depth_image_output(args->output);
    check_output_location(args->stats);
    check_frame_outputs({args->output}, {args->stats},
                        planned_frames(args->frame_count, args->frame, args->frames),
                        {args->cache, args->tf, args->flight});
    const uint64_t frame_bytes = uint64_t(width) * uint64_t(height) * (16 + 16 + 4 + 16);
    check_frame_memory("depth-complexity", args->size, frame_bytes, args->memory_budget);
    // The mesh, the device's copy of it (--on gpu) or Embree's BVH (--on cpu) are held within
    // the budget as render's techniques hold them.
    TechniqueOptions budget;
    set_memory_budget(budget, args->memory_budget);
    const TransferFunction tf = resolve_transfer_function(args->tf);
    const CacheReader cache(args->cache);
    if (!cache.exists("/assets/tubes"))
      throw InputError(args->cache, "group /assets/tubes",
                       "missing: depth complexity counts the tube mesh; add it with: linebake "
                       "bake " +
                           args->cache + " --assets tubes");
    if (const auto provenance = cache.provenance("/assets/tubes"))
      if (auto why = data_does_not_fit(budget, provenance->memory_bytes, "tube mesh's buffers"))
        throw BudgetExceeded("depth-complexity: " + *why + "; raise --memory-budget");
    const TubeMesh tubes = load_tubes(cache);
    // What the budget leaves with the mesh loaded, less the frames' (0: no limit).
    uint64_t left = 0;
    if (!budget.memory_unlimited) {
      trimmed_rss_bytes();
      const MemoryBudget held(process_budget(budget));
      if (held.available() <= frame_bytes)
        throw BudgetExceeded(
            "depth-complexity: the tube mesh leaves nothing of the memory budget "
            "of " +
            format_bytes(held.total()) + " for the " + (args->on == "gpu" ? "device" : "BVH") +
            "; raise --memory-budget");
      left = held.available() - frame_bytes;
    }
    const FlightPlan plan = plan_flight(args->flight, args->frame_count, args->frame, args->frames,
                                        flight_bounds(cache), width, height);
    const bool numbered = plan.frames.size() > 1;
    std::optional<vk::Context> context;
    std::optional<vk::RasterRenderer> renderer;
    std::optional<EmbreeScene> scene;
    nlohmann::json stats = {{"on", args->on},
                            {"transfer_function", tf.name},
                            {"size", {width, height}},
                            {"frames", nlohmann::json::array()}};
    if (args->on == "gpu") {
      vk::ContextOptions options;
      options.device = args->device;
      options.validation = args->validation;
      context.emplace(options);
      if (left > 0)
        context->set_host_budget(process_budget(budget), frame_bytes,
                                 context->first_draw_compile_bytes());
      renderer.emplace(*context, tubes);
      stats["device"] = context->info().name;
    } else {
      EmbreeOptions embree;
      embree.max_memory_bytes = left;
      scene.emplace(EmbreeScene::from_tubes(tubes, embree));
    }
    TerminalProgress progress("depth-complexity");
    std::vector<std::string> lines;
    for (size_t i = 0; i < plan.frames.size(); ++i) {
      throw_if_interrupted();  // between frames: finished frames are kept
      const Camera& camera = plan.cameras[size_t(plan.frames[i])];
      std::vector<uint32_t> counts;
      double seconds = 0;
      if (renderer) {
        const vk::RasterFrame f = renderer->count_fragments(camera, tf, width, height);
        context->drop_compile_reserve();  // the first draw compiled
        if (context->validation_errors() > 0)
          throw Error("Vulkan validation: " + std::to_string(context->validation_errors()) +
                      " error(s); last: " + context->last_validation_error());
        counts = f.depth_complexity;
        seconds = f.stats.seconds;
      } else {
        TraceOptions trace;
        trace.width = width, trace.height = height;
        const Frame f = trace_frame(*scene, camera, tf, trace);
        counts = f.depth_complexity;
        seconds = f.stats.seconds;
      }
      throw_if_interrupted();  // during the frame: it is not written, the finished ones are kept
      if (!args->output.empty())
        write_png_counts(counts, width, height, frame_path(args->output, plan.frames[i], numbered));
      nlohmann::json entry = summarise(counts);
      entry["frame"] = plan.frames[i];
      entry["seconds"] = seconds;
      stats["frames"].push_back(entry);
      progress.update(i + 1, plan.frames.size());
      char line[160];
      std::snprintf(line, sizeof line,
                    "frame %d: depth complexity max %u, mean %.3g over %llu covered pixels "
                    "(p50 %u, p90 %u, p99 %u)",
                    plan.frames[i], entry["max"].get<uint32_t>(),
                    entry["mean_covered"].get<double>(),
                    static_cast<unsigned long long>(entry["covered_pixels"].get<uint64_t>()),
                    entry["covered_percentiles"]["p50"].get<uint32_t>(),
                    entry["covered_percentiles"]["p90"].get<uint32_t>(),
                    entry["covered_percentiles"]["p99"].get<uint32_t>());
      lines.push_back(line);
      // As it goes when the lines are a log beside files; otherwise they are the result, below.
      const bool to_stdout = args->json || (args->output.empty() && args->stats.empty());
      if (!TerminalProgress::enabled() && !to_stdout) std::cerr << line << "\n";
    }
    progress.finish();
    if (!args->stats.empty()) write_file_atomically(args->stats, json_text(stats, 2) + "\n");
    // The statistics are the command's result: on stdout when no file takes them, and left on
    // the terminal after the bar.
    if (args->json)
      std::cout << json_text(stats, 2) << "\n";
    else if (args->output.empty() && args->stats.empty())
      for (const std::string& l : lines) std::cout << l << "\n";
    else if (TerminalProgress::enabled())
      for (const std::string& l : lines) std::cerr << l << "\n";
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
