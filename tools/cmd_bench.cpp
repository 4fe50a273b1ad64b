// linebake bench <step>: speed of a build step against the machine's own memory bandwidth,
// measured in the same run, or of the rendering techniques (bench render, bench_render.cpp).
// Targets are checked and printed, never asserted in tests.

#include <hdf5.h>
#include <tbb/global_control.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>

#ifdef __GLIBC__
#include <malloc.h>
#endif

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>

#include "accel/capsule_chain.hpp"
#include "accel/embree_scene.hpp"
#include "bench_isolation.hpp"
#include "bench_render.hpp"
#include "bench_shaders.hpp"
#include "cache/line_store.hpp"
#include "cli_contract.hpp"
#include "commands.hpp"
#include "core/array.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/interrupt.hpp"
#include "core/json_file.hpp"
#include "core/measure.hpp"
#include "core/memory_budget.hpp"
#include "core/output_lock.hpp"
#include "core/progress.hpp"
#include "flight_plan.hpp"
#include "formats/registry.hpp"
#include "lines/line_reader.hpp"
#include "pipeline/bake.hpp"
#include "pipeline/bake_budget.hpp"
#include "synth/synth.hpp"
#include "tubes/tube_builder.hpp"
#include "voxels/voxelizer.hpp"
#include "whole_output.hpp"

