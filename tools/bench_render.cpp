// linebake bench render CACHE...: every technique of the registry (or those asked for) on every
// cache and transfer function over an N-frame flight: GPU time per pass and in total (median and
// max over the frames), wall time per frame, per-frame memory, the device, and PSNR/SSIM of
// frame 0 against the reference, rendered once per camera. A Markdown table, or JSON.

#include "bench_render.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "cli_contract.hpp"
#include "core/error.hpp"
#include "core/interrupt.hpp"
#include "core/json_file.hpp"
#include "core/measure.hpp"
#include "core/nearest.hpp"
#include "flight_plan.hpp"
#include "metrics/image_metrics.hpp"
#include "render/image.hpp"
#include "render/vulkan/context.hpp"
#include "source_revision.hpp"
#include "techniques/framing.hpp"
#include "techniques/technique.hpp"

namespace linebake::cli {
namespace {

double maximum(const std::vector<double>& v) {
  return v.empty() ? 0 : *std::max_element(v.begin(), v.end());
}

nlohmann::json spread(const std::vector<double>& v) {
  return {{"median", median(v)}, {"max", maximum(v)}};
}

std::string camera_key(const Camera& c) {
  char text[256];
  std::snprintf(text, sizeof text, "%.9g %.9g %.9g %.9g %.9g %.9g %.9g", c.eye.x, c.eye.y, c.eye.z,
                c.target.x, c.target.y, c.target.z, c.fov_y_degrees);
  return text;
}

// The reference's frame 0 per camera (every technique frames the cache's flight_bounds, so one
// camera a cache; kept per camera all the same), rendered when first asked for. Asked for once a
// cache's techniques have all run and let go of their scenes (FirstFrame): the reference's BVH and
// a technique's scene are never held at once, and the reference's frames are prepared once per
// cache (a `reference` row prepares its own scene for its timings).
class ReferenceFrames {
 public:
  ReferenceFrames(const CacheReader& cache, const std::string& name, const TechniqueOptions& o)
      : cache_(cache), name_(name), options_(o) {}
  // The reference's image, or nullptr with why_not() set when it cannot be rendered (a cache
  // without tubes): the technique's row then has no quality figures, its timings stay.
  const Image* at(const Camera& camera, const TransferFunction& tf, int width, int height) {
    if (!why_not_.empty()) return nullptr;
    const std::string key = camera_key(camera) + " " + tf.name;
    auto found = images_.find(key);
    if (found != images_.end()) return &found->second;
    try {
      if (!prepared_) {
        const Technique& reference = find_technique("reference");
        prepared_ = reference.prepare(reference.info, cache_, name_, options_);
      }
      Image image = display_encoded(prepared_->render(camera, tf, width, height).image);
      return &images_.emplace(key, std::move(image)).first->second;
    } catch (const Interrupted&) {
      throw;
    } catch (const std::exception& e) {
      why_not_ = e.what();
      return nullptr;
    }
  }
  const std::string& why_not() const { return why_not_; }

