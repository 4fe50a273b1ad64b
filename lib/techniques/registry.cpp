// The table of techniques (technique.hpp). Order: the ground truth, CPU ray tracing, the
// rasterisation techniques from opaque to approximate, voxel ray casting, GPU ray tracing.

#include <algorithm>

#include "core/error.hpp"
#include "core/measure.hpp"
#include "core/memory_budget.hpp"
#include "core/nearest.hpp"
#include "render/vulkan/context.hpp"
#include "techniques/families.hpp"

namespace linebake {

namespace {

// Why a device (or a shared context on it) cannot run rtx.
std::string no_ray_tracing(const vk::DeviceInfo& device) {
  if (!device.ray_tracing)
    return "ray tracing is not supported on this device (" + device.name +
           "): it needs VK_KHR_ray_tracing_pipeline and VK_KHR_acceleration_structure";
  return "the shared Vulkan context on " + device.name + " was made without ray tracing";
}

}  // namespace

double TechniqueFrame::total_gpu_ms() const {
  double total = 0;
  for (const auto& [pass, ms] : gpu_ms) total += ms;
  return total;
}

const std::vector<std::string> kCommonRenderOptions = {
    "technique", "tf",    "flight",        "frame-count",      "frame", "frames", "size", "output",
    "png-bits",  "stats", "memory-budget", "depth-complexity", "json",  "warm-up"};

void check_technique_options(const TechniqueInfo& info, const std::vector<std::string>& given) {
  const auto reads = [&](const std::string& name) {
    return std::find(info.options.begin(), info.options.end(), name) != info.options.end() ||
           std::find(kCommonRenderOptions.begin(), kCommonRenderOptions.end(), name) !=
               kCommonRenderOptions.end();
  };
  std::string unread, read;
  for (const std::string& name : given)
    if (!reads(name)) unread += (unread.empty() ? "--" : ", --") + name;
  if (unread.empty()) return;
  for (const std::string& name : info.options) read += (read.empty() ? "--" : ", --") + name;
  throw UsageError(unread + ": not read by " + info.name + " (" + info.name + " reads " +
                   (read.empty() ? std::string("no options of its own") : read) +
                   ", and the flight and output options)");
}

const std::vector<Technique>& techniques() {
  using A = std::vector<std::string>;
  static const std::vector<Technique> table = {
      {{"reference", "exact: CPU ray tracing (Embree) of the cached tube mesh, every hit in order",
        A{"tubes"}, false, false, true, A{"embree-quality", "hits", "packets"}},
       prepare_cpu_tracing,
       cpu_tracing_frame_bytes},
      {{"embree", "CPU ray tracing (Embree) of curves over the lines, every hit in order (OSP)",
        A{"lines"}, false, false, true,
        A{"embree-geometry", "embree-quality", "hits", "packets", "radius", "attribute",
          "early-termination", "no-early-termination"}},
       prepare_cpu_tracing,
       cpu_tracing_frame_bytes},
      {{"opaque", "Vulkan: the tube mesh depth-tested, opacity ignored", A{"tubes"}, true, false,
        false, A{"device", "validation"}},
       prepare_raster,
       raster_frame_bytes},
      {{"dp",
        "Vulkan: depth peeling, one pass per layer (exact up to --max-layers; fragments of equal "
        "depth, as coincident tubes give, peel once)",
        A{"tubes"}, true, false, true, A{"device", "validation", "max-layers"}},
       prepare_raster,
       raster_frame_bytes},
      {{"ll", "Vulkan: per-pixel linked lists, sorted and blended (exact)", A{"tubes"}, true, false,
        true,
        A{"device", "validation", "sort", "capacity", "node-bytes", "early-termination",
          "no-early-termination"}},
       prepare_raster,
       raster_frame_bytes},
      {{"mlab", "Vulkan: multi-layer alpha blending, k nodes per pixel", A{"tubes"}, true, false,
        false, A{"device", "validation", "layers", "no-interlock"}},
       prepare_raster,
       raster_frame_bytes},
      {{"mlabdb", "Vulkan: MLAB with depth buckets", A{"tubes"}, true, false, false,
        A{"device", "validation", "layers", "tau-alpha", "tau-opaque", "no-interlock"}},
       prepare_raster,
       raster_frame_bytes},
      {{"mboit", "Vulkan: moment-based OIT", A{"tubes"}, true, false, false,
        A{"device", "validation", "beta", "moments", "moment-basis", "moment-bias"}},
       prepare_raster,
       raster_frame_bytes},
      {{"wboit", "Vulkan: weighted blended OIT", A{"tubes"}, true, false, false,
        A{"device", "validation", "wboit-weight"}},
       prepare_raster,
       raster_frame_bytes},
      {{"vrc", "voxel ray casting of the voxel line grid, CPU or Vulkan compute (--on gpu)",
        A{"voxels"}, false, false, false,
        A{"on", "early-termination", "no-early-termination", "no-skip", "radius", "device",
          "validation"}},
       prepare_vrc,
       cpu_tracing_frame_bytes},
      {{"rtx", "Vulkan ray tracing of the tube mesh (or capsules), every hit in order", A{"tubes"},
        true, true, true,
        A{"device", "validation", "rtx-geometry", "rebuild", "rtx-no-compaction", "max-iterations",
          "hits", "early-termination", "no-early-termination", "radius", "attribute"}},
       prepare_rtx,
       cpu_tracing_frame_bytes},
      {{"tiles",
        "Vulkan compute only: capsules binned into 16x16 tiles, radix-sorted, composited per "
        "pixel in exact order",
        A{"lines"}, true, false, true,
        A{"device", "validation", "radius", "attribute", "early-termination",
          "no-early-termination", "tiles-geometry", "tiles-sort", "tiles-strips"}},
       prepare_tiles,
       cpu_tracing_frame_bytes},
  };
  return table;
}

uint64_t frame_output_bytes(const TechniqueOptions& options) {
  return uint64_t(options.width) * uint64_t(options.height) * (16 + 16 + 4);
}

uint64_t estimate_frame_bytes(const Technique& technique, const TechniqueOptions& options) {
  return frame_output_bytes(options) + technique.frame_bytes(technique.info, options);
}

void set_memory_budget(TechniqueOptions& options, const std::string& budget) {
  options.memory_unlimited = budget == "unlimited";
  options.memory_budget = budget.empty() || options.memory_unlimited ? 0 : parse_size(budget);
  if (!budget.empty() && !options.memory_unlimited && options.memory_budget == 0)
    throw UsageError(kZeroBudget);
}

TechniqueFrame technique_frame(Image image, std::vector<uint32_t> depth_complexity, double seconds,
                               uint64_t frame_bytes) {
  TechniqueFrame out;
  out.image = std::move(image);
  out.depth_complexity = std::move(depth_complexity);
  out.seconds = seconds;
  out.frame_bytes = frame_bytes;
  return out;
}

void throw_missing_asset(const std::string& cache_name, const std::string& asset,
                         const std::string& why) {
  throw InputError(
      cache_name, "group /assets/" + asset,
      "missing: " + why + "; add it with: linebake bake " + cache_name + " --assets " + asset);
}

std::vector<std::string> technique_names() {
  std::vector<std::string> names;
  for (const Technique& t : techniques()) names.push_back(t.info.name);
  return names;
}

const Technique& find_technique(const std::string& name) {
  for (const Technique& t : techniques())
    if (t.info.name == name) return t;
  throw UsageError("unknown technique '" + name + "' (" + name_list(technique_names()) + ")" +
                   did_you_mean(name, technique_names()));
}

std::optional<std::string> technique_unavailable(const Technique& technique,
                                                 const TechniqueOptions& options,
                                                 const CacheReader* cache) {
  const TechniqueInfo& info = technique.info;
  if (cache) {
    std::vector<std::string> assets = info.assets;
    // tiles over the tube mesh reads the tubes (it had been a failed row, not a skipped one).
    if (info.name == "tiles" && options.tiles_geometry == "triangles") assets.push_back("tubes");
    for (const std::string& asset : assets) {
      const std::string group = asset == "lines" ? "/lines" : "/assets/" + asset;
      if (!cache->exists(group))
        return "the cache has no " + asset + " (linebake bake CACHE --assets " + asset + ")";
    }
  }
  const bool vulkan = info.vulkan || (info.name == "vrc" && options.on == "gpu");
  if (!vulkan) return std::nullopt;
  if (options.context) {
    if (info.ray_tracing && !options.context->ray_tracing())
      return no_ray_tracing(options.context->info());
    return std::nullopt;
  }
  std::vector<vk::DeviceInfo> devices;
  try {
    devices = vk::list_devices();
  } catch (const Error& e) {
    return std::string(e.what());
  }
  // The device a Context would pick: the named one, else a discrete GPU, else the first.
  auto named = [&](const vk::DeviceInfo& d) {
    return options.device.empty() ? d.type == VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU
                                  : d.name.find(options.device) != std::string::npos;
  };
  auto chosen = std::find_if(devices.begin(), devices.end(), named);
  if (chosen == devices.end() && options.device.empty() && !devices.empty())
    chosen = devices.begin();
  if (chosen == devices.end())
    return options.device.empty() ? "no Vulkan device"
                                  : "no Vulkan device named '" + options.device + "'";
  if (info.ray_tracing && !chosen->ray_tracing) return no_ray_tracing(*chosen);
  return std::nullopt;
}

ContextHolder::ContextHolder(const TechniqueOptions& options, bool ray_tracing) {
  if (options.context) {
    if (ray_tracing && !options.context->ray_tracing())
      throw vk::RayTracingUnsupported(no_ray_tracing(options.context->info()));
    context_ = options.context;
    return;
  }
  vk::ContextOptions co;
  co.device = options.device;
  co.validation = options.validation;
  co.ray_tracing = ray_tracing;
  owned_ = std::make_unique<vk::Context>(co);
  context_ = owned_.get();
}

ContextHolder::~ContextHolder() {
  if (budget_serial_ && !owned_) context_->restore_host_budget(budget_serial_, found_);
}

void ContextHolder::budget_host_memory(const TechniqueOptions& options, uint64_t compile) {
  if (!budget_serial_) found_ = context_->host_budget_state();
  budget_serial_ =
      context_->set_host_budget(process_budget(options), frame_output_bytes(options), compile);
}

uint64_t process_budget(const TechniqueOptions& o) {
  if (o.memory_unlimited) return 0;
  return o.memory_budget > 0 ? o.memory_budget : default_memory_budget();
}

std::optional<std::string> data_does_not_fit(const TechniqueOptions& o, uint64_t bytes,
                                             const std::string& data) {
  if (o.memory_unlimited) return std::nullopt;
  if (bytes <= MemoryBudget(process_budget(o)).available()) return std::nullopt;
  trimmed_rss_bytes();  // memory freed but still resident in the heap is not held
  const MemoryBudget budget(process_budget(o));
  if (bytes <= budget.available()) return std::nullopt;
  // What the process holds already (the Vulkan driver, its compiler) is not left: said so, with
  // no figure of its own, which differs from process to process (the CLI's and Python's).
  return "the " + data + " take " + format_bytes(bytes) +
         " in memory, more than the memory budget leaves (" + format_bytes(budget.available()) +
         " of " + format_bytes(budget.total()) + ", less what the process holds already)";
}

void check_data_fits(const TechniqueInfo& info, const TechniqueOptions& o, const CacheReader& cache,
                     const std::string& group, const std::string& data) {
  const auto provenance = cache.provenance(group);
  if (provenance) check_bytes_fit(info, o, provenance->memory_bytes, data);
}

void check_bytes_fit(const TechniqueInfo& info, const TechniqueOptions& o, uint64_t bytes,
                     const std::string& data) {
  if (auto why = data_does_not_fit(o, bytes, data))
    throw BudgetExceeded(info.name + ": " + *why + "; raise --memory-budget");
}

void ContextHolder::check_validation() const {
  if (context_->validation_errors() > 0)
    throw Error("Vulkan validation: " + std::to_string(context_->validation_errors()) +
                " error(s); last: " + context_->last_validation_error());
}

}  // namespace linebake