namespace linebake::cli {
namespace {

// Best-of-n memcpy bandwidth (bytes written per second) over pre-touched buffers (1 GiB unless
// told), with the copy split over all threads like the builders split their work.
double memcpy_bandwidth(int repeats, size_t bytes = size_t{1} << 30) {
  Array<unsigned char> src(bytes), dst(bytes);
  std::memset(src.data(), 1, bytes);
  std::memset(dst.data(), 0, bytes);
  double best = 1e30;
  const size_t parts = 64;
  for (int r = 0; r < repeats; ++r) {
    const auto start = std::chrono::steady_clock::now();
    tbb::parallel_for(size_t{0}, parts, [&](size_t p) {
      const size_t begin = bytes * p / parts, end = bytes * (p + 1) / parts;
      std::memcpy(dst.data() + begin, src.data() + begin, end - begin);
    });
    best = std::min(best, seconds_since(start));
  }
  return double(bytes) / best;
}

struct BenchArgs {
  std::string input, grid = "auto", geometry = "linear", quality = "medium";
  int sides = 3, repeat = 3, threads = 0;
  uint32_t quantization = 32;
  bool json = false;
  // bake
  std::vector<std::string> assets{"tubes"};
  std::string memory_budget, compression = "lz4", output;
  bool keep = false;
};

// The build steps' memory budget (--memory-budget: half of physical memory by default; 0:
// unlimited, as for convert and export), with what the process holds now counted as used (its
// free heap given back first: what a step before let go would count otherwise).
MemoryBudget step_budget(const BenchArgs& args) {
  trimmed_rss_bytes();
  return MemoryBudget(memory_budget_bytes(args.memory_budget));
}

[[noreturn]] void refuse(const std::string& step, const std::string& what, uint64_t bytes,
                         const MemoryBudget& budget) {
  throw BudgetExceeded("bench " + step + ": " + what + ": about " + format_bytes(bytes) +
                       " in memory, more than the memory budget of " +
                       format_bytes(budget.total()) + " leaves (" +
                       format_bytes(budget.available()) + "); raise --memory-budget");
}

// The whole line set, as the builders take it, within the budget (read_line_set with
// ReadOptions::memory_limit: a format read whole checks its own arrays; the others are gathered
// in batches, refused where the lines and their arrays' growth would not fit, or at a line that
// alone would not).
LineSet load(const std::string& step, const BenchArgs& args, const MemoryBudget& budget) {
  TerminalProgress progress("loading " + args.input);
  ReadOptions read;
  read.progress = progress.callback();
  if (!budget.unlimited()) read.memory_limit = budget.available();
  try {
    return read_line_set(args.input, read);
  } catch (const BudgetExceeded& e) {
    throw BudgetExceeded("bench " + step + ": " + e.what());
  }
}

// Keeps a streamed voxel build's figures, not its arrays: what the grid would hold.
class VoxelFigures : public VoxelSink {
 public:
  VoxelGrid grid;  // placement and statistics, no arrays
  uint64_t chords = 0, coarse_density_bytes = 0;
  void begin(const VoxelGrid& g, uint64_t chord_count) override {
    grid = g;
    chords = chord_count;
  }
  void voxels(uint64_t, uint64_t, const uint32_t*, const uint8_t*, const float*, const uint32_t*,
              uint64_t) override {}
  void end(const VoxelGrid& g, uint32_t, std::vector<Array<float>> coarse) override {
    grid = g;
    for (const Array<float>& level : coarse) coarse_density_bytes += level.bytes();
  }
  // VoxelGrid::representation_bytes() and bytes() of the grid built whole.
  uint64_t representation_bytes() const { return (grid.voxel_count() + 1) * 4 + chords * 8; }
  uint64_t bytes() const {
    return representation_bytes() + grid.voxel_count() * (1 + 4) + coarse_density_bytes;
  }
};

// The voxel grid build as bake runs it: the chord records held within what the budget leaves
// (spilled to an unlinked file in the working directory past it), the grid streamed out voxel
// range by voxel range and not kept. Every run, best and median, chords/s, the representation's
// memory.
void bench_voxels(const BenchArgs& args) {
  MemoryBudget budget = step_budget(args);
  const LineSet lines = load("voxels", args, budget);
  budget = step_budget(args);  // the lines counted as held
  VoxelOptions options;
  parse_grid(args.grid, options);
  options.quantization = args.quantization;
  const LineSetStats stats = compute_stats(lines);
  VoxelMemory memory;
  uint64_t batch_points = lines.point_count();
  if (!budget.unlimited()) {
    const VoxelStreamBuilder placement(lines, stats, options);
    if (placement.fixed_bytes() >= budget.available())
      refuse("voxels",
             "the voxel grid's chord counts and density mip levels (" +
                 std::to_string(placement.description().voxel_count()) + " voxels)",
             placement.fixed_bytes(), budget);
    budget.reserve(placement.fixed_bytes(), "the voxel grid's chord counts");
    // The lines go through the walk in batches, as bake's: a batch's records are made before
    // they can spill (bake's share of the budget for one).
    const uint64_t per_point = cost_per_point(BakeOptions{}, lines, false, true, false);
    batch_points =
        std::clamp<uint64_t>(budget.available() / 4 / per_point, 1024, uint64_t{1} << 21);
    budget.reserve(batch_points * per_point,
                   "one batch of " + std::to_string(batch_points) + " points");
    // Each batch's run of records keeps its index to the merge, as bake's (which counts it the
    // same way): the reader below fills every batch.
    const uint64_t runs = most_batches(stats.points, stats.lines, batch_points, stats.largest_line);
    budget.reserve(runs * placement.run_index_bytes(),
                   "the indexes of up to " + std::to_string(runs) + " runs of voxel records");
    memory = voxel_memory_within(budget.available());
    // Beside the working directory's absolute path where it has one, so that an error names it.
    std::error_code ec;
    const std::filesystem::path here = std::filesystem::current_path(ec);
    memory.spill_near = ec ? "bench-voxels" : (here / "bench-voxels").string();
    memory.resident_limit = budget.total() - batch_points * per_point;
  }
  std::vector<double> times;
  VoxelFigures grid;
  uint64_t peak = 0, spilled = 0;
  for (int r = 0; r < args.repeat; ++r) {
    grid = VoxelFigures();
    StepMeter meter;
    VoxelStreamBuilder builder(lines, stats, options, memory);
    if (batch_points >= lines.point_count()) {
      builder.add(lines);  // one batch: the lines as they are, not a copy
    } else {
      const std::unique_ptr<MemoryLineReader> reader = MemoryLineReader::view(lines);
      for (LineSet batch; reader->next(batch, batch_points);) builder.add(batch);
    }
    builder.finish(grid);
    const StepFigures f = meter.stop();
    times.push_back(f.wall_s);
    peak = std::max(peak, f.peak_rss);
    spilled = builder.spilled_bytes();
  }
  std::sort(times.begin(), times.end());
  const double best = times.front(), median_s = median(times);
  const size_t threads =
      tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
  const nlohmann::json out = {{"step", "voxels"},
                              {"input", args.input},
                              {"threads", threads},
                              {"segments", lines.segment_count()},
                              {"resolution", grid.grid.resolution},
                              {"quantization", grid.grid.quantization},
                              {"chords", grid.chords},
                              {"runs_s", times},
                              {"best_s", best},
                              {"median_s", median_s},
                              {"segments_per_s", double(lines.segment_count()) / best},
                              {"representation_bytes", grid.representation_bytes()},
                              {"bytes_with_density", grid.bytes()},
                              {"max_error_voxels", grid.grid.max_error},
                              {"mean_error_voxels", grid.grid.mean_error},
                              {"spilled_bytes", spilled},
                              {"memory_budget_bytes", budget.total()},
                              {"peak_rss_bytes", peak}};
  if (args.json) {
    std::cout << json_text(out, 2) << "\n";
    return;
  }
  std::cout << std::fixed << std::setprecision(3) << "voxels: " << args.input << ", "
            << lines.segment_count() << " segments, grid " << grid.grid.resolution[0] << "x"
            << grid.grid.resolution[1] << "x" << grid.grid.resolution[2] << " Q"
            << grid.grid.quantization << ", " << threads << " threads\n  runs (s):        ";
  for (double t : times) std::cout << t << " ";
  std::cout << "\n  best:            " << best << " s, median " << median_s << " s\n"
            << "  chords:          " << grid.chords << "\n"
            << "  representation:  " << std::setprecision(1)
            << double(grid.representation_bytes()) / (1 << 20) << " MiB (offsets + chords), "
            << double(grid.bytes()) / (1 << 20) << " MiB with density mips and line counts\n"
            << "  error (voxels):  max " << std::setprecision(4) << grid.grid.max_error << ", mean "
            << grid.grid.mean_error << "\n"
            << "  peak RSS:        " << format_bytes(peak) << " (budget "
            << (budget.unlimited() ? "unlimited" : format_bytes(budget.total())) << "; records "
            << format_bytes(spilled) << " spilled)\n";
}

// The baseline: a fresh device and scene over the already prepared buffers, shared with Embree
// as they are; only rtcCommitScene is timed.
// Embree's allocations against a limit (0: none), as EmbreeScene's memory monitor holds them.
struct BareMonitor {
  int64_t limit = 0;
  std::atomic<int64_t> held{0};
  std::atomic<bool> refused{false};
  // Embree asks before it allocates (post: false) and tells after it frees (negative bytes);
  // an allocation it reports after the fact (post) is counted even where refused.
  static bool monitor(void* user, ssize_t bytes, bool post) {
    auto* m = static_cast<BareMonitor*>(user);
    if (bytes > 0 && m->limit > 0 && (m->refused || m->held.load() + bytes > m->limit)) {
      m->refused = true;
      if (post) m->held += bytes;
      return false;
    }
    m->held += bytes;
    return true;
  }
};

double bare_commit_seconds(const std::vector<PreparedCurves>& parts, EmbreeGeometry geometry,
                           BuildQuality quality, uint64_t max_bvh_bytes) {
  RTCDevice device = rtcNewDevice(nullptr);
  BareMonitor monitor;
  monitor.limit = int64_t(std::min<uint64_t>(max_bvh_bytes, INT64_MAX));
  rtcSetDeviceMemoryMonitorFunction(device, &BareMonitor::monitor, &monitor);
  RTCScene scene = rtcNewScene(device);
  rtcSetSceneBuildQuality(scene, quality == BuildQuality::Low    ? RTC_BUILD_QUALITY_LOW
                                 : quality == BuildQuality::High ? RTC_BUILD_QUALITY_HIGH
                                                                 : RTC_BUILD_QUALITY_MEDIUM);
  std::vector<CapsuleChain> chains(parts.size());
  for (size_t i = 0; i < parts.size(); ++i) {
    const PreparedCurves& p = parts[i];
    RTCGeometry g = nullptr;
    if (geometry == EmbreeGeometry::Capsules) {
      g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_USER);
      chains[i] = {p.vertices.data(), p.indices.data(), p.flags.data()};
      set_capsule_geometry(g, &chains[i], uint32_t(p.indices.size()));
    } else {
      const bool linear = geometry == EmbreeGeometry::LinearCurve;
      g = rtcNewGeometry(device, linear ? RTC_GEOMETRY_TYPE_ROUND_LINEAR_CURVE
                                        : RTC_GEOMETRY_TYPE_ROUND_BEZIER_CURVE);
      rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, p.vertices.data(),
                                 0, 16, p.vertices.size() / 4 - 1);
      rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT, p.indices.data(), 0,
                                 4, p.indices.size());
      if (linear)
        rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_FLAGS, 0, RTC_FORMAT_UCHAR, p.flags.data(), 0,
                                   1, p.flags.size());
    }
    rtcCommitGeometry(g);
    rtcAttachGeometry(scene, g);
    rtcReleaseGeometry(g);
  }
  const auto start = std::chrono::steady_clock::now();
  rtcCommitScene(scene);
  const double seconds = seconds_since(start);
  const bool failed = rtcGetDeviceError(device) != RTC_ERROR_NONE;
  rtcReleaseScene(scene);
  rtcReleaseDevice(device);
  if (failed && monitor.refused)
    throw BudgetExceeded("bench: Embree's bare build needs more than the " +
                         format_bytes(max_bvh_bytes) +
                         " the memory budget leaves for its BVH; raise --memory-budget");
  if (failed) throw Error("Embree: the bare build failed");
  return seconds;
}

