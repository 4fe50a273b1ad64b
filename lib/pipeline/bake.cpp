#include "pipeline/bake.hpp"

#include <tbb/info.h>

#include <filesystem>

#include "accel/capsule_segments.hpp"
#include "cache/embree_store.hpp"
#include "cache/line_store.hpp"
#include "cache/rtx_store.hpp"
#include "cache/tube_store.hpp"
#include "cache/voxel_store.hpp"
#include "core/error.hpp"
#include "core/hash.hpp"
#include "render/vulkan/rt_scene.hpp"
#include "synth/synth.hpp"

namespace linebake {
namespace {

// Bumped when a step's stored layout changes, so old caches rebuild instead of misreading.
constexpr uint64_t kLinesVersion = 1;
constexpr uint64_t kTubesVersion = 1;
constexpr uint64_t kVoxelsVersion = 1;
constexpr uint64_t kEmbreeVersion = 1;
constexpr uint64_t kRtxVersion = 1;

uint64_t threads() {
  return static_cast<uint64_t>(tbb::info::default_concurrency());
}

// The input's identity: its bytes, or for a synth: source its parameters and the generator
// version (the generator is part of linebake).
std::string source_hash(const std::string& input) {
  if (synth::is_synth_source(input)) {
    const synth::SynthParams p = synth::parse_synth_source(input);
    Hasher h;
    h.update(std::string_view("synth"))
        .update(std::string_view(p.name))
        .update(std::string_view(std::to_string(p.scale)))
        .update(p.seed)
        .update(uint64_t{p.adaptive})
        .update(std::string_view(LINEBAKE_VERSION));
    return h.hex();
  }
  return hash_file(input);
}

std::string key_of(std::initializer_list<std::string_view> parts) {
  Hasher h;
  for (std::string_view part : parts) h.update(part);
  return h.hex();
}

}  // namespace

const std::vector<std::string>& bakeable_assets() {
  static const std::vector<std::string> assets{"tubes", "voxels", "embree", "rtx"};
  return assets;
}

std::string default_cache_path(const std::string& input) {
  if (synth::is_synth_source(input)) {
    const synth::SynthParams p = synth::parse_synth_source(input);
    return p.name + ".lbc.h5";
  }
  return std::filesystem::path(input).stem().string() + ".lbc.h5";
}

nlohmann::json to_json(const TubeOptions& t) {
  nlohmann::json j = {{"sides", t.sides},
                      {"radius", t.radius},
                      {"radius_absolute", t.radius_absolute},
                      {"radius_attribute", t.radius_attribute},
                      {"caps", t.caps},
                      {"normals", to_string(t.normals)},
                      {"attribute", t.attribute},
                      {"max_chunk_bytes", t.max_chunk_bytes},
                      {"max_chunk_indices", t.max_chunk_indices},
                      {"min_point_distance", t.min_point_distance}};
  j["attribute_range"] = t.attribute_range ? nlohmann::json(*t.attribute_range) : nullptr;
  return j;
}

std::string tubes_key(const std::string& lines_hash, const TubeOptions& tubes,
                      Compression compression, int level) {
  return key_of({"tubes", std::to_string(kTubesVersion), lines_hash, to_json(tubes).dump(),
                 to_string(compression), std::to_string(level)});
}

nlohmann::json to_json(const VoxelOptions& v) {
  nlohmann::json j = {{"grid", v.grid},
                      {"quantization", v.quantization},
                      {"max_chords_per_voxel", v.max_chords_per_voxel},
                      {"attribute", v.attribute}};
  j["resolution"] = v.resolution ? nlohmann::json(*v.resolution) : nullptr;
  j["attribute_range"] = v.attribute_range ? nlohmann::json(*v.attribute_range) : nullptr;
  return j;
}

std::string voxels_key(const std::string& lines_hash, const VoxelOptions& voxels,
                       Compression compression, int level) {
  return key_of({"voxels", std::to_string(kVoxelsVersion), lines_hash, to_json(voxels).dump(),
                 to_string(compression), std::to_string(level)});
}

nlohmann::json to_json(const EmbreeOptions& e, const TubeOptions& t) {
  return {{"geometry", to_string(e.geometry)},
          {"quality", to_string(e.quality)},
          {"compact", e.compact},
          {"robust", e.robust},
          {"max_primitives_per_scene", e.max_primitives_per_scene},
          {"radius", t.radius},
          {"radius_absolute", t.radius_absolute},
          {"attribute", t.attribute}};
}

std::string embree_key(const std::string& lines_hash, const EmbreeOptions& e, const TubeOptions& t,
                       Compression compression, int level) {
  return key_of({"embree", std::to_string(kEmbreeVersion), lines_hash, to_json(e, t).dump(),
                 to_string(compression), std::to_string(level)});
}

nlohmann::json to_json(const RtxOptions& r) {
  return {{"geometry", r.geometry}, {"compaction", r.compaction}};
}

std::string rtx_capsules_source(const std::string& lines_hash, float radius,
                                const std::string& attribute) {
  return key_of({"capsules", lines_hash, std::to_string(radius), attribute});
}

// The attribute the tubes colour by, for the curves: "" = the first, "none" = none.
static std::string curve_attribute(const LineSet& lines, const TubeOptions& t) {
  if (t.attribute == "none") return "";
  if (!t.attribute.empty()) return t.attribute;
  return lines.attributes.empty() ? "" : lines.attributes[0].name;
}

// Builds the BLAS and TLAS on the ray tracing device, serialises the BLAS into `out` and the
// figures into the provenance.
static void build_rtx_step(vk::Context& context, const BakeOptions& options, const LineSet& lines,
                           const std::string& lines_hash, const std::string& tubes_step_key,
                           const TubeMesh& built_tubes, const CacheReader* old, StoredRtx& out,
                           Provenance& p) {
  std::optional<vk::RtScene> scene;
  TubeMesh loaded_tubes;
  CapsuleSegments capsules;
  if (options.rtx.geometry == "triangles") {
    const bool built_now =
        std::find(options.assets.begin(), options.assets.end(), "tubes") != options.assets.end();
    const TubeMesh* mesh = built_now && !built_tubes.chunks.empty() ? &built_tubes : nullptr;
    if (!mesh && old) {
      const auto previous = old->provenance("/assets/tubes");
      if (previous && previous->key == tubes_step_key) {
        loaded_tubes = load_tubes(*old);
        mesh = &loaded_tubes;
      }
    }
    if (!mesh)
      throw Error(
          "rtx: triangle BLAS are built over the tube mesh; bake --assets tubes,rtx (with the "
          "same tube options)");
    scene.emplace(context, *mesh);
    out.source = tubes_step_key;
  } else {
    const float radius = world_radius(lines, options.tubes);
    const std::string attribute = curve_attribute(lines, options.tubes);
    capsules = build_capsule_segments(lines, radius, attribute);
    scene.emplace(context, capsules);
    out.source = rtx_capsules_source(lines_hash, radius, attribute);
  }
  scene->build(options.rtx.compaction);
  out.blobs = scene->serialize();
  out.geometry = options.rtx.geometry;
  out.compaction = options.rtx.compaction;
  const vk::DeviceInfo& device = context.info();
  out.device = device.name;
  out.driver = device.driver;
  out.driver_uuid = vk::to_hex(device.driver_uuid);
  const vk::RtBuildFigures& f = scene->figures();
  p.stats = vk::to_json(f);
  uint64_t serialized = 0;
  for (const auto& blob : out.blobs) serialized += blob.size();
  p.stats["serialized_bytes"] = serialized;
  p.stats["device"] = device.name;
  p.stats["driver"] = device.driver;
  p.stats["driver_uuid"] = out.driver_uuid;
  // What ray tracing keeps resident on the device: geometry, BLAS, TLAS and instances.
  p.memory_bytes = f.resident_bytes();
  if (context.validation_errors() > 0)
    throw Error("Vulkan validation: " + std::to_string(context.validation_errors()) +
                " error(s); last: " + context.last_validation_error());
}

BakeResult bake(const BakeOptions& options_in) {
  BakeOptions options = options_in;
  for (const std::string& asset : options.assets)
    if (std::find(bakeable_assets().begin(), bakeable_assets().end(), asset) ==
        bakeable_assets().end())
      throw Error("unknown asset '" + asset + "' (bake builds: tubes, voxels, embree, rtx)");
  // Build order: rtx needs the tubes of this run.
  std::stable_sort(
      options.assets.begin(), options.assets.end(), [](const std::string& a, const std::string& b) {
        const auto& order = bakeable_assets();
        return std::find(order.begin(), order.end(), a) < std::find(order.begin(), order.end(), b);
      });
  options.assets.erase(std::unique(options.assets.begin(), options.assets.end()),
                       options.assets.end());
  if (options.rtx.geometry != "triangles" && options.rtx.geometry != "capsules")
    throw Error("rtx: unknown geometry '" + options.rtx.geometry + "' (triangles, capsules)");
  // Ray tracing needs its device before anything is read: the BLAS belong to it (its driver UUID
  // is part of the step's key), and a device without ray tracing fails here, in one line.
  std::optional<vk::Context> rt_context;
  if (std::find(options.assets.begin(), options.assets.end(), "rtx") != options.assets.end()) {
    vk::ContextOptions co;
    co.device = options.rtx.device;
    co.validation = options.rtx.validation;
    co.ray_tracing = true;
    try {
      rt_context.emplace(co);
    } catch (const vk::RayTracingUnsupported& e) {
      throw vk::RayTracingUnsupported(std::string("rtx: ") + e.what());
    }
  }
  BakeResult result;
  result.cache = options.cache.empty() ? default_cache_path(options.input) : options.cache;

  const std::string source = source_hash(options.input);
  const std::string format = options.format ? format_info(*options.format).name : "auto";
  const std::string policy = options.on_invalid == InvalidPolicy::reject ? "reject" : "repair";
  const std::string lines_key =
      key_of({"lines", std::to_string(kLinesVersion), source, format, policy});

  // What the existing cache already holds.
  std::unique_ptr<CacheReader> old;
  if (std::filesystem::exists(result.cache)) {
    try {
      old = std::make_unique<CacheReader>(result.cache);
    } catch (const InputError& e) {
      // A damaged or foreign file at the output path is replaced, not trusted.
      result.notes.push_back(std::string("existing cache not usable, rebuilding: ") + e.what());
    }
  }
  const auto old_provenance = [&](const std::string& group) -> std::optional<Provenance> {
    return old ? old->provenance(group) : std::nullopt;
  };

  // Lines: reuse when the same input was read the same way.
  LineSet lines;
  bool lines_loaded = false;
  BakeStep lines_step{"lines", false, {}};
  const auto old_lines = old_provenance("/lines");
  const bool reuse_lines = !options.force && old_lines && old_lines->key == lines_key;
  const auto load_or_read = [&] {
    if (lines_loaded) return;
    lines_loaded = true;
    if (reuse_lines) {
      lines = load_lines(*old);
      return;
    }
    StepMeter meter;
    {
      TerminalProgress progress("reading " + options.input);
      ReadOptions read;
      read.format = options.format;
      if (options.progress) read.progress = progress.callback();
      lines = read_line_set(options.input, read);
    }
    const ValidationReport report = validate(lines, options.on_invalid, options.input);
    if (!report.clean()) result.notes.push_back(options.input + ": " + report.summary());
    Provenance& p = lines_step.provenance;
    p.build = meter.stop();
    p.step = "lines";
    p.key = lines_key;
    p.input_hash = source;
    p.parameters = {{"source", options.input}, {"format", format}, {"on_invalid", policy}};
    const LineSetStats stats = compute_stats(lines);
    p.stats = {{"content_hash", content_hash(lines)},
               {"lines", stats.lines},
               {"points", stats.points},
               {"segments", stats.segments}};
    p.created = utc_now_iso8601();
    p.threads = threads();
    p.compression = to_string(options.compression);
    lines_step.built = true;
  };
  if (!reuse_lines) load_or_read();
  const std::string lines_hash =
      reuse_lines ? old_lines->stats.value("content_hash", "")
                  : lines_step.provenance.stats["content_hash"].get<std::string>();
  lines_step.provenance = reuse_lines ? *old_lines : lines_step.provenance;

  // Assets: reuse on an equal key, else build.
  std::vector<BakeStep> asset_steps;
  TubeMesh tubes;
  VoxelGrid voxels;
  StoredCurves curves;
  StoredRtx rtx;
  for (const std::string& asset : options.assets) {
    BakeStep step{asset, false, {}};
    const bool is_tubes = asset == "tubes", is_voxels = asset == "voxels";
    const bool is_rtx = asset == "rtx";
    const std::string tubes_step_key =
        tubes_key(lines_hash, options.tubes, options.compression, options.compression_level);
    std::string key = is_tubes    ? tubes_step_key
                      : is_voxels ? voxels_key(lines_hash, options.voxels, options.compression,
                                               options.compression_level)
                                  : embree_key(lines_hash, options.embree, options.tubes,
                                               options.compression, options.compression_level);
    if (is_rtx) {
      const vk::DeviceInfo& device = rt_context->info();
      key = key_of({"rtx", std::to_string(kRtxVersion), tubes_step_key, to_json(options.rtx).dump(),
                    device.name, vk::to_hex(device.driver_uuid), to_string(options.compression),
                    std::to_string(options.compression_level)});
    }
    const auto previous = old_provenance("/assets/" + asset);
    if (!options.force && previous && previous->key == key) {
      step.provenance = *previous;
      asset_steps.push_back(std::move(step));
      continue;
    }
    load_or_read();
    Provenance& p = step.provenance;
    StepMeter meter;
    {
      TerminalProgress progress("building " + asset);
      const ProgressFn callback = options.progress ? progress.callback() : ProgressFn{};
      if (is_tubes) {
        tubes = build_tubes(lines, options.tubes, callback);
      } else if (is_rtx) {
        build_rtx_step(*rt_context, options, lines, lines_hash, tubes_step_key, tubes, old.get(),
                       rtx, p);
      } else if (is_voxels) {
        voxels = voxelize(lines, options.voxels, callback);
      } else {
        curves.geometry = options.embree.geometry;
        curves.radius = world_radius(lines, options.tubes);
        curves.attribute = curve_attribute(lines, options.tubes);
        const EmbreeScene scene =
            EmbreeScene::from_lines(lines, curves.radius, curves.attribute, options.embree);
        curves.parts = scene.prepared_curves();
        const BvhStats& b = scene.stats();
        p.stats = {{"geometry", to_string(b.geometry)},
                   {"quality", to_string(options.embree.quality)},
                   {"primitives", b.primitives},
                   {"parts", b.parts},
                   {"instanced", b.instanced},
                   {"radius_world", curves.radius},
                   {"attribute", curves.attribute},
                   {"prepare_s", b.prepare_s},
                   {"commit_s", b.commit_s},
                   {"buffer_bytes", b.buffer_bytes},
                   {"bvh_bytes", b.bvh_bytes},
                   {"bvh_peak_bytes", b.bvh_peak_bytes}};
        // What ray tracing needs resident: the prepared buffers and the BVH.
        p.memory_bytes = b.buffer_bytes + b.bvh_bytes;
      }
    }
    p.build = meter.stop();
    if (is_tubes) {
      p.parameters = to_json(options.tubes);
      p.stats = {{"chunks", tubes.chunks.size()},        {"vertices", tubes.vertex_count()},
                 {"triangles", tubes.triangle_count()},  {"radius_world", tubes.radius},
                 {"attribute", tubes.attribute},         {"attribute_range", tubes.attribute_range},
                 {"lines_dropped", tubes.lines_dropped}, {"points_skipped", tubes.points_skipped}};
      p.memory_bytes = tubes.bytes();
      if (tubes.lines_dropped)
        result.notes.push_back("tubes: " + std::to_string(tubes.lines_dropped) +
                               " lines with fewer than two distinct points have no tube");
    } else if (is_rtx) {
      p.parameters = to_json(options.rtx);
    } else if (!is_voxels) {
      p.parameters = to_json(options.embree, options.tubes);
    } else {
      p.parameters = to_json(options.voxels);
      p.stats = {{"resolution", voxels.resolution},
                 {"quantization", voxels.quantization},
                 {"chords", voxels.chord_count()},
                 {"voxels_occupied", voxels.voxels_occupied},
                 {"chords_dropped", voxels.chords_dropped},
                 {"voxels_overflowed", voxels.voxels_overflowed},
                 {"max_error_voxels", voxels.max_error},
                 {"mean_error_voxels", voxels.mean_error},
                 {"bytes_with_density", voxels.bytes()}};
      p.memory_bytes = voxels.representation_bytes();
      if (voxels.chords_dropped)
        result.notes.push_back("voxels: " + std::to_string(voxels.chords_dropped) +
                               " chords dropped in " + std::to_string(voxels.voxels_overflowed) +
                               " voxels over the cap of " +
                               std::to_string(voxels.max_chords_per_voxel) + " per voxel");
    }
    p.step = asset;
    p.key = key;
    p.input_hash = lines_hash;
    p.created = utc_now_iso8601();
    p.threads = threads();
    p.compression = to_string(options.compression);
    step.built = true;
    asset_steps.push_back(std::move(step));
  }

  bool anything_built = lines_step.built;
  for (const BakeStep& s : asset_steps) anything_built |= s.built;
  // Assets in the old cache that were not asked for this time are kept if still valid for
  // these lines.
  std::vector<std::string> kept;
  if (old) {
    for (const std::string& name : old->assets()) {
      if (std::find(options.assets.begin(), options.assets.end(), name) != options.assets.end())
        continue;
      const auto p = old->provenance("/assets/" + name);
      if (p && p->input_hash == lines_hash) kept.push_back(name);
    }
  }
  if (anything_built) {
    CacheWriter writer(result.cache, options.compression, options.compression_level);
    TerminalProgress progress("writing " + result.cache);
    uint64_t total = lines_step.built ? line_set_bytes(lines) : 0;
    for (const BakeStep& s : asset_steps)
      if (s.built)
        total += s.step == "embree" ? s.provenance.stats.value("buffer_bytes", uint64_t{0})
                 : s.step == "rtx"  ? s.provenance.stats.value("serialized_bytes", uint64_t{0})
                                    : s.provenance.memory_bytes;
    if (options.progress) writer.set_progress(progress.callback(), total);
    if (lines_step.built) {
      store_lines(writer, lines, lines_step.provenance);
    } else {
      writer.copy_group(result.cache, "/lines");
    }
    for (const BakeStep& s : asset_steps) {
      if (!s.built)
        writer.copy_group(result.cache, "/assets/" + s.step);
      else if (s.step == "tubes")
        store_tubes(writer, tubes, s.provenance);
      else if (s.step == "voxels")
        store_voxels(writer, voxels, s.provenance);
      else if (s.step == "rtx")
        store_rtx(writer, rtx, s.provenance);
      else
        store_embree(writer, curves, s.provenance);
    }
    for (const std::string& name : kept) writer.copy_group(result.cache, "/assets/" + name);
    old.reset();
    writer.commit();
    result.written = true;
    // Read back what was stored, so the report shows the stored figures (disk bytes).
    CacheReader stored(result.cache, false);
    if (auto p = stored.provenance("/lines")) lines_step.provenance = *p;
    for (BakeStep& s : asset_steps)
      if (auto p = stored.provenance("/assets/" + s.step)) s.provenance = *p;
  }
  result.steps.push_back(std::move(lines_step));
  for (BakeStep& s : asset_steps) result.steps.push_back(std::move(s));
  return result;
}

}  // namespace linebake
