#include "pipeline/bake.hpp"

#include <sys/stat.h>
#include <tbb/global_control.h>
#include <tbb/info.h>
#include <tbb/parallel_invoke.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <set>

#include "accel/capsule_segments.hpp"
#include "cache/embree_store.hpp"
#include "cache/line_store.hpp"
#include "cache/rtx_store.hpp"
#include "cache/tube_store.hpp"
#include "cache/voxel_store.hpp"
#include "core/error.hpp"
#include "core/hash.hpp"
#include "core/interrupt.hpp"
#include "core/json_file.hpp"
#include "core/measure.hpp"
#include "core/memory_budget.hpp"
#include "core/output_lock.hpp"
#include "lines/line_spool.hpp"
#include "pipeline/bake_budget.hpp"
#include "render/vulkan/rt_scene.hpp"
#include "synth/synth.hpp"

namespace linebake {

uint64_t build_threads() {
  // The machine's, or fewer under a tbb::global_control (bench --threads).
  const size_t allowed =
      tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
  return std::min<uint64_t>(uint64_t(tbb::info::default_concurrency()), uint64_t(allowed));
}

namespace {

// Bumped when a step's stored layout changes, so old caches rebuild instead of misreading.
// Version 2: the content hash is computed per array (batch by batch), and the provenance keeps
// the line statistics later steps need. Version 4 (the key covers the file's bytes, not what the
// readers make of them): the readers of 2026-11-29 read files differently (VTK component names,
// OBJ colours, NetCDF packing and missing values, renamed duplicate names), so lines cached from
// the same file before are read again. Version 5: a missing NetCDF position is a gap that splits
// its trajectory (it ended it, dropping the positions after it).
constexpr uint64_t kLinesVersion = 5;
constexpr uint64_t kTubesVersion = 1;
constexpr uint64_t kVoxelsVersion = 1;
constexpr uint64_t kEmbreeVersion = 1;
constexpr uint64_t kRtxVersion = 1;

uint64_t threads() {
  return build_threads();
}

// The input's identity: its bytes (each file's hash, from `file_hashes` where given), or for a
// synth: source its parameters and the generator version (the generator is part of linebake).
std::string source_hash(const std::vector<std::string>& inputs,
                        const std::vector<std::string>& file_hashes) {
  const auto file_hash = [&](size_t i) {
    return file_hashes.empty() ? hash_file(inputs[i]) : file_hashes.at(i);
  };
  if (inputs.size() > 1) {
    Hasher h;
    h.update(std::string_view("files")).update(uint64_t{inputs.size()});
    for (size_t i = 0; i < inputs.size(); ++i) h.update(std::string_view(file_hash(i)));
    return h.hex();
  }
  const std::string& input = inputs.front();
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
  return file_hash(0);
}

std::string key_of(std::initializer_list<std::string_view> parts) {
  Hasher h;
  for (std::string_view part : parts) h.update(part);
  return h.hex();
}

}  // namespace

LinesIdentity lines_identity(const BakeOptions& options,
                             const std::vector<std::string>& file_hashes) {
  LinesIdentity id;
  id.source_hash =
      source_hash(options.inputs.empty() ? std::vector<std::string>{options.input} : options.inputs,
                  file_hashes);
  id.format = options.format ? format_info(*options.format).name : "auto";
  id.policy = options.on_invalid == InvalidPolicy::reject ? "reject" : "repair";
  // "auto" as asked (the same source bytes give the same origin), numbers as origin_text writes.
  const std::optional<Origin> numbers = origin_option_numbers(options.origin);
  id.origin = numbers ? origin_text(*numbers) : options.origin;
  // Lines read without an origin keep the key they had before origins existed.
  id.key =
      id.origin.empty()
          ? key_of({"lines", std::to_string(kLinesVersion), id.source_hash, id.format, id.policy})
          : key_of({"lines", std::to_string(kLinesVersion), id.source_hash, id.format, id.policy,
                    "origin", id.origin});
  return id;
}

uint64_t cost_per_point(const BakeOptions& o, const LineSet& header, bool tubes, bool voxels,
                        bool embree) {
  const uint64_t line_bytes = 12 + 4 * header.attributes.size() + 8;
  uint64_t cost = 3 * line_bytes;
  if (tubes) {
    const bool attribute = o.tubes.attribute != "none" &&
                           (!header.attributes.empty() || !header.line_attributes.empty());
    cost += uint64_t(o.tubes.sides) * tube_vertex_bytes(o.tubes.normals, attribute) +
            uint64_t(o.tubes.sides) * 6 * 4;
  }
  if (voxels) cost += 2 * 2 * 16 + 64;
  if (embree) cost += o.embree.geometry == EmbreeGeometry::BezierCurve ? 69 : 21;
  return cost;
}

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

std::string bake_output_path(const BakeOptions& options) {
  if (!options.cache.empty()) return options.cache;
  const std::vector<std::string> inputs =
      options.inputs.empty() ? std::vector<std::string>{options.input} : options.inputs;
  if (inputs.size() != 1) return "";
  const std::string& input = inputs[0];
  if (!synth::is_synth_source(input) && is_linebake_cache(input)) return input;
  return default_cache_path(input);
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
  return key_of({"tubes", std::to_string(kTubesVersion), lines_hash, json_text(to_json(tubes)),
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
  return key_of({"voxels", std::to_string(kVoxelsVersion), lines_hash, json_text(to_json(voxels)),
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
  return key_of({"embree", std::to_string(kEmbreeVersion), lines_hash, json_text(to_json(e, t)),
                 to_string(compression), std::to_string(level)});
}

StoredCurves embree_curves(const BakeOptions& options, const LineSet& header,
                           const LineSetStats& stats) {
  StoredCurves curves;
  curves.geometry = options.embree.geometry;
  curves.radius = world_radius(stats.bounds, options.tubes);
  if (options.tubes.attribute != "none")
    curves.attribute = !options.tubes.attribute.empty() ? options.tubes.attribute
                       : header.attributes.empty()      ? ""
                                                        : header.attributes[0].name;
  if (options.embree.geometry == EmbreeGeometry::Triangles)
    throw Error("Embree: triangles are built from a tube mesh, not from lines");
  if (!(curves.radius > 0)) throw Error("Embree: the curve radius must be positive");
  if (options.embree.max_primitives_per_scene == 0)
    throw Error("Embree: max primitives per scene is 0");
  return curves;
}

nlohmann::json to_json(const RtxOptions& r) {
  return {{"geometry", r.geometry}, {"compaction", r.compaction}};
}

nlohmann::json voxel_stats(const VoxelGrid& g, uint64_t chords, uint64_t bytes_with_density,
                           uint64_t records_in_memory, uint64_t records_spilled) {
  return {{"resolution", g.resolution},
          {"quantization", g.quantization},
          {"chords", chords},
          {"bytes_with_density", bytes_with_density},
          {"voxels_occupied", g.voxels_occupied},
          {"chords_dropped", g.chords_dropped},
          {"voxels_overflowed", g.voxels_overflowed},
          {"max_error_voxels", g.max_error},
          {"mean_error_voxels", g.mean_error},
          {"records_in_memory_bytes", records_in_memory},
          {"records_spilled_bytes", records_spilled}};
}

std::string dropped_chords_note(const VoxelGrid& g) {
  if (!g.chords_dropped) return "";
  return "voxels: " + std::to_string(g.chords_dropped) + " chords dropped in " +
         std::to_string(g.voxels_overflowed) + " voxels over the cap of " +
         std::to_string(g.max_chords_per_voxel) + " per voxel";
}

nlohmann::json embree_stats(const EmbreeOptions& embree, const StoredCurves& curves,
                            double prepare_s, const EmbreeStoreWriter& writer) {
  return {{"geometry", to_string(embree.geometry)},
          {"quality", to_string(embree.quality)},
          {"radius_world", curves.radius},
          {"attribute", curves.attribute},
          {"prepare_s", prepare_s},
          {"buffer_bytes", writer.buffer_bytes()},
          {"primitives", writer.segments()},
          {"parts", writer.part_count()}};
}

nlohmann::json tube_stats(const TubeMesh& mesh, const std::vector<TubeChunkPlan>& plan) {
  uint64_t vertices = 0, indices = 0;
  for (const TubeChunkPlan& c : plan) vertices += c.vertices, indices += c.indices;
  return {{"chunks", plan.size()},
          {"vertices", vertices},
          {"triangles", indices / 3},
          {"radius_world", mesh.radius},
          {"attribute", mesh.attribute},
          {"attribute_range", mesh.attribute_range},
          {"lines_dropped", mesh.lines_dropped},
          {"points_skipped", mesh.points_skipped}};
}

// The attribute the tubes colour by, for the curves: "" = the first, "none" = none.
static std::string curve_attribute(const LineSet& lines, const TubeOptions& t) {
  if (t.attribute == "none") return "";
  if (!t.attribute.empty()) return t.attribute;
  return lines.attributes.empty() ? "" : lines.attributes[0].name;
}

// The rtx step: BLAS built on the ray tracing device over the tube mesh (triangles; read back
// from the cache being written, or the old one) or over capsules (the whole line set), then
// serialised into `out` with the figures in the provenance.
static void build_rtx_step(vk::Context& context, const BakeOptions& options,
                           const MemoryBudget& budget, const std::function<LineSet()>& whole_lines,
                           const std::function<std::optional<TubeMesh>()>& tubes,
                           const std::string& lines_hash, const std::string& tubes_step_key,
                           StoredRtx& out, Provenance& p) {
  // The device's allocations of host memory (all of them on an integrated GPU; staging,
  // scratch and the serialisation's targets elsewhere) and the serialised copies within the
  // budget: past it the bake ends with BudgetExceeded and the figures, as its other steps do.
  context.set_host_budget(budget.total(), budget.reserved());
  std::optional<vk::RtScene> scene;
  std::optional<TubeMesh> mesh;
  CapsuleSegments capsules;
  if (options.rtx.geometry == "triangles") {
    mesh = tubes();
    if (!mesh)
      throw Error(
          "rtx: triangle BLAS are built over the tube mesh; bake --assets tubes,rtx (with the "
          "same tube options)");
    scene.emplace(context, *mesh);
    out.source = tubes_step_key;
  } else {
    const LineSet lines = whole_lines();
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

namespace {

bool contains(const std::vector<std::string>& list, const std::string& item) {
  return std::find(list.begin(), list.end(), item) != list.end();
}

}  // namespace

void check_attribute_options(const BakeOptions& o, const LineSet& header) {
  const auto has = [&](const std::string& name, bool vertex_only) {
    for (const Attribute& a : header.attributes)
      if (a.name == name) return true;
    if (!vertex_only)
      for (const Attribute& a : header.line_attributes)
        if (a.name == name) return true;
    return false;
  };
  const bool tubes = contains(o.assets, "tubes") || contains(o.assets, "rtx");
  const std::string& attribute = o.tubes.attribute;
  if (!attribute.empty() && attribute != "none") {
    if (tubes && !has(attribute, false))
      throw_unknown_attribute(header, "--attribute", attribute, false);
    if (contains(o.assets, "embree") && !has(attribute, true))
      throw_unknown_attribute(header, "--attribute", attribute, true);
  }
  if (tubes && !o.tubes.radius_attribute.empty() && !has(o.tubes.radius_attribute, true))
    throw_unknown_attribute(header, "--radius-attribute", o.tubes.radius_attribute, true);
  const std::string& voxel = o.voxels.attribute;
  if (contains(o.assets, "voxels") && !voxel.empty() && voxel != "none" && !has(voxel, true))
    throw_unknown_attribute(header, "--voxel-attribute", voxel, true);
}

namespace {

// Wall and CPU time of a step that runs in pieces inside shared passes, and the peak resident
// memory of the passes it ran in. Steps that run side by side (tubes and voxels in the build
// pass) each count the process's CPU time while they are in progress, so their figures overlap.
struct StepClock {
  explicit StepClock(std::string name) : step(std::move(name)) {}
  std::string step;
  double wall_s = 0, cpu_s = 0;
  uint64_t peak_rss = 0, rss_before = UINT64_MAX;
  uint64_t runs = 0;
  std::set<std::string> built_with;  // the other steps that ran in a pass with this one
  template <class F>
  void run(F&& f) {
    ++runs;
    const auto start = std::chrono::steady_clock::now();
    const double cpu = process_cpu_seconds();
    rss_before = std::min(rss_before, current_rss_bytes());
    f();
    wall_s += seconds_since(start);
    cpu_s += process_cpu_seconds() - cpu;
  }
  StepFigures figures() const {
    StepFigures f;
    f.wall_s = wall_s;
    f.cpu_s = cpu_s;
    f.rss_before = rss_before == UINT64_MAX ? 0 : rss_before;
    f.peak_rss = peak_rss;
    f.peak_is_step_local = true;
    f.built_with.assign(built_with.begin(), built_with.end());
    return f;
  }
};

// A pass over the data: its time and its resident high-water mark (reset at its start).
class Stage {
 public:
  Stage(BakeResult& result, std::string name, std::vector<StepClock*> clocks)
      : result_(result), clocks_(std::move(clocks)) {
    stage_.name = std::move(name);
    for (const StepClock* c : clocks_) runs_before_.push_back(c->runs);
  }
  ~Stage() {
    const StepFigures f = meter_.stop();
    stage_.wall_s = f.wall_s;
    stage_.cpu_s = f.cpu_s;
    stage_.peak_rss_bytes = f.peak_rss;
    // The pass's peak is each step's that ran in it, and theirs together.
    std::vector<StepClock*> ran;
    for (size_t i = 0; i < clocks_.size(); ++i)
      if (clocks_[i]->runs > runs_before_[i]) ran.push_back(clocks_[i]);
    for (StepClock* c : ran) {
      c->peak_rss = std::max(c->peak_rss, f.peak_rss);
      for (const StepClock* other : ran)
        if (other != c) c->built_with.insert(other->step);
    }
    result_.stages.push_back(stage_);
  }

 private:
  BakeResult& result_;
  std::vector<StepClock*> clocks_;
  std::vector<uint64_t> runs_before_;
  BakeStage stage_;
  StepMeter meter_;
};

// How the budget is shared between the stages of a bake (see budget_plan()).
struct BudgetPlan {
  uint64_t batch_points = 0;   // points per batch
  uint64_t batch_bytes = 0;    // what a batch costs in all the steps that see it
  uint64_t voxel_records = 0;  // chord records held in memory before they spill
  uint64_t voxel_merge = 0;    // one voxel range's merge
  uint64_t whole_lines = 0;    // a line set a format could not stream
};

// Bytes a batch costs per point in the steps that see it: the line data several times over
// (as read, as repaired, as read back), the tube staging, the voxel walk's records (about two
// chords per segment, 16 bytes each, twice: per block and sorted), Embree's buffers.

}  // namespace

uint64_t BakeEstimate::step(const std::string& name) const {
  return name == "lines"    ? lines
         : name == "tubes"  ? tubes
         : name == "voxels" ? voxels
         : name == "embree" ? embree
                            : 0;
}

// Stored sizes from the raw ones with the compression ratios measured on the synthetic sets
// (README, Table 1): LZ4 keeps about 41 % of a tube mesh, 77 % of a line set, 96 % of a voxel
// grid; deflate and Blosc/zstd a little less. Ten percent on top for what varies by data.
BakeEstimate estimate_bake(const LineSetStats& stats, const LineSet& header, const BakeOptions& o,
                           uint64_t records_in_memory) {
  const bool packed = o.compression != Compression::None;
  const auto stored = [&](double raw, double ratio) {
    return uint64_t(raw * (packed ? ratio : 1.0) * 1.1) + (uint64_t{64} << 10);
  };
  const double points = double(stats.points), segments = double(stats.segments),
               lines = double(stats.lines);
  const double attributes = double(header.attributes.size()),
               line_attributes = double(header.line_attributes.size());
  const auto has = [&](const char* asset) {
    return std::find(o.assets.begin(), o.assets.end(), asset) != o.assets.end();
  };
  BakeEstimate e;
  const double line_bytes =
      points * (12 + 4 * attributes) + (lines + 1) * 8 + lines * 4 * line_attributes;
  e.lines = stored(line_bytes, 0.78);
  e.spill = uint64_t(line_bytes);  // the line set as read, kept beside the cache
  if (has("tubes")) {
    const double sides = o.tubes.sides;
    const double vertex = double(tube_vertex_bytes(o.tubes.normals, true));
    double raw = points * sides * vertex + segments * 6 * sides * 4;
    if (o.tubes.caps) raw += lines * (2 * vertex + 6 * sides * 4);
    e.tubes = stored(raw, 0.42);
  }
  if (has("voxels")) {
    VoxelOptions v = o.voxels;
    VoxelGrid placement;
    try {
      placement = VoxelStreamBuilder(header, stats, v).description();
    } catch (const Error&) {
    }
    const double voxels = double(placement.voxel_count());
    const double chords = 1.9 * segments;  // measured 1.8 on clouds at the automatic grid
    e.voxels = stored(voxels * (4 + 1 + 4.0 * 8 / 7) + chords * 8, 0.96);
    const double records = chords * 16;
    if (records > double(records_in_memory))
      e.spill += uint64_t(records - double(records_in_memory));
  }
  if (has("embree")) {
    const bool bezier = o.embree.geometry == EmbreeGeometry::BezierCurve;
    e.embree = stored(bezier ? segments * (64 + 4) : points * 16 + segments * 5, 0.8);
  }
  return e;
}

namespace {
// The bounds' diagonal computed in double (a float diagonal of tiny data underflows to 0).
double diagonal_in_double(const Bounds& b) {
  return std::hypot(double(b.max[0]) - double(b.min[0]), double(b.max[1]) - double(b.min[1]),
                    double(b.max[2]) - double(b.min[2]));
}
}  // namespace

void check_geometry_span(const LineSetStats& stats, const BakeOptions& options) {
  // Tubes and Embree's curves are float32 geometry: their frames, normals and distance tests
  // square the distances between points, which underflow for data a trillionth of a unit across
  // (a span of 1e-30 made "no line has two distinct points"). Refused here, naming the input.
  const bool float_geometry = contains(options.assets, "tubes") ||
                              contains(options.assets, "embree") || contains(options.assets, "rtx");
  // In double: the float diagonal of such data is 0 (its square underflows too).
  const double span = diagonal_in_double(stats.bounds);
  if (float_geometry && span == 0)
    throw InputError(options.input, "",
                     "every point of the lines is the same: no extent to build tubes or Embree's "
                     "curves over");
  if (float_geometry && !(span >= double(kMinGeometrySpan))) {
    char text[32];
    std::snprintf(text, sizeof text, "%.3g", span);
    throw InputError(options.input, "",
                     std::string("the lines span ") + text +
                         " units (their bounding box's diagonal): too small for the float32 "
                         "geometry of tubes and Embree's curves, which needs 1e-12 or more; "
                         "scale the lines to smaller units first (voxels alone can be baked)");
  }
}

std::string far_from_origin_note(const LineSetStats& stats) {
  const std::array<float, 3>&lo = stats.bounds.min, &hi = stats.bounds.max;
  double reach = 0;
  for (int k = 0; k < 3; ++k)
    reach = std::max({reach, std::fabs(double(lo[size_t(k)])), std::fabs(double(hi[size_t(k)]))});
  const double span = diagonal_in_double(stats.bounds);
  // float32's spacing at the largest coordinate: half an ulp is the most a position is off.
  const double step = reach > 0 ? std::ldexp(1.0, std::ilogb(reach) - 23) : 0;
  if (!(span > 0) || step <= span * 1e-4) return "";
  char text[256];
  std::snprintf(text, sizeof text,
                "coordinates reach %.3g over an extent of %.3g: float32 positions (the line "
                "set's, the tubes', every renderer's) fall on steps of %.3g there, %.2g %% of the "
                "extent; moved nearer the origin, the lines keep their detail",
                reach, span, step, 100 * step / span);
  return text;
}

void check_free_space(const BakeResult& result, uint64_t already_written,
                      const BakeOptions& options) {
  const uint64_t needed =
      result.estimate.total() - std::min(already_written, result.estimate.total());
  if (!options.space_check || needed <= result.free_bytes) return;
  const std::filesystem::path dir = std::filesystem::path(result.cache).has_parent_path()
                                        ? std::filesystem::path(result.cache).parent_path()
                                        : std::filesystem::path(".");
  throw OutputError(result.cache,
                    "needs about " + format_bytes(needed) + " more (the cache about " +
                        format_bytes(result.estimate.total() - result.estimate.spill) +
                        ", temporary spill files about " + format_bytes(result.estimate.spill) +
                        "), " + format_bytes(result.free_bytes) + " free on " + dir.string() +
                        "; --no-space-check bakes anyway");
}

BakeResult bake(const BakeOptions& options_in) {
  const auto bake_start = std::chrono::steady_clock::now();
  BakeOptions options = options_in;
  for (const std::string& asset : options.assets)
    if (!contains(bakeable_assets(), asset))
      throw UsageError("unknown asset '" + asset + "' (bake builds: tubes, voxels, embree, rtx)");
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
  if (contains(options.assets, "rtx")) {
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
  if (options.inputs.empty()) options.inputs = {options.input};
  const std::vector<std::string>& inputs = options.inputs;
  if (inputs.size() > 1) {
    if (options.input.empty())
      options.input = inputs.front() + " and " + std::to_string(inputs.size() - 1) + " more";
    if (options.cache.empty())
      throw UsageError("several inputs make one line set: name its cache with -o");
  }
  BakeResult result;
  // A cache is a line source too: baking it without -o (or into itself) adds assets to it.
  const bool input_is_cache = inputs.size() == 1 && !synth::is_synth_source(options.input) &&
                              is_linebake_cache(options.input);
  result.cache = bake_output_path(options);
  options.cache = result.cache;
  std::error_code same_error;
  const bool in_place =
      input_is_cache && std::filesystem::equivalent(options.input, result.cache, same_error);
  // The new cache replaces the path given: through a symbolic or hard link that would leave the
  // linked file as it was.
  if (in_place && (std::filesystem::is_symlink(result.cache) ||
                   std::filesystem::hard_link_count(result.cache, same_error) > 1))
    throw OutputError(result.cache,
                      "is a link; bake the cache under its own path to add assets in place");
  if (in_place && !options.origin.empty())
    throw UsageError(
        "--origin: a cache baked in place keeps its lines and their origin; bake the "
        "lines' source file (or -o another cache) to place them at another origin");
  const uint64_t budget_bytes =
      options.memory_budget == BakeOptions::kDefaultBudget ? default_memory_budget()
      : options.memory_budget == BakeOptions::kUnlimited   ? 0
                                                           : options.memory_budget;
  MemoryBudget budget(budget_bytes);
  result.memory_budget_bytes = budget_bytes;

  // The output never replaces the input, and replaces a file that is not a linebake cache only
  // under --force; a damaged cache is rebuilt.
  if (!synth::is_synth_source(options.input) && !in_place)
    refuse_input_as_output(result.cache, inputs);
  // Another bake into this path between reading the old cache and renaming the new one would
  // have its assets dropped by this one's rename (or drop this one's).
  std::optional<OutputLock> one_writer;
  if (!options.dry_run) one_writer.emplace(result.cache);
  std::unique_ptr<CacheReader> old;
  std::error_code absent;
  if (std::filesystem::exists(result.cache, absent)) {
    if (!options.force && !is_linebake_cache(result.cache))
      throw OutputError(result.cache, "exists and is not a linebake cache; --force replaces it");
    try {
      old = std::make_unique<CacheReader>(result.cache);
    } catch (const InputError& e) {
      result.notes.push_back(std::string("existing cache not usable, rebuilding: ") + e.what());
    }
  }
  remove_stale_temporaries(result.cache);
  const auto old_provenance = [&](const std::string& group) -> std::optional<Provenance> {
    return old ? old->provenance(group) : std::nullopt;
  };

  // Which steps run: the lines when their key changed, an asset when its key did.
  BakeStep lines_step{"lines", false, {}};
  const auto old_lines = old_provenance("/lines");
  if (!options.compression_given && old_lines) {
    try {
      options.compression = parse_compression(old_lines->compression);
      options.compression_level = old_lines->compression_level;
    } catch (const Error&) {
      // A codec this build does not name: the option's default, as before.
    }
  }
  // In place the lines keep the identity of what they were first read from: the cache is not
  // their source, and hashing it would read the whole file for a key nobody compares.
  const bool keep_identity = in_place && old_lines.has_value();
  const LinesIdentity identity =
      keep_identity ? LinesIdentity{old_lines->input_hash, old_lines->key,
                                    old_lines->parameters.value("format", "auto"),
                                    old_lines->parameters.value("on_invalid", "repair"),
                                    old_lines->parameters.value("origin", "")}
                    : lines_identity(options);
  const std::string& source = identity.source_hash;
  const std::string& format = identity.format;
  const std::string& policy = identity.policy;
  const std::string& lines_key = identity.key;
  // In place, the cache's /lines are the input; --compression applies to /lines as well.
  const bool reuse_lines = !options.force && old_lines && old_lines->key == lines_key &&
                           old_lines->compression == to_string(options.compression) &&
                           old_lines->stats.contains("bounds");
  lines_step.built = !reuse_lines;
  if (reuse_lines) lines_step.provenance = *old_lines;

  // Reading: the input once (into the spool), or the old cache's /lines.
  std::optional<LineSpool> spool;
  LineSet header;
  LineSetStats stats;
  std::string lines_hash;
  StepClock lines_clock{"lines"};
  const uint64_t chunks_in_flight = reserve_bake_fixed_buffers(budget);
  std::unique_ptr<LineReader> input;
  uint64_t batch_points = uint64_t{1} << 21;
  const auto plan_batches = [&](const LineSet& h) {
    const uint64_t per_point =
        cost_per_point(options, h, contains(options.assets, "tubes"),
                       contains(options.assets, "voxels"), contains(options.assets, "embree"));
    if (!budget.unlimited()) {
      batch_points =
          std::clamp<uint64_t>(budget.available() / 4 / per_point, 1024, uint64_t{1} << 21);
      budget.reserve(batch_points * per_point,
                     "one batch of " + std::to_string(batch_points) + " points through every step");
    }
    result.batch_points = batch_points;
    return per_point;
  };

  if (!reuse_lines) {
    Stage stage(result, "read", {&lines_clock});
    lines_clock.run([&] {
      TerminalProgress progress("reading " + options.input);
      ReadOptions read;
      read.format = options.format;
      if (!budget.unlimited()) read.memory_limit = budget.available();
      read.origin = resolve_origin(options.origin, inputs, read);
      if (options.progress) read.progress = progress.callback();
      input = open_line_reader(inputs, read);
      ValidationReport total;
      std::optional<LineSet> whole;
      if (!input->streams()) {
        // A format that cannot stream is in memory whole already: repair it whole (attribute
        // arrays of the wrong length are dropped before any batch is cut), then serve batches.
        whole = input->take_whole();
        const uint64_t bytes = line_set_bytes(*whole);
        if (!budget.unlimited() && bytes > budget.available() / 2)
          throw BudgetExceeded(options.input + ": this format is read whole; its " +
                               std::to_string(whole->point_count()) + " points take " +
                               format_bytes(bytes) + ", more than half of what --memory-budget " +
                               format_bytes(budget.total()) +
                               " leaves; convert it to .binlines or .h5, which stream");
        total = validate(*whole, options.on_invalid, options.input);
        input = MemoryLineReader::view(*whole);
      }
      header = header_of(input->header());
      check_attribute_options(options, header);
      const std::string recorded = options.source_name.value_or(options.input);
      if (!synth::is_synth_source(options.input) && !keep_identity && !recorded.empty())
        header.metadata.emplace("source", recorded);
      const uint64_t per_point = plan_batches(header);
      LineStatsBuilder builder(header);
      LineContentHash hash(header);
      if (!options.dry_run) spool.emplace(result.cache, header);
      LineSet batch;
      uint64_t line_base = 0;
      while (input->next(batch, batch_points)) {
        throw_if_interrupted();
        // A batch's lines are named in their file where they come from several (as
        // linebake-mpi names them).
        const std::string file = input->batch_file();
        const std::string batch_source = file.empty() ? options.input : file;
        const uint64_t first = file.empty() ? line_base : input->batch_file_line();
        if (!whole) {
          const std::string where = batch_source + " (lines " + std::to_string(first) + ".." +
                                    std::to_string(first + batch.line_count() - 1) + ")";
          total.add(validate(batch, options.on_invalid, where, first));
        }
        line_base += batch.line_count();
        for (size_t l = 0; l < batch.line_count(); ++l)
          check_line_fits_batch(budget, batch.line_size(l), per_point, batch_source, first + l);
        builder.add(batch);
        hash.add(batch);
        if (spool) spool->append(batch);
      }
      const std::map<std::string, uint64_t> counts = input->counts_read();
      add_counts_read(header.metadata, counts);
      if (const std::string note = counts_read_note(counts); !note.empty())
        result.notes.push_back(options.input + ": " + note);
      input.reset();
      whole.reset();
      stats = builder.stats();
      if (stats.lines == 0)
        throw InputError(options.input, "",
                         std::string(total.clean() ? "has no lines"
                                                   : "has no line left once repaired (" +
                                                         total.summary() + ")") +
                             ": nothing to bake (an empty line set reads and converts, but a "
                             "cache holds lines); no cache written");
      if (!total.clean()) result.notes.push_back(options.input + ": " + total.summary());
      lines_hash = hash.hex();
      result.spill_peak_bytes = spool ? spool->bytes() : 0;
    });
  } else {
    header = header_of(open_line_reader(result.cache)->header());
    check_attribute_options(options, header);
    stats = line_stats_from_json(old_lines->stats, result.cache);
    lines_hash = old_lines->stats.value("content_hash", "");
    plan_batches(header);
  }
  check_geometry_span(stats, options);
  if (const std::string note = far_from_origin_note(stats); !note.empty())
    result.notes.push_back(options.input + ": " + note);
  // What the bake will write, against the room on the cache's file system: refused here, before
  // any of it, unless the user says otherwise.
  result.estimate = estimate_bake(stats, header, options, budget.available());
  if (!reuse_lines && spool)
    result.estimate.spill = std::max(result.estimate.spill, spool->bytes());
  result.free_bytes = free_bytes_for(result.cache);
  if (options.dry_run) {
    result.wall_s = seconds_since(bake_start);
    return result;
  }
  check_free_space(result, spool ? spool->bytes() : 0, options);  // the lines' spill is written
  // Replays the line set: from the spool, or the old cache's /lines.
  const auto replay = [&]() -> std::unique_ptr<LineReader> {
    if (spool) return spool->replay();
    return open_line_reader(result.cache);
  };

  // Assets: reuse on an equal key, else build.
  const std::string tubes_step_key =
      tubes_key(lines_hash, options.tubes, options.compression, options.compression_level);
  std::vector<BakeStep> asset_steps;
  for (const std::string& asset : options.assets) {
    BakeStep step{asset, false, {}};
    std::string key =
        asset == "tubes" ? tubes_step_key
        : asset == "voxels"
            ? voxels_key(lines_hash, options.voxels, options.compression, options.compression_level)
            : embree_key(lines_hash, options.embree, options.tubes, options.compression,
                         options.compression_level);
    if (asset == "rtx") {
      const vk::DeviceInfo& device = rt_context->info();
      key = key_of({"rtx", std::to_string(kRtxVersion), tubes_step_key,
                    json_text(to_json(options.rtx)), device.name, vk::to_hex(device.driver_uuid),
                    to_string(options.compression), std::to_string(options.compression_level)});
    }
    const auto previous = old_provenance("/assets/" + asset);
    if (!options.force && previous && previous->key == key) {
      step.provenance = *previous;
    } else {
      step.built = true;
      step.provenance.key = key;
    }
    asset_steps.push_back(std::move(step));
  }
  const auto building = [&](const std::string& asset) {
    for (const BakeStep& s : asset_steps)
      if (s.step == asset) return s.built;
    return false;
  };
  bool anything_built = lines_step.built;
  for (const BakeStep& s : asset_steps) anything_built |= s.built;
  // Assets in the old cache that were not asked for this time are kept if still valid for
  // these lines.
  std::vector<std::string> kept;
  if (old) {
    for (const std::string& name : old->assets()) {
      if (contains(options.assets, name)) continue;
      const auto p = old->provenance("/assets/" + name);
      if (p && p->input_hash == lines_hash)
        kept.push_back(name);
      else
        result.notes.push_back("dropped the cache's " + name + ": " +
                               (p ? "it was built from other lines"
                                  : "it has no provenance, so nothing says which lines it is of") +
                               " (--assets " + name + " rebuilds it)");
    }
  }
  if (!anything_built) {
    result.steps.push_back(std::move(lines_step));
    for (BakeStep& s : asset_steps) result.steps.push_back(std::move(s));
    result.wall_s = seconds_since(bake_start);
    return result;
  }

  BudgetPlan plan;
  plan.batch_points = batch_points;

  const auto finish_provenance = [&](Provenance& p, const std::string& step,
                                     const StepClock& clock) {
    p.build = clock.figures();
    p.step = step;
    p.created = utc_now_iso8601();
    p.threads = threads();
    p.compression = to_string(options.compression);
    p.compression_level = options.compression_level;
    p.memory_budget = budget_bytes;
    p.estimated_disk_bytes = result.estimate.step(step);
  };

  CacheWriter writer(result.cache, options.compression, options.compression_level);
  writer.limit_chunks_in_flight(chunks_in_flight);
  // Tubes and Embree parts need the whole set's line sizes before their datasets exist: a
  // first pass writes /lines and makes those plans.
  std::optional<TubeStreamBuilder> tubes;
  std::optional<CurvePartPlanner> embree_parts;
  StepClock tubes_clock{"tubes"}, voxels_clock{"voxels"}, embree_clock{"embree"};
  StoredCurves curves;  // the Embree step's description
  if (building("tubes")) tubes.emplace(header, stats, options.tubes);
  if (building("embree")) {
    curves = embree_curves(options, header, stats);
    embree_parts.emplace(curve_part_limit(options.embree));
  }
  if (lines_step.built || tubes || embree_parts) {
    // The plans made here (8 bytes a line) stay through the build pass, whose peak the tubes and
    // Embree steps get; this pass's is the lines'.
    Stage stage(result, "lines", {&lines_clock});
    TerminalProgress progress(lines_step.built ? "writing /lines" : "planning");
    std::optional<LineStoreWriter> store;
    if (lines_step.built) store.emplace(writer, header, stats);
    std::unique_ptr<LineReader> reader = replay();
    LineSet batch;
    while (reader->next(batch, batch_points)) {
      throw_if_interrupted();
      if (store) lines_clock.run([&] { store->append(batch); });
      if (tubes) tubes_clock.run([&] { tubes->plan(batch); });
      if (embree_parts)
        embree_clock.run([&] {
          for (size_t l = 0; l < batch.line_count(); ++l) embree_parts->add(batch.line_size(l));
        });
      if (options.progress) progress.update(reader->lines_read(), stats.lines);
    }
    if (store) {
      Provenance& p = lines_step.provenance;
      finish_provenance(p, "lines", lines_clock);
      p.key = lines_key;
      p.input_hash = source;
      if (keep_identity) {
        p.parameters = old_lines->parameters;
      } else {
        p.parameters = {{"source", options.source_name.value_or(options.input)},
                        {"format", format},
                        {"on_invalid", policy}};
        if (!identity.origin.empty()) p.parameters["origin"] = identity.origin;
        if (inputs.size() > 1) p.parameters["files"] = inputs;
      }
      p.stats = to_json(stats);
      p.stats["content_hash"] = lines_hash;
      p.spill_bytes = spool ? spool->bytes() : 0;
      store->close(header.metadata, p);
    }
  }
  if (!lines_step.built) writer.copy_group(result.cache, "/lines");
  for (const BakeStep& s : asset_steps)
    if (!s.built) writer.copy_group(result.cache, "/assets/" + s.step);

  // The build pass: every asset from the same batches.
  std::optional<TubeStoreSink> tube_sink;
  std::optional<VoxelStreamBuilder> voxels;
  std::optional<EmbreeStoreWriter> embree_writer;
  if (tubes) {
    tubes_clock.run([&] {
      tubes->finish_plan();
      tube_sink.emplace(writer, tubes->description());
    });
  }
  if (tubes && !budget.unlimited())
    budget.reserve(stats.lines * sizeof(uint64_t), "the tube plan (8 bytes per line)");
  std::optional<VoxelGrid> voxel_placement;
  if (building("voxels")) {
    // The grid's placement first: its density mip levels stay in memory through the merge.
    const VoxelStreamBuilder placement(header, stats, options.voxels);
    voxel_placement = placement.description();
    if (!budget.unlimited())
      budget.reserve(placement.fixed_bytes(),
                     "the voxel grid's chord counts and density mip levels (" +
                         std::to_string(voxel_placement->voxel_count()) + " voxels)");
    // And every batch's run index, kept to the merge: about 16 KiB a batch, which small
    // budgets' small batches multiply (turbulence at scale 1.0 under 60M: about 1,630 batches,
    // 26 MB, which took the bake to 84 MiB before it was counted). The spool replays the read's
    // batches as they were cut (one file's last batch is never joined to the next file's, and
    // repair drops points after the cut): their count; a cache's /lines fills every batch.
    if (!budget.unlimited()) {
      const uint64_t batches =
          spool ? spool->batches()
                : most_batches(stats.points, stats.lines, result.batch_points, stats.largest_line);
      budget.reserve(batches * placement.run_index_bytes(),
                     "the voxel walk's index of " + std::to_string(batches) + " batches of " +
                         std::to_string(result.batch_points) + " points");
    }
  }
  // The budget's shares, for what follows the batches: the voxel records held before they
  // spill, and one voxel range's merge.
  if (budget.unlimited()) {
    plan.voxel_records = UINT64_MAX;
    plan.voxel_merge = uint64_t{1} << 30;
  } else {
    const VoxelMemory shares = voxel_memory_within(budget.available());
    plan.voxel_merge = shares.merge_bytes;
    plan.voxel_records = shares.records_bytes;
  }

  if (voxel_placement) {
    VoxelMemory memory;
    memory.spill_near = result.cache;
    memory.records_bytes = plan.voxel_records;
    memory.merge_bytes = plan.voxel_merge;
    // Records held in memory leave a batch's room below the budget, whatever the shares miss:
    // tubes and voxels built side by side took 221 MiB under 200M (convection at scale 2).
    if (!budget.unlimited()) {
      const uint64_t batch_bytes =
          result.batch_points *
          cost_per_point(options, header, tubes.has_value(), true, embree_parts.has_value());
      memory.resident_limit = budget.total() > batch_bytes ? budget.total() - batch_bytes : 1;
    }
    voxels_clock.run([&] { voxels.emplace(header, stats, options.voxels, memory); });
  }
  if (embree_parts)
    embree_clock.run([&] {
      embree_writer.emplace(writer, embree_parts->finish(), curves.geometry, curves.radius,
                            curves.attribute);
    });
  if (tubes || voxels || embree_writer) {
    Stage stage(result, "build", {&tubes_clock, &voxels_clock, &embree_clock});
    std::string what;
    for (const char* name : {"tubes", "voxels", "embree"})
      if (building(name)) what += std::string(what.empty() ? "" : ", ") + name;
    TerminalProgress progress("building " + what);
    std::unique_ptr<LineReader> reader = replay();
    LineSet batch;
    while (reader->next(batch, batch_points)) {
      throw_if_interrupted();
      // Tubes and voxels side by side: their serial parts (HDF5's writes, the voxel spill's)
      // overlap the other's parallel work. Only one of them calls HDF5, as HDF5 requires.
      const auto build_tubes_batch = [&] {
        tubes_clock.run([&] { tubes->build(batch, *tube_sink); });
      };
      const auto build_voxels_batch = [&] { voxels_clock.run([&] { voxels->add(batch); }); };
      if (tubes && voxels)
        tbb::parallel_invoke(build_tubes_batch, build_voxels_batch);
      else if (tubes)
        build_tubes_batch();
      else if (voxels)
        build_voxels_batch();
      if (embree_writer) embree_clock.run([&] { embree_writer->append(batch); });
      if (options.progress) progress.update(reader->lines_read(), stats.lines);
    }
  }
  if (tubes) {
    BakeStep& step = *std::find_if(asset_steps.begin(), asset_steps.end(),
                                   [](const BakeStep& s) { return s.step == "tubes"; });
    Provenance& p = step.provenance;
    const TubeMesh& mesh = tubes->description();
    finish_provenance(p, "tubes", tubes_clock);
    p.input_hash = lines_hash;
    p.parameters = to_json(options.tubes);
    p.stats = tube_stats(mesh, tubes->finish_plan());
    tube_sink->close(mesh, p);
    tube_sink.reset();  // its staging buffers go before the voxel merge
    if (mesh.lines_dropped)
      result.notes.push_back("tubes: " + std::to_string(mesh.lines_dropped) +
                             " lines with fewer than two distinct points have no tube");
  }
  if (voxels) {
    Stage stage(result, "voxel merge", {&voxels_clock});
    TerminalProgress progress("merging voxels");
    VoxelStoreSink sink(writer);
    voxels_clock.run(
        [&] { voxels->finish(sink, options.progress ? progress.callback() : ProgressFn{}); });
    BakeStep& step = *std::find_if(asset_steps.begin(), asset_steps.end(),
                                   [](const BakeStep& s) { return s.step == "voxels"; });
    Provenance& p = step.provenance;
    const VoxelGrid& g = voxels->description();
    finish_provenance(p, "voxels", voxels_clock);
    p.input_hash = lines_hash;
    p.parameters = to_json(options.voxels);
    p.spill_bytes = voxels->spilled_bytes();
    p.stats = voxel_stats(g, sink.chord_count(), sink.memory_with_density(),
                          voxels->peak_record_bytes(), voxels->spilled_bytes());
    result.spill_peak_bytes = std::max(result.spill_peak_bytes, voxels->spilled_bytes());
    sink.close(p);
    if (g.chords_dropped) result.notes.push_back(dropped_chords_note(g));
    voxels.reset();
  }
  if (embree_writer) {
    BakeStep& step = *std::find_if(asset_steps.begin(), asset_steps.end(),
                                   [](const BakeStep& s) { return s.step == "embree"; });
    Provenance& p = step.provenance;
    finish_provenance(p, "embree", embree_clock);
    p.input_hash = lines_hash;
    p.parameters = to_json(options.embree, options.tubes);
    p.stats = embree_stats(options.embree, curves, embree_clock.wall_s, *embree_writer);
    p.memory_bytes = embree_writer->buffer_bytes();
    // The BVH is built and measured where it fits the budget: the line set, the buffers and
    // Embree's BVH (about the buffers' size again for linear curves) in memory at once. The
    // estimate decides whether to try; Embree's memory monitor holds the build to what the
    // budget leaves beside the line set, so an estimate that errs low costs the BVH, not the
    // budget.
    const uint64_t needed = stats.total_bytes() + 3 * embree_writer->buffer_bytes();
    std::string not_built;
    if (budget.unlimited() || needed <= budget.available()) {
      Stage stage(result, "embree bvh", {&embree_clock});
      const LineSet whole = read_all(*replay());
      EmbreeOptions embree = options.embree;
      if (!budget.unlimited())
        embree.max_memory_bytes = std::max<uint64_t>(budget.available() - stats.total_bytes(), 1);
      try {
        const EmbreeScene scene =
            EmbreeScene::from_lines(whole, curves.radius, curves.attribute, embree);
        const BvhStats& b = scene.stats();
        p.stats["primitives"] = b.primitives;
        p.stats["parts"] = b.parts;
        p.stats["instanced"] = b.instanced;
        p.stats["commit_s"] = b.commit_s;
        p.stats["bvh_bytes"] = b.bvh_bytes;
        p.stats["bvh_peak_bytes"] = b.bvh_peak_bytes;
        // What ray tracing needs resident: the prepared buffers and the BVH.
        p.memory_bytes = b.buffer_bytes + b.bvh_bytes;
      } catch (const BudgetExceeded& e) {
        not_built = "not built at bake: " + std::string(e.what()) + "; render builds it";
      }
    } else {
      not_built = "not built at bake: the line set, buffers and BVH need about " +
                  format_bytes(needed) + ", the memory budget leaves " +
                  format_bytes(budget.available()) + "; render builds it";
    }
    if (!not_built.empty()) {
      p.stats["bvh"] = not_built;
      result.notes.push_back("embree: " + not_built);
    }
    embree_writer->close(p);
  }
  // Ray tracing, last: its BLAS are built over the tubes just written (or copied), or over
  // capsules of the whole line set.
  if (building("rtx")) {
    BakeStep& step = *std::find_if(asset_steps.begin(), asset_steps.end(),
                                   [](const BakeStep& s) { return s.step == "rtx"; });
    Provenance& p = step.provenance;
    StepClock rtx_clock{"rtx"};
    StoredRtx rtx;
    Stage stage(result, "rtx", {&rtx_clock});
    rtx_clock.run([&] {
      const auto whole_lines = [&] { return read_all(*replay()); };
      const auto tube_mesh = [&]() -> std::optional<TubeMesh> {
        if (!building("tubes")) {
          const auto previous = old_provenance("/assets/tubes");
          if (!previous || previous->key != tubes_step_key) return std::nullopt;
          if (!writer.has_group("/assets/tubes")) writer.copy_group(result.cache, "/assets/tubes");
        }
        writer.flush();
        return load_tubes(CacheReader(writer.temp_path(), false));
      };
      try {
        build_rtx_step(*rt_context, options, budget, whole_lines, tube_mesh, lines_hash,
                       tubes_step_key, rtx, p);
      } catch (const vk::HostBudgetExceeded& e) {
        throw BudgetExceeded("rtx: " + std::string(e.what()) + "; raise --memory-budget");
      }
    });
    const nlohmann::json figures = p.stats;
    const uint64_t resident = p.memory_bytes;
    finish_provenance(p, "rtx", rtx_clock);
    p.stats = figures;
    p.memory_bytes = resident;
    p.input_hash = lines_hash;
    p.parameters = to_json(options.rtx);
    store_rtx(writer, rtx, p);
  }
  spool.reset();
  // Assets that did not change, and kept ones, as stored.
  for (const BakeStep& s : asset_steps)
    if (!s.built && !writer.has_group("/assets/" + s.step))
      writer.copy_group(result.cache, "/assets/" + s.step);
  for (const std::string& name : kept)
    if (!writer.has_group("/assets/" + name)) writer.copy_group(result.cache, "/assets/" + name);
  old.reset();
  {
    Stage stage(result, "commit", {});
    writer.commit();
  }
  result.written = true;
  // Read back what was stored, so the report shows the stored figures (disk bytes). Opening the
  // cache runs its probe in a child process, which a signal can cut short: the cache is whole by
  // then, and the message says so.
  try {
    CacheReader stored(result.cache, false);
    if (auto p = stored.provenance("/lines")) lines_step.provenance = *p;
    for (BakeStep& s : asset_steps)
      if (auto p = stored.provenance("/assets/" + s.step)) s.provenance = *p;
  } catch (const Interrupted& e) {
    throw Interrupted(e.signal(), "after " + result.cache +
                                      " was written whole (reading its figures back for the "
                                      "report was cut short)");
  }
  result.steps.push_back(std::move(lines_step));
  for (BakeStep& s : asset_steps) result.steps.push_back(std::move(s));
  for (const BakeStage& stage : result.stages)
    result.peak_rss_bytes = std::max(result.peak_rss_bytes, stage.peak_rss_bytes);
  struct stat st {};
  if (::stat(result.cache.c_str(), &st) == 0) result.bytes_written = uint64_t(st.st_size);
  result.wall_s = seconds_since(bake_start);
  return result;
}

}  // namespace linebake
