#pragma once
// The rendering techniques of the paper as one table that every command iterates (`render`,
// `view`, `bench render`, the pipeline planner), in the spirit of bgfx's renderer table: a
// technique says which cached assets it reads and what it needs of the machine, prepares its
// scene from a cache once, then renders cameras into frames with their statistics. The drivers
// themselves live in lib/render (CPU) and lib/render/vulkan (GPU); a family file here adapts
// them (cpu_tracing.cpp, raster.cpp, vrc.cpp, rtx.cpp). A new technique is its driver, its
// shaders and one line in registry.cpp.

#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "cache/cache.hpp"
#include "lines/line_set.hpp"
#include "render/camera.hpp"
#include "render/image.hpp"
#include "render/transfer_function.hpp"

namespace linebake {

namespace vk {
class Context;
}

struct TechniqueInfo {
  std::string name;                 // as on the command line
  std::string summary;              // one line
  std::vector<std::string> assets;  // cache groups it reads: "lines", "tubes", "voxels"
  bool vulkan = false;              // needs a Vulkan device (vrc: only with on = "gpu")
  bool ray_tracing = false;         // needs VK_KHR_ray_tracing_pipeline
  bool exact = false;               // every hit composited in order (the ground truth's class)
  // The render options it reads besides the flight's and the outputs' (kCommonRenderOptions),
  // as long option names without "--".
  std::vector<std::string> options = {};
};

// Render options every technique reads: the transfer function, the flight, the frames, the
// image and its outputs, the memory budget.
extern const std::vector<std::string> kCommonRenderOptions;
// Of the options given (long names without "--"), those the technique does not read; a
// UsageError listing them and what the technique does read unless `given` is clean.
void check_technique_options(const TechniqueInfo& info, const std::vector<std::string>& given);

// Every knob of every technique, with the command line's defaults; a technique reads its own.
struct TechniqueOptions {
  int width = 1280, height = 720;  // what the flight frames (each frame gives its own size)
  bool early_termination = false;  // embree, ll, rtx (vrc: see vrc_early_termination)
  // Vulkan: the device (part of its name; empty: a discrete GPU, else the first), the Khronos
  // validation layer, or a context to share (the viewer's window); validation errors fail a frame.
  std::string device;
  bool validation = false;
  vk::Context* context = nullptr;
  // embree, reference (CPU ray tracing) and rtx
  std::string hits = "filter";  // filter | stepping
  std::string geometry = "linear", quality = "medium";
  bool packets = false;
  // embree and reference: collect every hit, for the depth complexity (render --stats,
  // --depth-complexity); off, a ray stops where its pixel is opaque (render/ray_tracer.hpp).
  bool every_hit = false;
  float radius = 0;       // curves: world units (0: the cached tubes', else 0.001 x diagonal)
  std::string attribute;  // curves: vertex attribute (empty: the tubes', else the first)
  // raster techniques (opaque, dp, ll, mlab, mlabdb, mboit, wboit)
  std::string sort = "heap";
  uint64_t capacity = 0;
  uint32_t node_bytes = 24;  // ll: 24 (float colour) or 12 (RGBA8 colour)
  int max_layers = 2000, layers = 0, wboit_weight = 0, moments = 4;
  double tau_alpha = 0.2, tau_opaque = 0.98, beta = 0.1, moment_bias = -1;
  std::string moment_basis = "power";
  bool interlock = true;
  // vrc
  std::string on = "cpu";  // cpu | gpu
  bool vrc_early_termination = true, skip_empty_space = true;
  // rtx
  std::string rt_geometry;  // triangles | capsules (empty: what the cached BLAS were built over)
  bool rebuild = false, compaction = true;
  int max_iterations = 1024;
  // tiles
  std::string tiles_geometry = "capsules";  // capsules (the lines) | triangles (the tube mesh)
  // The key sort's path: auto (subgroups where the device has them) | subgroups | shared.
  std::string tiles_sort = "auto";
  // The composite takes the crowded tiles first (false: every tile in raster order; bench
  // render's tiles-raster-order, no command-line option).
  bool tiles_most_keys_first = true;
  // The tiles whose composite takes four workgroups, a strip of 16x4 pixels each: none |
  // crowded | all (vk::TileStrips; render --tiles-strips, bench render's tiles-crowded-strips
  // and tiles-strips).
  std::string tiles_strips = "none";
  // Each pixel computes its own hits instead of the composite's rounds of pairs
  // (vk::TileOptions::pixel_hits; bench render's tiles-pixel-hits and
  // tiles-triangles-pixel-hits, no command-line option).
  bool tiles_pixel_hits = false;
  // The composite shades each hit when it composites it, its window holding no colours
  // (vk::TileOptions::late_shading; bench render's tiles-late-shading,
  // tiles-triangles-late-shading and tiles-pixel-hits-late-shading, no command-line option).
  bool tiles_late_shading = false;
  // The process's memory budget in bytes (render --memory-budget; 0: none given, half of
  // physical memory). Data is read only where the cache's provenance says it fits; embree and
  // reference build their BVH within what it leaves of the process's resident memory; the
  // Vulkan techniques' allocations in the machine's memory are held within it
  // (vk::Context::set_host_budget); tiles renders in bands of tile rows to fit what it leaves
  // (where the device has memory of its own: these bytes, when given). memory_unlimited
  // (--memory-budget unlimited): no limit at all.
  uint64_t memory_budget = 0;
  bool memory_unlimited = false;
};

struct TechniqueFrame {
  Image image;  // linear RGB, background included
  std::vector<uint32_t> depth_complexity;
  double seconds = 0;                    // wall, readback included
  std::map<std::string, double> gpu_ms;  // per pass, GPU timestamps (empty on the CPU)
  uint64_t frame_bytes = 0;              // the technique's per-frame buffers
  nlohmann::json stats;                  // the technique's own per-frame `--stats` fields
  std::vector<std::string> warnings;     // for stderr ("needs 31 layers; dp peeled 20")
  std::string note;                      // for the per-frame progress line
  double total_gpu_ms() const;
};

class PreparedTechnique {
 public:
  virtual ~PreparedTechnique() = default;
  // One frame of `width` x `height` (the viewer's window may change it between frames).
  virtual TechniqueFrame render(const Camera& camera, const TransferFunction& tf, int width,
                                int height) = 0;
  // The technique's own `--stats` header fields (device, BVH or grid figures, options in force).
  virtual nlohmann::json stats() const = 0;
  // The Vulkan device's name, "" on the CPU.
  virtual std::string device() const { return ""; }
  // What preparing decided that a user should hear of (rtx: "cached BLAS not used (...)").
  std::vector<std::string> warnings;
};

struct Technique {
  TechniqueInfo info;
  // Loads what it needs from the cache (`cache_name` names it in errors) and builds its scene.
  std::unique_ptr<PreparedTechnique> (*prepare)(const TechniqueInfo& info, const CacheReader& cache,
                                                const std::string& cache_name,
                                                const TechniqueOptions& options) = nullptr;
  // The technique's own per-frame buffers at options.width x options.height, estimated before
  // any work (ll: where its node pool starts).
  uint64_t (*frame_bytes)(const TechniqueInfo& info, const TechniqueOptions& options) = nullptr;
};

// The memory one frame takes, estimated before it is spent: the image as floats, its output,
// depth-complexity counts, and the technique's own buffers (on lavapipe and integrated GPUs
// device memory is host memory too). Errs high.
uint64_t estimate_frame_bytes(const Technique& technique, const TechniqueOptions& options);
// The image, output and depth-complexity part of that, which every technique's frame holds.
uint64_t frame_output_bytes(const TechniqueOptions& options);
// --memory-budget's text into `options`: "" (none given), "unlimited", or a size ("8G").
void set_memory_budget(TechniqueOptions& options, const std::string& budget);

// Every technique, in the order the commands list them.
const std::vector<Technique>& techniques();
std::vector<std::string> technique_names();
// Throws Error naming the techniques when `name` is none of them.
const Technique& find_technique(const std::string& name);
// Why this machine cannot run the technique with these options (no Vulkan device, no device with
// ray tracing, a missing asset in `cache` when one is given), or nullopt.
std::optional<std::string> technique_unavailable(const Technique& technique,
                                                 const TechniqueOptions& options,
                                                 const CacheReader* cache = nullptr);

}  // namespace linebake