// linebake's Embree build (buffer preparation + commit) against a bare rtcCommitScene on the
// same buffers, runs interleaved; the target is a ratio of best times of at most 1.2.
// Within the budget: linebake's scene through EmbreeOptions::max_memory_bytes (its buffers and
// BVH), the bare build's BVH through the same memory monitor, with the buffers it shares held.
void bench_embree(const BenchArgs& args) {
  // What a round's builds free goes back to the system before the next: glibc's threshold for
  // mapping large blocks would otherwise rise with Embree's frees and keep them in the heap
  // (three rounds of capsules under 112M peaked at 122 to 126 MiB). Both builds alike.
#ifdef __GLIBC__
  mallopt(M_MMAP_THRESHOLD, 128 << 10);
#endif
  const MemoryBudget budget = step_budget(args);
  const LineSet lines = load("embree", args, budget);
  EmbreeOptions options;
  options.geometry = parse_embree_geometry(args.geometry);
  if (options.geometry == EmbreeGeometry::Triangles)
    throw Error("bench embree: curves only (linear, bezier, capsules)");
  options.quality = parse_build_quality(args.quality);
  const Bounds b = compute_bounds(lines);
  const float dx = b.max[0] - b.min[0], dy = b.max[1] - b.min[1], dz = b.max[2] - b.min[2];
  const float radius = TubeOptions{}.radius * std::sqrt(dx * dx + dy * dy + dz * dz);
  const std::string attribute = lines.attributes.empty() ? "" : lines.attributes[0].name;
  std::vector<double> ours, prepare, commit, bare;
  BvhStats stats;
  // Each build gets what the budget leaves then (the lines, and for the bare build the buffers
  // it shares, counted as held), less a twentieth for what Embree's monitor does not see: the
  // builds ran 2 to 3 % past the budget before their refusals without it (bezier under 130M,
  // capsules under 100M).
  const auto left = [&] {
    const uint64_t available = step_budget(args).available();
    return std::max<uint64_t>(available - available / 20, 1);
  };
  for (int r = 0; r < args.repeat; ++r) {
    std::vector<PreparedCurves> buffers;
    if (!budget.unlimited()) options.max_memory_bytes = left();
    {
      const auto start = std::chrono::steady_clock::now();
      const EmbreeScene scene = EmbreeScene::from_lines(lines, radius, attribute, options);
      ours.push_back(seconds_since(start));
      stats = scene.stats();
      prepare.push_back(stats.prepare_s);
      commit.push_back(stats.commit_s);
      buffers = scene.prepared_curves();
    }
    bare.push_back(bare_commit_seconds(buffers, options.geometry, options.quality,
                                       budget.unlimited() ? 0 : left()));
  }
  const auto best = [](std::vector<double> v) { return *std::min_element(v.begin(), v.end()); };
  const double ratio = best(ours) / best(bare);
  const size_t threads =
      tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
  const nlohmann::json out = {{"step", "embree"},
                              {"input", args.input},
                              {"threads", threads},
                              {"geometry", to_string(options.geometry)},
                              {"quality", to_string(options.quality)},
                              {"primitives", stats.primitives},
                              {"ours_runs_s", ours},
                              {"prepare_runs_s", prepare},
                              {"commit_runs_s", commit},
                              {"bare_commit_runs_s", bare},
                              {"ratio_best", ratio},
                              {"target_ratio", 1.2},
                              {"buffer_bytes", stats.buffer_bytes},
                              {"bvh_bytes", stats.bvh_bytes},
                              {"bvh_peak_bytes", stats.bvh_peak_bytes},
                              {"memory_budget_bytes", budget.total()}};
  if (args.json) {
    std::cout << json_text(out, 2) << "\n";
    return;
  }
  std::cout << std::fixed << std::setprecision(3) << "embree: " << args.input << ", "
            << stats.primitives << " " << to_string(options.geometry) << " primitives, "
            << to_string(options.quality) << " quality, " << threads << " threads\n"
            << "  ours (s):        ";
  for (double t : ours) std::cout << t << " ";
  std::cout << "(prepare best " << best(prepare) << ", commit best " << best(commit) << ")\n"
            << "  bare commit (s): ";
  for (double t : bare) std::cout << t << " ";
  std::cout << "\n  ratio:           " << std::setprecision(3) << ratio
            << " (best over best; target <= 1.2: " << (ratio <= 1.2 ? "met" : "missed") << ")\n"
            << "  memory:          buffers " << std::setprecision(1)
            << double(stats.buffer_bytes) / (1 << 20) << " MiB, BVH "
            << double(stats.bvh_bytes) / (1 << 20) << " MiB (peak "
            << double(stats.bvh_peak_bytes) / (1 << 20) << " MiB)\n";
}

