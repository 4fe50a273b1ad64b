// linebake bench <step>: speed of a build step against the machine's own memory bandwidth,
// measured in the same run. Targets are checked and printed, never asserted in tests.

#include <tbb/global_control.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "core/array.hpp"
#include "core/measure.hpp"
#include "core/progress.hpp"
#include "formats/registry.hpp"
#include "tubes/tube_builder.hpp"
#include "voxels/voxelizer.hpp"

namespace linebake::cli {
namespace {

// Best-of-n memcpy bandwidth (bytes written per second) over pre-touched 1 GiB buffers, with the
// copy split over all threads like the builders split their work.
double memcpy_bandwidth(int repeats) {
  const size_t bytes = size_t{1} << 30;
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
  std::string step, input = "synth:clouds", grid = "512";
  int sides = 3, repeat = 3, threads = 0;
  uint32_t quantization = 32;
  bool json = false;
};

LineSet load(const BenchArgs& args) {
  TerminalProgress progress("loading " + args.input);
  ReadOptions read;
  read.progress = progress.callback();
  return read_line_set(args.input, read);
}

// The voxel grid build: every run, best and median, chords/s, the representation's memory.
void bench_voxels(const BenchArgs& args) {
  const LineSet lines = load(args);
  VoxelOptions options;
  parse_grid(args.grid, options);
  options.quantization = args.quantization;
  std::vector<double> times;
  VoxelGrid grid;
  uint64_t peak = 0;
  for (int r = 0; r < args.repeat; ++r) {
    grid = VoxelGrid();
    StepMeter meter;
    grid = voxelize(lines, options);
    const StepFigures f = meter.stop();
    times.push_back(f.wall_s);
    peak = std::max(peak, f.peak_rss);
  }
  std::sort(times.begin(), times.end());
  const double best = times.front(), median = times[times.size() / 2];
  const size_t threads =
      tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
  const nlohmann::json out = {{"step", "voxels"},
                              {"input", args.input},
                              {"threads", threads},
                              {"segments", lines.segment_count()},
                              {"resolution", grid.resolution},
                              {"quantization", grid.quantization},
                              {"chords", grid.chord_count()},
                              {"runs_s", times},
                              {"best_s", best},
                              {"median_s", median},
                              {"segments_per_s", double(lines.segment_count()) / best},
                              {"representation_bytes", grid.representation_bytes()},
                              {"bytes_with_density", grid.bytes()},
                              {"max_error_voxels", grid.max_error},
                              {"mean_error_voxels", grid.mean_error},
                              {"peak_rss_bytes", peak}};
  if (args.json) {
    std::cout << out.dump(2) << "\n";
    return;
  }
  std::cout << std::fixed << std::setprecision(3) << "voxels: " << args.input << ", "
            << lines.segment_count() << " segments, grid " << grid.resolution[0] << "x"
            << grid.resolution[1] << "x" << grid.resolution[2] << " Q" << grid.quantization << ", "
            << threads << " threads\n  runs (s):        ";
  for (double t : times) std::cout << t << " ";
  std::cout << "\n  best:            " << best << " s, median " << median << " s\n"
            << "  chords:          " << grid.chord_count() << "\n"
            << "  representation:  " << std::setprecision(1)
            << double(grid.representation_bytes()) / (1 << 20) << " MiB (offsets + chords), "
            << double(grid.bytes()) / (1 << 20) << " MiB with density mips and line counts\n"
            << "  error (voxels):  max " << std::setprecision(4) << grid.max_error << ", mean "
            << grid.mean_error << "\n"
            << "  peak RSS:        " << std::setprecision(2) << double(peak) / (1 << 30)
            << " GiB\n";
}

void bench_tubes(const BenchArgs& args) {
  const LineSet lines = load(args);
  TubeOptions options;
  options.sides = args.sides;
  const double bandwidth = memcpy_bandwidth(5);
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
  std::sort(times.begin(), times.end());
  const double best = times.front(), median = times[times.size() / 2];
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
                        {"median_s", median},
                        {"segments_per_s", double(segments) / best},
                        {"written_GBps", written / 1e9},
                        {"memcpy_GBps", bandwidth / 1e9},
                        {"fraction_of_memcpy", written / bandwidth},
                        {"peak_rss_bytes", peak}};
  if (args.json) {
    std::cout << out.dump(2) << "\n";
    return;
  }
  std::cout << std::fixed << std::setprecision(3) << "tubes: " << args.input << ", " << segments
            << " segments, " << args.sides << " sides, " << threads << " threads\n"
            << "  runs (s):        ";
  for (double t : times) std::cout << t << " ";
  std::cout << "\n  best:            " << best << " s, median " << median << " s\n"
            << "  segments/s:      " << std::setprecision(1) << double(segments) / best / 1e6
            << " M\n"
            << "  written:         " << std::setprecision(2) << double(bytes) / 1e9 << " GB at "
            << written / 1e9 << " GB/s\n"
            << "  memcpy:          " << bandwidth / 1e9 << " GB/s (same run, " << threads
            << " threads)\n"
            << "  of memcpy:       " << std::setprecision(0) << 100 * written / bandwidth << " %\n"
            << "  peak RSS:        " << std::setprecision(2) << double(peak) / (1 << 30)
            << " GiB\n";
}

}  // namespace

Command add_bench(CLI::App& app) {
  auto* sub = app.add_subcommand("bench", "Benchmark a build step (tubes, voxels)");
  auto args = std::make_shared<BenchArgs>();
  sub->add_option("step", args->step, "Step to measure")
      ->required()
      ->check(CLI::IsMember({"tubes", "voxels"}));
  sub->add_option("--input", args->input, "Input file or synth source (default synth:clouds)");
  sub->add_option("--grid", args->grid, "voxels: auto, N or NxNxN (default 512)");
  sub->add_option("--quantization", args->quantization, "voxels: 16 | 32 (default) | 64")
      ->check(CLI::IsMember({16, 32, 64}));
  sub->add_option("--tube-sides", args->sides, "Ring vertices (default 3)")
      ->check(CLI::Range(3, 32));
  sub->add_option("--repeat", args->repeat, "Runs; the best is reported (default 3)")
      ->check(CLI::Range(1, 100));
  sub->add_option("--threads", args->threads, "Worker threads (default: all cores)")
      ->check(CLI::Range(0, 1024));
  sub->add_flag("--json", args->json, "Print the figures as JSON");
  return [args] {
    std::unique_ptr<tbb::global_control> limit;
    if (args->threads > 0)
      limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                    size_t(args->threads));
    if (args->step == "voxels")
      bench_voxels(*args);
    else
      bench_tubes(*args);
  };
}

}  // namespace linebake::cli