 private:
  const CacheReader& cache_;
  std::string name_;
  TechniqueOptions options_;
  std::unique_ptr<PreparedTechnique> prepared_;
  std::map<std::string, Image> images_;
  std::string why_not_;
};

std::string fixed(double v, int digits);

// A technique's frame 0, kept (display-encoded) for its quality against the reference.
struct FirstFrame {
  Camera camera;
  Image image;
};

// One technique on one cache with one transfer function; its frame 0 into `first` (none for
// the reference itself). `kept`: the bytes of the earlier rows' frames 0, which count against
// the memory budget with the frame's estimate.
nlohmann::json bench_one(const BenchRenderArgs& args, const Technique& technique,
                         const CacheReader& cache, const std::string& cache_name,
                         const TransferFunction& tf, const TechniqueOptions& options, uint64_t kept,
                         std::optional<FirstFrame>& first) {
  nlohmann::json row = {{"technique", technique.info.name}, {"transfer_function", tf.name}};
  if (auto reason = technique_unavailable(technique, options, &cache)) {
    row["skipped"] = *reason;
    return row;
  }
  try {
    check_frame_memory(technique.info.name, args.size, estimate_frame_bytes(technique, options),
                       args.memory_budget, kept);
    const auto start = std::chrono::steady_clock::now();
    std::unique_ptr<PreparedTechnique> prepared =
        technique.prepare(technique.info, cache, cache_name, options);
    row["prepare_s"] = seconds_since(start);
    row["device"] = prepared->device().empty() ? "CPU" : prepared->device();
    const nlohmann::json header = prepared->stats();
    if (header.contains("mesh_bytes")) row["mesh_bytes"] = header["mesh_bytes"];
    const FlightPlan plan = plan_flight("orbit-zoom", args.frames, 0, "all", flight_bounds(cache),
                                        options.width, options.height);
    std::vector<double> gpu, wall;
    std::map<std::string, std::vector<double>> passes;
    uint64_t frame_bytes = 0;
    nlohmann::json layers = nlohmann::json::array();
    bool capped = false;
    // tiles: per frame, what its GPU time follows (keys, the fullest tile, the crowded tiles,
    // walks), and its composite's first walk apart from the walks again.
    nlohmann::json tiles_frames = nlohmann::json::array();
    std::vector<double> first_walk_ms, walks_again_ms;
    // Frames before the flight, not counted: the first frame of a technique pays for what it
    // makes when first used (lavapipe compiles a pipeline at its first dispatch, tiles allocates
    // its pixels' states when a frame first needs them) and, on a GPU that has idled, for its
    // clocks (docs/cli.md, "bench render").
    if (args.warm_up > 0) {
      const auto warm_start = std::chrono::steady_clock::now();
      for (int w = 0; w < args.warm_up; ++w) {
        throw_if_interrupted();
        prepared->render(plan.cameras[size_t(plan.frames.front())], tf, options.width,
                         options.height);
      }
      row["warm_up_s"] = seconds_since(warm_start);
    }
    double frames_s = 0;  // the technique's own frames, not the reference's
    for (int f : plan.frames) {
      throw_if_interrupted();
      const Camera& camera = plan.cameras[size_t(f)];
      const TechniqueFrame frame = prepared->render(camera, tf, options.width, options.height);
      wall.push_back(frame.seconds);
      frames_s += frame.seconds;
      if (!frame.gpu_ms.empty()) gpu.push_back(frame.total_gpu_ms());
      for (const auto& [pass, ms] : frame.gpu_ms) passes[pass].push_back(ms);
      frame_bytes = std::max(frame_bytes, frame.frame_bytes);
      if (frame.stats.contains("critical_section"))
        row["critical_section"] = frame.stats["critical_section"];
      // The CPU tracers' path (every hit, or the interval walk) and its traversal counts.
      for (const char* count : {"traversals", "rays_stopped_opaque", "front_hits"})
        if (frame.stats.contains(count))
          row[count] = row.value(count, uint64_t{0}) + frame.stats[count].get<uint64_t>();
      if (frame.stats.contains("every_hit")) row["every_hit"] = frame.stats["every_hit"];
      if (frame.stats.contains("walk_ms") && frame.stats.contains("keys")) {
        tiles_frames.push_back({{"keys", frame.stats["keys"]},
                                {"max_tile_keys", frame.stats["max_tile_keys"]},
                                {"crowded_tiles", frame.stats["crowded_tiles"]},
                                {"walks", frame.stats["walks"]},
                                {"workgroups", frame.stats["composite_workgroups"]}});
        if (frame.stats.contains("late_misses"))
          tiles_frames.back()["late_misses"] = frame.stats["late_misses"];
        const std::vector<double> walks = frame.stats["walk_ms"].get<std::vector<double>>();
        double again = 0;
        for (size_t w = 1; w < walks.size(); ++w) again += walks[w];
        first_walk_ms.push_back(walks.empty() ? 0.0 : walks[0]);
        walks_again_ms.push_back(again);
      }
      if (technique.info.name == "dp" && frame.stats.contains("layers")) {
        layers.push_back(frame.stats["layers"]);
        capped = capped || frame.stats.value("layers_capped", false);
      }
      if (f == 0 && technique.info.name != "reference")
        first = FirstFrame{camera, display_encoded(frame.image)};
      // (0 had meant no limit, and the note had rounded 0.04 to "0.0".)
      if (frames_s > args.max_seconds && f + 1 < args.frames) {
        char limit[32];
        std::snprintf(limit, sizeof limit, "%.6g", args.max_seconds);
        row["stopped"] = "after " + std::to_string(f + 1) + " of " + std::to_string(args.frames) +
                         " frames (--max-seconds " + limit + ")";
        break;
      }
    }
    row["frames"] = wall.size();
    row["wall_s"] = spread(wall);
    if (!gpu.empty()) {
      row["gpu_ms"] = spread(gpu);
      nlohmann::json p = nlohmann::json::object();
      for (const auto& [pass, ms] : passes) p[pass] = spread(ms);
      row["passes"] = p;
    }
    row["frame_bytes"] = frame_bytes;
    if (!tiles_frames.empty())
      row["tiles"] = {{"frames", tiles_frames},
                      {"first_walk_ms", spread(first_walk_ms)},
                      {"walks_again_ms", spread(walks_again_ms)}};
    if (!layers.empty()) {
      row["dp_layers"] = layers;
      row["dp_layers_capped"] = capped;
    }
  } catch (const Interrupted&) {
    throw;
  } catch (const std::exception& e) {
    // A failed row has no figures, frame 0's quality included (it may have rendered).
    row["failed"] = e.what();
    first.reset();
  }
  return row;
}

// Bench names beside the registry's: a technique with one option set. vrc-gpu is vrc on Vulkan
// compute, tiles-shared and tiles-subgroups are tiles with its key sort's shared-memory and
// subgroup path (tiles takes subgroups where the device has them, except on lavapipe: the two
// paths' A/B), tiles-triangles is tiles over the tube mesh (comparable with the reference to the
// last bit of coverage), tiles-raster-order is tiles dispatching every tile in raster order
// instead of the crowded ones first (the A/B of that order), tiles-strips is tiles with four
// workgroups a tile, each over a strip of 16x4 pixels, and tiles-crowded-strips with four for
// the crowded tiles and the small walks again (the A/B of workgroups of 64 against 256);
// tiles-pixel-hits and tiles-triangles-pixel-hits have each pixel compute its own hits instead of
// the composite's rounds of pairs (the A/B of the rounds on a GPU); tiles-late-shading,
// tiles-triangles-late-shading and tiles-pixel-hits-late-shading shade each hit when it is
// composited, the window holding no colours (the A/B of the window's registers on a GPU).
struct BenchVariant {
  const char* name;
  const char* technique;
  void (*apply)(TechniqueOptions&);
};
constexpr BenchVariant kBenchVariants[] = {
    {"vrc-gpu", "vrc", [](TechniqueOptions& o) { o.on = "gpu"; }},
    {"tiles-shared", "tiles", [](TechniqueOptions& o) { o.tiles_sort = "shared"; }},
    {"tiles-subgroups", "tiles", [](TechniqueOptions& o) { o.tiles_sort = "subgroups"; }},
    {"tiles-triangles", "tiles", [](TechniqueOptions& o) { o.tiles_geometry = "triangles"; }},
    {"tiles-raster-order", "tiles", [](TechniqueOptions& o) { o.tiles_most_keys_first = false; }},
    {"tiles-crowded-strips", "tiles", [](TechniqueOptions& o) { o.tiles_strips = "crowded"; }},
    {"tiles-strips", "tiles", [](TechniqueOptions& o) { o.tiles_strips = "all"; }},
    {"tiles-pixel-hits", "tiles", [](TechniqueOptions& o) { o.tiles_pixel_hits = true; }},
    {"tiles-triangles-pixel-hits", "tiles",
     [](TechniqueOptions& o) {
       o.tiles_geometry = "triangles";
       o.tiles_pixel_hits = true;
     }},
    {"tiles-late-shading", "tiles", [](TechniqueOptions& o) { o.tiles_late_shading = true; }},
    {"tiles-triangles-late-shading", "tiles",
     [](TechniqueOptions& o) {
       o.tiles_geometry = "triangles";
       o.tiles_late_shading = true;
     }},
    {"tiles-pixel-hits-late-shading", "tiles",
     [](TechniqueOptions& o) {
       o.tiles_pixel_hits = true;
       o.tiles_late_shading = true;
     }},
};

const BenchVariant* variant_of(const std::string& name) {
  for (const BenchVariant& v : kBenchVariants)
    if (name == v.name) return &v;
  return nullptr;
}

// The registry's technique behind a bench name.
std::string technique_of(const std::string& name) {
  const BenchVariant* v = variant_of(name);
  return v ? v->technique : name;
}

std::string fixed(double v, int digits) {
  char text[64];
  std::snprintf(text, sizeof text, "%.*f", digits, v);
  return text;
}

std::string with_commas(uint64_t v) {
  std::string digits = std::to_string(v), out;
  for (size_t i = 0; i < digits.size(); ++i) {
    if (i && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return out;
}

void print_markdown(const nlohmann::json& result) {
  std::cout << "| cache (segments) | tf | technique | device | frames | GPU ms median | GPU ms max "
               "| wall ms median | frame MiB | PSNR dB | SSIM | passes, median ms | notes |\n"
               "|---|---|---|---|---:|---:|---:|---:|---:|---:|---:|---|---|\n";
  for (const auto& run : result["runs"]) {
    const std::string set = run["cache"].get<std::string>() + " (" +
                            with_commas(run.value("segments", uint64_t{0})) + ")";
    for (const auto& r : run["rows"]) {
      std::cout << "| " << set << " | " << r["transfer_function"].get<std::string>() << " | "
                << r["technique"].get<std::string>() << " | ";
      if (r.contains("skipped") || r.contains("failed")) {
        std::cout << r.value("device", "") << " | | | | | | | | | "
                  << (r.contains("skipped") ? "skipped: " + r["skipped"].get<std::string>()
                                            : "failed: " + r["failed"].get<std::string>())
                  << " |\n";
        continue;
      }
      std::string passes, notes;
      if (r.contains("passes"))
        for (const auto& [pass, s] : r["passes"].items())
          passes += (passes.empty() ? "" : ", ") + pass + " " + fixed(s["median"], 1);
      if (r.contains("critical_section")) notes += r["critical_section"].get<std::string>();
      if (r.contains("dp_layers")) {
        std::vector<double> l;
        for (const auto& v : r["dp_layers"]) l.push_back(v.get<double>());
        notes += "layers " + fixed(median(l), 0) + " median, " + fixed(maximum(l), 0) + " max" +
                 (r["dp_layers_capped"].get<bool>() ? " (capped by --max-layers)" : "");
      }
      if (r.contains("stopped"))
        notes += (notes.empty() ? "" : "; ") + r["stopped"].get<std::string>();
      // An empty PSNR says why.
      if (r.contains("quality_skipped"))
        notes += (notes.empty() ? "" : "; ") + r["quality_skipped"].get<std::string>();
      const bool gpu = r.contains("gpu_ms");
      std::cout << r["device"].get<std::string>() << " | " << r["frames"].get<int>() << " | "
                << (gpu ? fixed(r["gpu_ms"]["median"], 1) : "") << " | "
                << (gpu ? fixed(r["gpu_ms"]["max"], 1) : "") << " | "
                << fixed(1000 * r["wall_s"]["median"].get<double>(), 1) << " | "
                << fixed(r["frame_bytes"].get<double>() / (1 << 20), 1) << " | "
                << (r.contains("psnr_db") ? fixed(r["psnr_db"], 1) : "") << " | "
                << (r.contains("ssim") ? fixed(r["ssim"], 4) : "") << " | " << passes << " | "
                << notes << " |\n";
    }
  }
}

}  // namespace

void bench_render(const BenchRenderArgs& args) {
  if (args.caches.empty()) throw Error("bench render: name at least one cache");
  // The registry's names, and vrc-gpu for vrc on Vulkan compute (as the viewer names it).
  std::vector<std::string> names = args.techniques;
  if (names.empty())
    for (const std::string& name : technique_names()) {
      names.push_back(name);
      if (name == "vrc") names.push_back("vrc-gpu");
    }
  // Fail first, as a bad command line (exit 1), with the nearest known name.
  std::vector<std::string> known = technique_names();
  for (const BenchVariant& v : kBenchVariants) known.push_back(v.name);
  for (const std::string& name : names)
    if (std::find(known.begin(), known.end(), name) == known.end())
      throw UsageError("--techniques: unknown technique '" + name + "' (" + name_list(known) + ")" +
                       did_you_mean(name, known));
  for (const std::string& path : args.caches)
    if (!std::filesystem::is_regular_file(path)) throw InputError(path, "", "no such cache file");
  std::vector<TransferFunction> tfs;
  for (const std::string& name : args.transfer_functions)
    tfs.push_back(resolve_transfer_function(name));
  const auto [width, height] = parse_image_size(args.size);
  // Checked before any work: the frames are compared with the reference by SSIM at the end.
  if (width < 11 || height < 11)
    throw UsageError("--size '" + args.size +
                     "': bench render compares frame 0 with the reference by SSIM, which needs at "
                     "least 11x11 pixels");
  TechniqueOptions options;
  options.width = width, options.height = height;
  options.device = args.device;
  set_memory_budget(options, args.memory_budget);
  // One Vulkan context for every technique, with ray tracing where the device has it: a context
  // per technique costs an instance each, and NVIDIA's driver refused new instances after about
  // thirty in one process (H100, driver 580).
  std::optional<vk::Context> context;
  const bool vulkan = std::any_of(names.begin(), names.end(), [](const std::string& name) {
    return find_technique(technique_of(name)).info.vulkan || name == "vrc-gpu";
  });
  if (vulkan && !technique_unavailable(find_technique("opaque"), options)) {
    vk::ContextOptions co;
    co.device = args.device;
    co.ray_tracing = !technique_unavailable(find_technique("rtx"), options);
    try {
      context.emplace(co);
    } catch (const vk::RayTracingUnsupported&) {  // the extensions, but a feature is off
      co.ray_tracing = false;
      context.emplace(co);
    }
    options.context = &*context;
  }
  nlohmann::json result = {{"linebake", LINEBAKE_VERSION},
                           {"source_revision", LINEBAKE_SOURCE_REVISION},
                           {"size", {width, height}},
                           {"frames", args.frames},
                           {"warm_up", args.warm_up},
                           {"flight", "orbit-zoom"},
                           {"early_termination", args.early_termination},
                           {"every_hit", args.every_hit},
                           {"runs", nlohmann::json::array()}};
  for (const std::string& path : args.caches) {
    // The techniques' reader; the reference gets its own, once this one and the pages of the
    // cache it mapped are gone.
    std::optional<CacheReader> cache(std::in_place, path);
    nlohmann::json run = {{"cache", std::filesystem::path(path).stem().stem().string()},
                          {"path", path},
                          {"rows", nlohmann::json::array()}};
    if (const auto lines = cache->provenance("/lines"))
      run["segments"] = lines->stats.value("segments", uint64_t{0});
    // Each row's frame 0 (and its transfer function), for the quality figures at the end.
    std::vector<std::tuple<size_t, const TransferFunction*, FirstFrame>> firsts;
    uint64_t kept = 0;  // their images' bytes
    for (const TransferFunction& tf : tfs)
      for (const std::string& name : names) {
        TechniqueOptions o = options;
        if (const BenchVariant* v = variant_of(name)) v->apply(o);
        // The reference stays exact (its frames for quality are rendered with `options`).
        o.early_termination = args.early_termination && name != "reference";
        o.every_hit = args.every_hit;
        std::optional<FirstFrame> first;
        nlohmann::json row =
            bench_one(args, find_technique(technique_of(name)), *cache, path, tf, o, kept, first);
        if (first) {
          kept += first->image.pixels.size() * sizeof(float);
          firsts.emplace_back(run["rows"].size(), &tf, std::move(*first));
        }
        row["technique"] = name;
        std::cerr << "bench render: " << run["cache"].get<std::string>() << " " << tf.name << " "
                  << name << ": "
                  << (row.contains("skipped")  ? "skipped, " + row["skipped"].get<std::string>()
                      : row.contains("failed") ? "failed, " + row["failed"].get<std::string>()
                      : row.contains("gpu_ms")
                          ? "GPU " + fixed(row["gpu_ms"]["median"], 1) + " ms median"
                          : "wall " + fixed(row["wall_s"]["median"], 3) + " s median")
                  << "\n";
        run["rows"].push_back(row);
      }
    // Quality last, every technique's scene let go: frame 0 against the reference's.
    if (!firsts.empty()) {
      std::cerr << "bench render: " << run["cache"].get<std::string>()
                << ": the reference's frames for PSNR and SSIM\n";
      cache.emplace(path);
      ReferenceFrames references(*cache, path, options);
      for (const auto& [index, tf, first] : firsts) {
        nlohmann::json& row = run["rows"][index];
        if (const Image* truth = references.at(first.camera, *tf, width, height)) {
          row["psnr_db"] = psnr(first.image, *truth);
          row["ssim"] = ssim(first.image, *truth);
        } else {
          row["quality_skipped"] = "no reference: " + references.why_not();
        }
      }
      if (!references.why_not().empty())
        std::cerr << "bench render: " << run["cache"].get<std::string>()
                  << ": no PSNR or SSIM, the reference cannot render: " << references.why_not()
                  << "\n";
    }
    result["runs"].push_back(std::move(run));
  }
  if (args.json)
    std::cout << json_text(result, 2) << "\n";
  else
    print_markdown(result);
}

}  // namespace linebake::cli