// The tube mesh built whole, as often as --repeat says, refused before the first build where
// it would not fit the budget (its planned size and the plan's 8 bytes a line); then memcpy's
// bandwidth over buffers of up to 1 GiB each that fit what the budget leaves.
void bench_tubes(const BenchArgs& args) {
  MemoryBudget budget = step_budget(args);
  const LineSet lines = load("tubes", args, budget);
  budget = step_budget(args);  // the lines counted as held
  TubeOptions options;
  options.sides = args.sides;
  if (!budget.unlimited()) {
    TubeStreamBuilder plan(lines, compute_stats(lines), options);
    plan.plan(lines);
    // The mesh's arrays, each rounded up to the 2 MiB pages large arrays take (core/array.hpp),
    // the plan's 8 bytes a line, and a twentieth more (what the build holds besides).
    const uint64_t arrays = 4 * plan.finish_plan().size();
    const uint64_t planned = plan.output_bytes(0, lines.line_count());
    const uint64_t mesh =
        planned + planned / 20 + arrays * (uint64_t{2} << 20) + 8 * lines.line_count();
    if (mesh > budget.available())
      refuse("tubes",
             "the tube mesh of " + std::to_string(lines.segment_count()) + " segments with " +
                 std::to_string(args.sides) + " sides",
             mesh, budget);
  }
  std::vector<double> times;
  uint64_t bytes = 0, triangles = 0;
  uint64_t peak = 0;
  for (int r = 0; r < args.repeat; ++r) {
    StepMeter meter;
    TubeMesh mesh = build_tubes(lines, options);
    const StepFigures f = meter.stop();
    times.push_back(f.wall_s);
    bytes = mesh.bytes();
    triangles = mesh.triangle_count();
    peak = std::max(peak, f.peak_rss);
  }
  // Two buffers of a third of what the budget leaves each, the mesh let go: of what it leaves
  // now, the builds' heap trimmed (their allocator's slack stays, about 1 MiB a repeat; sized
  // from the budget's start, --repeat 10 under 40M had peaked at 52 MB).
  const uint64_t resident = trimmed_rss_bytes();
  const uint64_t left = budget.total() > resident ? budget.total() - resident : 0;
  const uint64_t copy_bytes =
      budget.unlimited() ? uint64_t{1} << 30
                         : std::clamp<uint64_t>(left / 3, uint64_t{1} << 20, uint64_t{1} << 30);
  const double bandwidth = memcpy_bandwidth(5, size_t(copy_bytes));
  std::sort(times.begin(), times.end());
  const double best = times.front(), median_s = median(times);
  const double written = double(bytes) / best;
  const uint64_t segments = lines.segment_count();
  const size_t threads =
      tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
  nlohmann::json out = {{"step", "tubes"},
                        {"input", args.input},
                        {"threads", threads},
                        {"segments", segments},
                        {"sides", args.sides},
                        {"triangles", triangles},
                        {"bytes_written", bytes},
                        {"runs_s", times},
                        {"best_s", best},
                        {"median_s", median_s},
                        {"segments_per_s", double(segments) / best},
                        {"written_GBps", written / 1e9},
                        {"memcpy_GBps", bandwidth / 1e9},
                        {"fraction_of_memcpy", written / bandwidth},
                        {"memcpy_buffer_bytes", copy_bytes},
                        {"memory_budget_bytes", budget.total()},
                        {"peak_rss_bytes", peak}};
  if (args.json) {
    std::cout << json_text(out, 2) << "\n";
    return;
  }
  std::cout << std::fixed << std::setprecision(3) << "tubes: " << args.input << ", " << segments
            << " segments, " << args.sides << " sides, " << threads << " threads\n"
            << "  runs (s):        ";
  for (double t : times) std::cout << t << " ";
  std::cout << "\n  best:            " << best << " s, median " << median_s << " s\n"
            << "  segments/s:      " << std::setprecision(1) << double(segments) / best / 1e6
            << " M\n"
            << "  written:         " << std::setprecision(2) << double(bytes) / 1e9 << " GB at "
            << written / 1e9 << " GB/s\n"
            << "  memcpy:          " << bandwidth / 1e9 << " GB/s (same run, " << threads
            << " threads)\n"
            << "  of memcpy:       " << std::setprecision(0) << 100 * written / bandwidth << " %\n"
            << "  peak RSS:        " << format_bytes(peak) << " (budget "
            << (budget.unlimited() ? "unlimited" : format_bytes(budget.total())) << ")\n";
}

