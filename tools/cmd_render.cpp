// linebake render <cache>: renders frames of a flight with the CPU ray tracer (technique
// `embree`, curves) or the ground truth (technique `reference`, the triangle tube mesh).

#include <cmath>
#include <iostream>
#include <nlohmann/json.hpp>
#include <regex>

#include "accel/embree_scene.hpp"
#include "cache/cache.hpp"
#include "cache/embree_store.hpp"
#include "cache/line_store.hpp"
#include "cache/tube_store.hpp"
#include "commands.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/progress.hpp"
#include "render/ray_tracer.hpp"
#include "render/vulkan/raster_renderer.hpp"
#include "tubes/tube_builder.hpp"

namespace linebake::cli {
namespace {

std::array<int, 2> parse_size(const std::string& text) {
  static const std::regex pattern(R"((\d{1,5})x(\d{1,5}))");
  std::smatch m;
  if (!std::regex_match(text, m, pattern)) throw Error("--size: expected WxH, got '" + text + "'");
  const int w = std::stoi(m[1]), h = std::stoi(m[2]);
  if (w < 1 || h < 1 || w > 16384 || h > 16384) throw Error("--size: 1..16384 per axis");
  return {w, h};
}

// "out.png" -> "out_007.png" for frame 7 of a multi-frame render.
std::string frame_path(const std::string& path, int frame, bool numbered) {
  if (!numbered) return path;
  const auto dot = path.find_last_of('.');
  const auto slash = path.find_last_of('/');
  char number[16];
  std::snprintf(number, sizeof number, "_%03d", frame);
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return path + number;
  return path.substr(0, dot) + number + path.substr(dot);
}

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

// The flight's cameras and the frames to render (--frame F or --frames all).
struct FlightPlan {
  FlightKind kind = FlightKind::OrbitZoom;
  std::vector<Camera> cameras;
  std::vector<int> frames;
};

template <class Args>
FlightPlan plan_flight(const Args& args, const Bounds& bounds, int width, int height) {
  FlightOptions flight;
  flight.kind = parse_flight_kind(args.flight);
  if (flight.kind == FlightKind::Keyframes) flight.keyframes_file = args.flight;
  flight.frames = args.frame_count;
  FlightPlan plan;
  plan.kind = flight.kind;
  plan.cameras = make_flight(bounds, double(width) / height, flight);
  if (args.frames == "all")
    for (int i = 0; i < args.frame_count; ++i) plan.frames.push_back(i);
  else
    plan.frames.push_back(args.frame);
  return plan;
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
  const FlightPlan plan = plan_flight(args, compute_bounds(tubes), width, height);
  const std::vector<Camera>& cameras = plan.cameras;
  const std::vector<int>& frames = plan.frames;
  const bool numbered = frames.size() > 1;
  nlohmann::json stats = {{"technique", args.technique},      {"device", context.info().name},
                          {"driver", context.info().driver},  {"transfer_function", tf.name},
                          {"flight", to_string(plan.kind)},   {"mesh_bytes", renderer.mesh_bytes()},
                          {"frames", nlohmann::json::array()}};
  if (o.technique == vk::RasterTechnique::LinkedLists) stats["sort"] = vk::to_string(o.sort);
  TerminalProgress progress("render");
  for (size_t i = 0; i < frames.size(); ++i) {
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
    progress.update(i + 1, frames.size());
    if (!TerminalProgress::enabled())
      std::cerr << "frame " << frames[i] << ": " << frame.stats.seconds << " s on "
                << context.info().name << "\n";
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
    std::string sort = "heap", device;
    uint64_t capacity = 0;
    bool validation = false;
    int frame = 0, frame_count = 64, png_bits = 8;
    float radius = 0;
    bool early = false, packets = false;
  };
  auto args = std::make_shared<Args>();
  sub->add_option("cache", args->cache, "Asset cache (.lbc.h5)")
      ->required()
      ->check(CLI::ExistingFile);
  sub->add_option("--technique", args->technique,
                  "embree (CPU ray tracing of curves) | reference (exact, the tube mesh) | "
                  "opaque | ll (Vulkan rasterisation of the tube mesh)")
      ->check(CLI::IsMember({"embree", "reference", "opaque", "ll"}));
  sub->add_option("--sort", args->sort, "ll: per-pixel sort insertion | shell | heap (default)")
      ->check(CLI::IsMember({"insertion", "shell", "heap"}));
  sub->add_option("--capacity", args->capacity,
                  "ll: fragment nodes to start with (default 20 x pixels; grows on overflow)");
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
                  "How hits are found: filter (one traversal, default) | stepping (closest-hit "
                  "queries from just past the last hit)")
      ->check(CLI::IsMember({"filter", "stepping"}));
  sub->add_flag("--packets", args->packets,
                "Trace 4x2 ray packets (rtcIntersect8) instead of single rays (filter hits)");
  sub->add_flag("--early-termination", args->early,
                "Stop compositing at opacity 0.99 (never for ground truth)");
  return [args] {
    const auto [width, height] = parse_size(args->size);
    const bool reference = args->technique == "reference";
    if ((reference || args->technique == "opaque") && args->early)
      throw Error("--early-termination: the reference never stops early");
    if (args->frame >= args->frame_count && args->frames.empty())
      throw Error("--frame " + std::to_string(args->frame) + " is past the flight's " +
                  std::to_string(args->frame_count) + " frames");
    const TransferFunction tf = resolve_transfer_function(args->tf);
    const CacheReader cache(args->cache);
    if (args->technique == "opaque" || args->technique == "ll") {
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
      std::string attribute = args->attribute;
      if (attribute.empty())
        attribute = tube_provenance ? tube_provenance->stats.value("attribute", "")
                                    : (lines.attributes.empty() ? "" : lines.attributes[0].name);
      float radius = args->radius;
      if (!(radius > 0)) {
        if (tube_provenance && tube_provenance->stats.contains("radius_world")) {
          radius = tube_provenance->stats["radius_world"].get<float>();
        } else {
          const Bounds b = compute_bounds(lines);
          const float dx = b.max[0] - b.min[0], dy = b.max[1] - b.min[1], dz = b.max[2] - b.min[2];
          radius = TubeOptions{}.radius * std::sqrt(dx * dx + dy * dy + dz * dz);
        }
      }
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
    const FlightPlan plan = plan_flight(*args, scene->bounds(), width, height);
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
}

}  // namespace linebake::cli
