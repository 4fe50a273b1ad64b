// linebake bake <input> -o <cache>: build assets into the cache and print the build report.
// linebake report <cache>...: the paper's Table 1 for the cached data.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <optional>

#include "cache/cache.hpp"
#include "cli_contract.hpp"
#include "commands.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/interrupt.hpp"
#include "core/json_file.hpp"
#include "core/memory_budget.hpp"
#include "core/nearest.hpp"
#include "core/output_lock.hpp"
#include "pipeline/bake.hpp"
#include "pipeline/report.hpp"

namespace linebake::cli {

Command add_bake(CLI::App& app) {
  return add_bake_with(
      app, [](const BakeOptions& o) { return bake(o); }, true);
}

Command add_bake_with(CLI::App& app, std::function<BakeResult(const BakeOptions&)> run, bool print,
                      Together together) {
  if (!together) together = [](const std::function<void()>& step) { step(); };
  auto* sub = app.add_subcommand(
      "bake", "Build renderable assets (tubes, voxels, embree, rtx) into an asset cache");
  struct Args {
    BakeOptions options;
    std::string from, on_invalid = "repair", compression = "lz4", normals = "float32";
    std::vector<float> attribute_range;
    std::string grid = "auto", embree_geometry = "linear", embree_quality = "medium";
    std::string memory_budget;
    std::vector<std::string> inputs;
    bool json = false;
  };
  auto args = std::make_shared<Args>();
  BakeOptions& o = args->options;
  sub->add_option("input", args->inputs,
                  "Input file, or synth:<name>?scale=..&seed=..; several files or quoted glob "
                  "patterns ('run/*.vtp') make one line set, in sorted path order")
      ->required();
  sub->add_option("-o,--output", o.cache,
                  "Cache file (default: <input name>.lbc.h5; required with several inputs)");
  sub->add_option("--from", args->from, "Input format, overriding the extension");
  sub->add_option("--on-invalid", args->on_invalid, "reject | repair (default)")
      ->check(one_of({"reject", "repair"}));
  sub->add_option("--origin", o.origin, kOriginHelp)->check(origin_value());
  add_list_option(sub, "--assets", o.assets,
                  "Assets to build: tubes, voxels, embree, rtx (default: tubes)")
      ->allow_extra_args(false);
  sub->add_option("--tube-sides", o.tubes.sides, "Ring vertices per point, 3..32 (default 3)")
      ->check(bake_number_check("--tube-sides"));
  sub->add_option("--radius", o.tubes.radius,
                  "Tube radius as a fraction of the bounding-box diagonal (default 0.001)")
      ->check(bake_number_check("--radius"));
  sub->add_flag("--radius-absolute", o.tubes.radius_absolute,
                "--radius is in world units, not a fraction of the diagonal");
  sub->add_option("--radius-attribute", o.tubes.radius_attribute,
                  "Per-point radius: radius * value / max(value) of this vertex attribute");
  sub->add_flag("--caps", o.tubes.caps, "Close the tube ends");
  sub->add_option("--normals", args->normals, "float32 (default) | oct16")
      ->check(one_of({"float32", "oct16"}));
  sub->add_option("--attribute", o.tubes.attribute,
                  "Attribute stored per vertex (default: the first vertex attribute; none)");
  sub->add_option("--attribute-range", args->attribute_range,
                  "lo,hi mapped to unorm16 0..65535 (default: the attribute's range)")
      ->delimiter(',')
      ->expected(2);
  sub->add_option("--chunk-bytes", o.tubes.max_chunk_bytes,
                  "Byte budget per tube chunk (default 4 GiB)")
      ->check(bake_number_check("--chunk-bytes"));
  sub->add_option("--grid", args->grid,
                  "Voxels: auto (default), N along the longest axis, or XxYxZ")
      ->check(grid_check());
  sub->add_option("--quantization", o.voxels.quantization,
                  "Voxels: cells per face axis for chord ends, 16 | 32 (default) | 64")
      ->check(bake_number_check("--quantization"));
  sub->add_option("--max-chords", o.voxels.max_chords_per_voxel,
                  "Voxels: chords kept per voxel (default 32); the rest are counted and dropped")
      ->check(bake_number_check("--max-chords"));
  sub->add_option("--voxel-attribute", o.voxels.attribute,
                  "Voxels: vertex attribute stored as unorm8 at chord ends (default: the first; "
                  "none)");
  sub->add_option("--embree-geometry", args->embree_geometry,
                  "Embree: linear (default, round linear curves) | bezier (Catmull-Rom) | capsules "
                  "(round linear curves, as tiles and rtx --rtx-geometry capsules draw them)")
      ->check(one_of({"linear", "bezier", "capsules"}));
  sub->add_option("--embree-quality", args->embree_quality, "Embree: low | medium (default) | high")
      ->check(one_of({"low", "medium", "high"}));
  sub->add_flag("--embree-compact", o.embree.compact, "Embree: RTC_SCENE_FLAG_COMPACT");
  sub->add_flag("--embree-robust", o.embree.robust, "Embree: RTC_SCENE_FLAG_ROBUST");
  sub->add_option("--embree-max-primitives", o.embree.max_primitives_per_scene,
                  "Embree: segments per scene; a larger set is cut into parts of whole lines, "
                  "instanced in one top-level scene (default 4294967295)")
      ->check(bake_number_check("--embree-max-primitives"));
  sub->add_option("--rtx-geometry", o.rtx.geometry,
                  "rtx: BLAS over the tube mesh's triangles (default) or capsule AABBs")
      ->check(one_of({"triangles", "capsules"}));
  sub->add_flag(
      "--rtx-no-compaction", [&o](int64_t) { o.rtx.compaction = false; },
      "rtx: keep the BLAS as built (default: compacted)");
  sub->add_option("--device", o.rtx.device,
                  "rtx: Vulkan device, part of its name (default: a discrete GPU)");
  sub->add_flag("--validation", o.rtx.validation,
                "rtx: Khronos validation layer on; validation errors fail the bake");
  sub->add_option("--compression", args->compression, "none | deflate | lz4 (default) | blosc-zstd")
      ->check(one_of({"none", "deflate", "lz4", "blosc-zstd"}));
  sub->add_option("--compression-level", o.compression_level,
                  "Codec level: deflate 1-9 (default 4), blosc-zstd 1-9 (default 5)")
      ->check(bake_number_check("--compression-level"));
  sub->add_option("--memory-budget", args->memory_budget,
                  "Resident memory the bake may use, the process included: e.g. 2G, 512M; "
                  "unlimited (default: half of physical memory, or of the cgroup's or ulimit -v's "
                  "limit when less)")
      ->check(memory_budget_size());
  sub->add_flag("--force", o.force,
                "Rebuild every step even if the cache is up to date; replace an output file "
                "that is not a linebake cache");
  sub->add_flag(
      "--no-space-check", [&o](int64_t) { o.space_check = false; },
      "Bake even when the estimated output does not fit the free space");
  sub->add_flag("--dry-run", o.dry_run,
                "Read the input and print what the bake would write and the free space; "
                "write nothing");
  sub->add_flag("--json", args->json, "Print the report as JSON");
  // An option no step of this bake reads is a mistake, not a no-op.
  check_when_parsed(sub, [sub, args] {
    const std::vector<std::string>& assets = args->options.assets;
    const auto building = [&](const char* asset) {
      return std::find(assets.begin(), assets.end(), asset) != assets.end();
    };
    const std::vector<std::string> known = {"tubes", "voxels", "embree", "rtx"};
    for (const std::string& asset : assets)
      if (std::find(known.begin(), known.end(), asset) == known.end())
        throw UsageError("--assets: unknown asset '" + asset +
                         "' (bake builds: tubes, voxels, embree, rtx)" +
                         did_you_mean(asset, known));
    refuse_unless(sub, {"grid", "quantization", "max-chords", "voxel-attribute"},
                  building("voxels"), "when voxels are built (--assets voxels)");
    refuse_unless(sub,
                  {"embree-geometry", "embree-quality", "embree-compact", "embree-robust",
                   "embree-max-primitives"},
                  building("embree"), "when the Embree buffers are built (--assets embree)");
    refuse_unless(sub, {"rtx-geometry", "rtx-no-compaction", "device", "validation"},
                  building("rtx"), "when rtx acceleration structures are built (--assets rtx)");
    // Embree's curves have one radius for the whole set: a per-point radius is the tubes' alone.
    refuse_unless(
        sub,
        {"tube-sides", "caps", "normals", "chunk-bytes", "attribute-range", "radius-attribute"},
        building("tubes") || building("rtx"), "when tubes are built (--assets tubes)");
    refuse_unless(sub, {"radius", "radius-absolute", "attribute"},
                  building("tubes") || building("rtx") || building("embree"),
                  "when tubes or Embree curves are built");
    refuse_unless(sub, {"compression-level"},
                  args->compression == "deflate" || args->compression == "blosc-zstd",
                  "with --compression deflate or blosc-zstd (lz4 and none have no levels)");
  });
  return [args, run, print, sub, together] {
    BakeOptions options = args->options;
    for (const std::string& input : args->inputs)
      if (input.find_first_of("*?[") == std::string::npos) check_input_file(input);
    options.inputs = expand_inputs(args->inputs);
    options.input = options.inputs.size() == 1 ? options.inputs[0] : "";
    if (!args->from.empty()) options.format = parse_format(args->from);
    options.on_invalid = parse_invalid_policy(args->on_invalid);
    options.compression = parse_compression(args->compression);
    // Not given: a bake into an existing cache keeps its codec (BakeOptions::compression_given).
    options.compression_given = given(sub, "compression");
    options.tubes.normals = parse_normal_encoding(args->normals);
    parse_grid(args->grid, options.voxels);
    options.embree.geometry = parse_embree_geometry(args->embree_geometry);
    options.embree.quality = parse_build_quality(args->embree_quality);
    if (args->attribute_range.size() == 2) {
      // NaN or an empty range would quantise every vertex to one value (or store a range no
      // reader can parse): refused as Python's attribute_range is.
      const float lo = args->attribute_range[0], hi = args->attribute_range[1];
      if (!(std::isfinite(lo) && std::isfinite(hi) && lo < hi)) {
        char given[96];
        std::snprintf(given, sizeof given, "%g,%g", double(lo), double(hi));
        throw UsageError(std::string("--attribute-range: expected two finite numbers LO,HI with "
                                     "LO < HI, got ") +
                         given);
      }
      options.tubes.attribute_range = std::array<float, 2>{lo, hi};
    }
    if (args->memory_budget == "unlimited")
      options.memory_budget = BakeOptions::kUnlimited;
    else if (!args->memory_budget.empty())
      options.memory_budget = std::max<uint64_t>(parse_size(args->memory_budget), 1);
    if (!options.dry_run)
      check_output_location(options.cache);  // "" : the default beside the input
    // Held around the bake (which takes it again) and the report read back after it, so that
    // another bake's cache renamed there in between is not the one reported. linebake-mpi: on
    // the rank that prints, rank 0, which holds it in the bake too.
    std::optional<OutputLock> one_writer;
    together([&] {
      if (print && !options.dry_run)
        if (const std::string cache = bake_output_path(options); !cache.empty())
          one_writer.emplace(cache);
    });
    const BakeResult result = run(options);
    if (!print) return;
    if (options.dry_run) {
      const BakeEstimate& e = result.estimate;
      std::cout << "would write " << result.cache << ": about " << format_bytes(e.total() - e.spill)
                << " (lines " << format_bytes(e.lines);
      for (const std::string& a : options.assets)
        if (e.step(a)) std::cout << ", " << a << " " << format_bytes(e.step(a));
      std::cout
          << "), temporary spill files about " << format_bytes(e.spill) << "; "
          << (result.free_bytes == UINT64_MAX
                  ? "free space unknown: the directory cannot be asked (it does not exist yet?)"
                  : format_bytes(result.free_bytes) + " free there")
          << "\n";
      return;
    }
    for (const std::string& note : result.notes) std::cerr << "linebake: " << note << "\n";
    for (const BakeStep& step : result.steps)
      std::cerr << "linebake: " << step.step << ": "
                << (step.built ? "built" : "up to date, reused") << "\n";
    if (!result.written) std::cerr << "linebake: " << result.cache << " is up to date\n";
    for (const BakeStage& stage : result.stages)
      say("stage " + stage.name + ": " + format_seconds(stage.wall_s) + " wall, " +
          format_seconds(stage.cpu_s) + " CPU, peak RSS " + format_bytes(stage.peak_rss_bytes));
    // The cache is in place by now: a signal while it is read back for the report (its probe
    // runs in a child process) says so, as the serial bake's own read-back does.
    std::vector<CacheSummary> summary;
    try {
      const CacheReader cache(result.cache, false);
      summary.push_back(summarize_cache(cache));
    } catch (const Interrupted& e) {
      if (!result.written) throw;
      throw Interrupted(e.signal(), "after " + result.cache +
                                        " was written whole (reading its figures back for the "
                                        "report was cut short)");
    }
    if (args->json)
      std::cout << json_text(report_json(summary), 2) << "\n";
    else
      std::cout << report_text(summary);
  };
}

Command add_report(CLI::App& app) {
  auto* sub = app.add_subcommand("report", "Table 1 for one or more caches: sizes, build times");
  struct Args {
    std::vector<std::string> caches;
    bool json = false, markdown = false;
  };
  auto args = std::make_shared<Args>();
  sub->add_option("caches", args->caches, "Cache files (.lbc.h5)")->required();
  auto* json = sub->add_flag("--json", args->json, "All figures as JSON");
  sub->add_flag("--markdown", args->markdown, "One Markdown table row per cache")->excludes(json);
  return [args] {
    std::vector<CacheSummary> summaries;
    for (const std::string& path : args->caches) check_cache_input(path);
    for (const std::string& path : args->caches)
      summaries.push_back(summarize_cache(CacheReader(path, false)));
    if (args->json)
      std::cout << json_text(report_json(summaries), 2) << "\n";
    else if (args->markdown)
      std::cout << report_markdown(summaries);
    else
      std::cout << report_text(summaries);
  };
}

}  // namespace linebake::cli