// A whole bake, as `linebake bake` runs it (forced, so every step builds), per stage: wall and
// CPU time and the resident high-water mark; then the bytes written per second against the
// machine's memcpy bandwidth from the same run (over buffers of up to 256 MiB that fit the
// budget, measured after the bakes so it does not count in their memory).
void bench_bake(const BenchArgs& args) {
  BakeOptions options;
  options.input = args.input;
  options.assets = args.assets;
  options.compression = parse_compression(args.compression);
  options.force = true;
  options.progress = !args.json;
  if (args.memory_budget == "unlimited")
    options.memory_budget = BakeOptions::kUnlimited;
  else if (!args.memory_budget.empty())
    options.memory_budget = std::max<uint64_t>(linebake::parse_size(args.memory_budget), 1);
  // <input name>.bench.lbc.h5: bake's default name with .bench before its .lbc.h5.
  const std::string bake_name = default_cache_path(args.input);
  options.cache =
      args.output.empty()
          ? bake_name.substr(0, bake_name.size() - std::string(".lbc.h5").size()) + ".bench.lbc.h5"
          : args.output;
  refuse_input_as_output(options.cache, {args.input});
  // Held across the runs and the removals of their cache, the last one's included: a bake of
  // another process into this path waits (bake() takes it again).
  const OutputLock one_writer(options.cache);
  // Each run bakes a new cache there and removes it, so only a path with nothing there is this
  // command's to write: a file the user has there (a cache, a kept bench cache, anything) is
  // not removed (it had been, before any check, even when the options were then refused).
  std::error_code ec;
  if (std::filesystem::symlink_status(options.cache, ec).type() !=
      std::filesystem::file_type::not_found)
    throw OutputError(options.cache,
                      "exists: bench bake bakes a new cache there on every run and removes it "
                      "(unless --keep); remove it, or name another path with -o");
  // The cache goes on the way out unless kept: a run that fails or is interrupted leaves none.
  struct RemovedUnlessKept {
    const std::string& path;
    bool keep;
    ~RemovedUnlessKept() {
      std::error_code ignored;
      if (!keep) std::filesystem::remove(path, ignored);
    }
  } cache_after{options.cache, args.keep};
  std::vector<BakeResult> runs;
  for (int r = 0; r < args.repeat; ++r) {
    std::filesystem::remove(options.cache);
    // What the last run freed goes back to the system first, HDF5's free lists too: each run
    // starts from what the process holds (a run left about 8 MiB in the heap, and a second run
    // under a budget the first met was refused).
    if (r > 0) {
      H5garbage_collect();
      trimmed_rss_bytes();
    }
    runs.push_back(bake(options));
  }
  // Its two buffers (256 MiB each at most) take no more than two thirds of what the budget
  // leaves the process after the bakes.
  const uint64_t budget = options.memory_budget == BakeOptions::kDefaultBudget
                              ? default_memory_budget()
                              : options.memory_budget;
  const uint64_t resident = trimmed_rss_bytes();
  const uint64_t copy_bytes = std::clamp<uint64_t>((budget > resident ? budget - resident : 0) / 3,
                                                   uint64_t{1} << 20, uint64_t{256} << 20);
  const double bandwidth = memcpy_bandwidth(5, size_t(copy_bytes));
  std::vector<double> walls;
  for (const BakeResult& r : runs) walls.push_back(r.wall_s);
  std::sort(walls.begin(), walls.end());
  const double median_s = median(walls);
  // The run whose wall time is the median (of an even count, the nearer of the middle two: the
  // faster on a tie) is the one reported in detail.
  const BakeResult& run =
      *std::min_element(runs.begin(), runs.end(), [&](const BakeResult& a, const BakeResult& b) {
        const double da = std::fabs(a.wall_s - median_s), db = std::fabs(b.wall_s - median_s);
        return da < db || (da == db && a.wall_s < b.wall_s);
      });
  const size_t threads =
      tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
  uint64_t segments = 0;
  for (const BakeStep& step : run.steps)
    if (step.step == "lines") segments = step.provenance.stats.value("segments", uint64_t{0});
  nlohmann::json stages = nlohmann::json::array();
  for (const BakeStage& s : run.stages)
    stages.push_back({{"stage", s.name},
                      {"wall_s", s.wall_s},
                      {"cpu_s", s.cpu_s},
                      {"peak_rss_bytes", s.peak_rss_bytes}});
  const double written = double(run.bytes_written) / run.wall_s;
  const nlohmann::json out = {{"step", "bake"},
                              {"input", args.input},
                              {"assets", args.assets},
                              {"compression", args.compression},
                              {"threads", threads},
                              {"segments", segments},
                              {"memory_budget_bytes", run.memory_budget_bytes},
                              {"batch_points", run.batch_points},
                              {"runs_s", walls},
                              {"median_s", median_s},
                              {"stages", stages},
                              {"peak_rss_bytes", run.peak_rss_bytes},
                              {"spill_peak_bytes", run.spill_peak_bytes},
                              {"bytes_written", run.bytes_written},
                              {"written_MBps", written / 1e6},
                              {"memcpy_GBps", bandwidth / 1e9}};
  if (args.json) {
    std::cout << json_text(out, 2) << "\n";
    return;
  }
  std::cout << std::fixed << std::setprecision(2) << "bake: " << args.input << ", " << segments
            << " segments, assets ";
  for (size_t i = 0; i < args.assets.size(); ++i) std::cout << (i ? "," : "") << args.assets[i];
  std::cout << ", " << args.compression << ", " << threads << " threads, budget "
            << (run.memory_budget_bytes ? format_bytes(run.memory_budget_bytes) : "unlimited")
            << "\n  runs (s):        ";
  for (double t : walls) std::cout << t << " ";
  std::cout << "(median " << median_s << " s; the run of " << run.wall_s << " s reported)\n";
  for (const BakeStage& s : run.stages)
    std::cout << "  " << std::left << std::setw(16) << (s.name + ":") << std::right << std::setw(7)
              << s.wall_s << " s wall, " << std::setw(7) << s.cpu_s << " s CPU, peak RSS "
              << format_bytes(s.peak_rss_bytes) << "\n";
  std::cout << "  peak RSS:        " << format_bytes(run.peak_rss_bytes) << " (budget "
            << (run.memory_budget_bytes ? format_bytes(run.memory_budget_bytes) : "unlimited")
            << ", " << run.batch_points << " points per batch)\n"
            << "  spill files:     " << format_bytes(run.spill_peak_bytes) << " at their largest\n"
            << "  written:         " << format_bytes(run.bytes_written) << " at "
            << std::setprecision(0) << written / 1e6 << " MB/s\n"
            << "  memcpy:          " << std::setprecision(2) << bandwidth / 1e9
            << " GB/s (same run, " << threads << " threads)\n";
}

}  // namespace

Command add_bench(CLI::App& app) {
  auto* bench =
      app.add_subcommand("bench",
                         "Benchmark a build step (tubes, voxels, embree), a whole bake, or the "
                         "rendering techniques on caches");
  bench->require_subcommand(1);
  auto args = std::make_shared<BenchArgs>();
  auto render = std::make_shared<BenchRenderArgs>();
  // Every step reads its input as bake does and runs with bake's defaults, so it measures what
  // bake builds.
  const auto step = [&](const char* name, const char* what, const char* reports) {
    auto* sub = bench->add_subcommand(name, std::string(what) + "; " + reports);
    sub->add_option("input", args->input, "Input file or synth source, as for bake")->required();
    sub->add_option("--repeat", args->repeat, std::string("Runs (default 3); ") + reports)
        ->check(CLI::Range(1, 100));
    sub->add_option("--threads", args->threads, "Worker threads (default: all cores)")
        ->check(CLI::Range(0, 1024));
    sub->add_flag("--json", args->json, "Print the figures as JSON");
    return sub;
  };
  // The in-memory builds (tubes, voxels, embree) are held to a budget as every command is.
  const auto within_budget = [&](CLI::App* sub, const char* what) {
    sub->add_option("--memory-budget", args->memory_budget,
                    std::string("Resident memory at most, e.g. 2G; unlimited (default: half of "
                                "physical memory, or of the cgroup's or ulimit -v's limit when "
                                "less): ") +
                        what)
        ->check(memory_budget_size());
  };
  auto* tubes = step("tubes", "Tube build speed against memcpy bandwidth of the same run",
                     "prints every run, the best and the median");
  tubes->add_option("--tube-sides", args->sides, "Ring vertices per point, 3..32 (default 3)")
      ->check(CLI::Range(3, 32));
  within_budget(tubes, "the lines read and the mesh built whole, refused past it");
  auto* voxels = step("voxels", "Voxel grid build: time, chords, memory, quantisation error",
                      "prints every run, the best and the median");
  voxels->add_option("--grid", args->grid, "auto (default, bake's rule), N or NxNxN")
      ->check(grid_check());
  voxels->add_option("--quantization", args->quantization, "16 | 32 (default) | 64")
      ->check(CLI::IsMember({16, 32, 64}));
  within_budget(voxels,
                "the lines read whole, the chord records spilled past it (a temporary file in the "
                "working directory), as bake builds them");
  auto* embree = step("embree", "linebake's Embree build against a bare rtcCommitScene",
                      "prints the best of each and their ratio");
  embree->add_option("--embree-geometry", args->geometry, "linear (default) | bezier | capsules")
      ->check(one_of({"linear", "bezier", "capsules"}));
  embree->add_option("--embree-quality", args->quality, "low | medium (default) | high")
      ->check(one_of({"low", "medium", "high"}));
  within_budget(embree, "the lines read whole, both scenes' buffers and BVH, refused past it");
  auto* bake = step("bake", "A whole bake, per stage: wall and CPU time, peak RSS, spill, writes",
                    "prints the run of median wall time in detail");
  add_list_option(bake, "--assets", args->assets, "Assets to build (default tubes, as bake)");
  bake->add_option("--memory-budget", args->memory_budget,
                   "Resident memory the bake may use, e.g. 2G; unlimited (default: half of "
                   "physical memory, or of the cgroup's or ulimit -v's limit when less)")
      ->check(memory_budget_size());
  bake->add_option("--compression", args->compression,
                   "none | deflate | lz4 (default) | blosc-zstd")
      ->check(one_of({"none", "deflate", "lz4", "blosc-zstd"}));
  bake->add_option("-o,--output", args->output,
                   "The cache to write (default <input name>.bench.lbc.h5, removed after)");
  bake->add_flag("--keep", args->keep, "Keep the cache");
  auto* rendering = bench->add_subcommand(
      "render",
      "Every technique of the registry on each cache and transfer function: GPU ms per "
      "pass, wall, memory, PSNR/SSIM against the reference");
  rendering->add_option("caches", render->caches, "Asset caches")->required();
  add_list_option(
      rendering, "--techniques", render->techniques,
      "Techniques (default: every one, and vrc-gpu for vrc on Vulkan compute; "
      "tiles-shared and tiles-subgroups, tiles with its sort's shared-memory or subgroup "
      "path, tiles-triangles, tiles over the tube mesh, tiles-raster-order, tiles "
      "dispatching its tiles in raster order, tiles-strips, tiles with four workgroups "
      "a tile, tiles-crowded-strips, with four for the crowded tiles and the walks "
      "again, tiles-pixel-hits and tiles-triangles-pixel-hits, tiles with each "
      "pixel computing its own hits, and tiles-late-shading, "
      "tiles-triangles-late-shading and tiles-pixel-hits-late-shading, tiles shading "
      "each hit when it composites it, when named; those this machine cannot run are "
      "listed as skipped, with the reason)");
  add_list_option(rendering, "--tf", render->transfer_functions,
                  "Transfer functions (default semi): opaque, semi, transparent, FILE.json");
  rendering->add_option("--frames", render->frames, "Frames of the orbit-zoom flight (default 8)")
      ->check(CLI::Range(1, 100000));
  rendering
      ->add_option("--warm-up", render->warm_up,
                   "Frames each technique renders before the flight's, not counted (default 1)")
      ->check(CLI::Range(0, 100));
  rendering->add_option("--size", render->size, "Image size WxH (default 1920x1080)")
      ->check(image_size_check());
  rendering->add_option("--device", render->device, "Vulkan device, part of its name");
  rendering
      ->add_option("--max-seconds", render->max_seconds,
                   "Per technique and transfer function, stop after the frame that passes "
                   "this many seconds (dp on large sets); default: render every frame")
      ->check(non_negative());
  rendering
      ->add_option("--memory-budget", render->memory_budget,
                   "As render's, for every technique and the reference: refuse a frame past it; "
                   "embree's and reference's BVH within what it leaves (default: half of "
                   "physical memory, or of the cgroup's or ulimit -v's limit when less); unlimited")
      ->check(memory_budget_size());
  rendering->add_flag("--early-termination", render->early_termination,
                      "Stop compositing at opacity 0.99, as render (never the reference)");
  rendering->add_flag("--every-hit", render->every_hit,
                      "embree, reference: collect every hit of every ray (the path render --stats "
                      "takes), not the interval walk");
  rendering->add_flag("--json", render->json, "Print the figures as JSON");
  auto isolation_args = std::make_shared<BenchIsolationArgs>();
  auto* isolation = bench->add_subcommand(
      "isolation",
      "The cost of walking HDF5 metadata in an isolated child (docs/reliability.md) against "
      "reading the data, and of reading the data in the child into shared memory");
  isolation->add_option("files", isolation_args->files, "HDF5 files (line files, caches)")
      ->required();
  isolation->add_option("--repeat", isolation_args->repeat, "Runs (default 3); prints medians")
      ->check(CLI::Range(1, 100));
  isolation
      ->add_option("--resident", isolation_args->resident,
                   "Memory to touch first, e.g. 8G (default 0): a fork copies the page tables of "
                   "all of it")
      ->check(byte_size());
  isolation->add_flag("--json", isolation_args->json, "Print the figures as JSON");
  auto shaders_args = std::make_shared<BenchShadersArgs>();
  auto* shaders = bench->add_subcommand(
      "shaders",
      "The Vulkan driver's compiler statistics of every compute shader (registers, spills, "
      "scratch, occupancy), compiled without rendering");
  add_list_option(shaders, "--shaders", shaders_args->shaders,
                  "Shaders whose names contain one of these (default: every compute shader), "
                  "e.g. tiles_composite");
  add_list_option(shaders, "--statistics", shaders_args->statistics,
                  "Statistics whose names contain one of these (default: all but hashes), "
                  "e.g. VGPRs,Scratch");
  shaders->add_option("--device", shaders_args->device, "Vulkan device, part of its name");
  shaders->add_flag("--json", shaders_args->json, "Print the statistics as JSON");
  return [args, render, tubes, voxels, embree, bake, rendering, isolation, isolation_args, shaders,
          shaders_args] {
    if (shaders->parsed()) {
      bench_shaders(*shaders_args);
      return;
    }
    if (isolation->parsed()) {
      for (const std::string& file : isolation_args->files) check_input_file(file);
      bench_isolation(*isolation_args);
      return;
    }
    if (rendering->parsed()) {
      for (const std::string& cache : render->caches) check_cache_input(cache);
      bench_render(*render);
      return;
    }
    check_input_file(args->input);
    std::unique_ptr<tbb::global_control> limit;
    if (args->threads > 0)
      limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                    size_t(args->threads));
    if (bake->parsed()) {
      if (!args->output.empty()) check_output_location(args->output);
      bench_bake(*args);
    } else if (voxels->parsed())
      bench_voxels(*args);
    else if (embree->parsed())
      bench_embree(*args);
    else if (tubes->parsed())
      bench_tubes(*args);
  };
}

}  // namespace linebake::cli
