// linebake export <cache> -o out.glb -o out.vdb: assets from the cache in formats other tools
// read.

#include <chrono>
#include <filesystem>
#include <iostream>

#include "cache/cache.hpp"
#include "cache/line_store.hpp"
#include "cache/tube_store.hpp"
#include "cache/voxel_store.hpp"
#include "cli_contract.hpp"
#include "commands.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/interrupt.hpp"
#include "core/measure.hpp"
#include "core/memory_budget.hpp"
#include "formats/gltf.hpp"
#include "formats/vdb.hpp"
#include "lines/origin.hpp"
#include "render/transfer_function.hpp"
#include "whole_output.hpp"

namespace linebake::cli {
namespace {

// COLOR_0's colour map: the transfer function's colours, linear RGB in 8 bits.
std::vector<std::array<uint8_t, 3>> colour_map_of(const TransferFunction& tf) {
  std::vector<std::array<uint8_t, 3>> map(256);
  for (int i = 0; i < 256; ++i) {
    const Rgba c = tf.at(i / 255.0);
    const auto byte = [](double x) { return uint8_t(std::lround(std::clamp(x, 0.0, 1.0) * 255)); };
    map[size_t(i)] = {byte(c.r), byte(c.g), byte(c.b)};
  }
  return map;
}

}  // namespace

namespace {

// What each export holds at its peak, checked against what --memory-budget leaves before
// anything is read. The glTF is written a tube chunk at a time (formats/gltf.hpp): it holds the
// largest chunk and its glTF arrays a piece at a time (with Draco, a piece of the chunk at a
// time, below), and the lines whole, about 3.5 times their bytes, with
// --line-strips 7 KiB more a line for its primitive; a VDB's OpenVDB trees whole (formats/vdb.hpp,
// vdb_build_bytes), the grid read a piece at a time. (Measured on convection at scale 0.2 on the
// development VM: a 285 MiB mesh in one chunk and in nine of 32 MiB, its 31 MiB of lines in 20,608
// lines, a 14 MiB grid. The factors below add a margin.)
template <class Args>
void check_export_memory(Args& args, const CacheReader& cache) {
  if (args.memory_budget == "unlimited") return;
  if (!args.vdb.empty()) load_vdb(args.vdb);  // OpenVDB's own memory counted as held
  trimmed_rss_bytes();
  const MemoryBudget budget(memory_budget_bytes(args.memory_budget));
  const auto bytes_of = [&](const std::string& group) -> uint64_t {
    const auto provenance = cache.exists(group) ? cache.provenance(group) : std::nullopt;
    return provenance ? provenance->memory_bytes : 0;
  };
  // The VDB is written and let go before the glTF is built: the larger of the two counts.
  const uint64_t vdb = args.vdb.empty() ? 0 : vdb_build_bytes(load_voxel_description(cache));
  // The lines whole (about 4 times their bytes, and 8 KiB a line's primitive with --line-strips),
  // held while the tubes are written.
  uint64_t lines = 0;
  if (!args.glb.empty() && args.lines) {
    lines = uint64_t(4.0 * double(bytes_of("/lines")));
    if (args.gltf.line_strips && cache.exists("/lines/line_offsets"))
      lines += 8192 * cache.shape("/lines/line_offsets").at(0);
  }
  uint64_t gltf = lines;
  if (!args.glb.empty() && !args.no_tubes) {
    const TubeMesh description = load_tube_description(cache);
    // Plain: a chunk and its glTF arrays a piece at a time, a tenth and 24 MiB more (convection
    // at scale 0.05 in chunks of 8 MB and at scale 0.2 in chunks of 32 MiB and in one of 285
    // MiB: peaks 30, 50 and 294 MiB past what the process held).
    // Draco: a chunk, and a piece of it at a time with its arrays and Draco's encoder
    // (tubes/mesh_pieces.hpp), about 16.5 times the piece, and 32 MiB (the spill's buffers:
    // convection at scale 0.2 in one chunk of 285 MiB peaked 13.5 times its pieces of 524,288
    // vertices past the chunk, 19 times those of 131,072); and every piece's primitive, which
    // the export keeps to the end, 24 KiB each (in pieces of one vertex, one a line, clouds at
    // scale 0.03 peaked 39 % past a budget that left out this term).
    constexpr double kPlain = 1.1, kDracoPiece = 16.5;
    constexpr uint64_t kPlainFixed = uint64_t{24} << 20, kDracoFixed = uint64_t{32} << 20,
                       kPrimitive = uint64_t{24} << 10;
    const uint64_t pv = args.gltf.draco_piece_vertices;
    uint64_t largest = 0, most = 0;  // a chunk's bytes; with Draco, its and its piece's
    uint64_t pieces = 0;             // with Draco, at most (pieces either side of a cut pass pv)
    double per_vertex = 0;           // the bytes of a vertex of a chunk, its triangles' share too
    for (size_t c = 0; c < description.chunks.size(); ++c) {
      const uint64_t bytes = tube_chunk_bytes(cache, description, c);
      largest = std::max(largest, bytes);
      const TubeCounts counts = tube_chunk_counts(cache, c);
      if (counts.vertices == 0) continue;
      const double vertex = double(bytes) / double(counts.vertices);
      per_vertex = std::max(per_vertex, vertex);
      most = std::max(
          most, bytes + uint64_t(kDracoPiece * vertex * double(std::min(counts.vertices, pv))));
      pieces += std::min<uint64_t>(description.chunks[c].line_count,
                                   2 * ((counts.vertices + pv - 1) / pv) + 1);
    }
    const uint64_t draco_fixed = kDracoFixed + kPrimitive * pieces;
    gltf += args.gltf.draco ? most + draco_fixed : uint64_t(kPlain * double(largest)) + kPlainFixed;
    // A piece that cannot be cut (a line longer than a piece) may be larger: it is refused past
    // what the budget leaves with the largest chunk, the primitives and the lines held.
    const uint64_t held = largest + draco_fixed + lines;
    if (args.gltf.draco && per_vertex > 0 && budget.available() > held)
      args.gltf.draco_max_piece_vertices = std::max<uint64_t>(
          pv, uint64_t(double(budget.available() - held) / (kDracoPiece * per_vertex)));
  }
  const uint64_t needed = std::max(vdb, gltf);
  const std::string what = vdb > gltf      ? "the voxel grid's VDB"
                           : args.no_tubes ? "the lines' glTF"
                                           : std::string("the tube mesh's glTF") +
                                                 (args.gltf.draco ? " with Draco" : "") +
                                                 (args.lines ? " and the lines" : "");
  if (needed > budget.available())
    throw BudgetExceeded("export: building " + what + " takes about " + format_bytes(needed) +
                         " in memory, more than the memory budget of " +
                         format_bytes(budget.total()) + " leaves (" +
                         format_bytes(budget.available()) + "); raise --memory-budget");
}

}  // namespace

Command add_export(CLI::App& app) {
  auto* sub = app.add_subcommand("export",
                                 "Export cached assets: glTF (tubes, lines), OpenVDB (voxel grid)");
  struct Args {
    std::string cache, glb, vdb, axes = "z-up", colors = "semi", memory_budget;
    std::vector<std::string> outputs;
    GltfOptions gltf;
    bool lines = false, no_tubes = false;
  };
  auto args = std::make_shared<Args>();
  sub->add_option("cache", args->cache, "Asset cache (.lbc.h5)")->required();
  sub->add_option("-o,--output", args->outputs,
                  "Output, the format from its extension: .glb or .gltf (as --glb) or .vdb (as "
                  "--vdb); once per format")
      ->allow_extra_args(false);
  sub->add_option("--glb", args->glb,
                  "glTF 2.0 output, the tube mesh (and lines): .glb, or .gltf with a .bin beside "
                  "it (no 4 GiB limit)");
  sub->add_option("--vdb", args->vdb,
                  "OpenVDB output: density, attribute_density, line_count, attribute_chord_max "
                  "from the voxel grid");
  sub->add_flag("--draco", args->gltf.draco, "Compress the tube mesh (KHR_draco_mesh_compression)");
  sub->add_option("--draco-bits", args->gltf.draco_position_bits,
                  "Position quantisation bits (default 14)")
      ->check(CLI::Range(1, 30));
  sub->add_option("--draco-normal-bits", args->gltf.draco_normal_bits,
                  "Normal quantisation bits (default 10)")
      ->check(CLI::Range(1, 30));
  sub->add_option("--draco-piece-vertices", args->gltf.draco_piece_vertices,
                  "Vertices of a tube chunk Draco encodes at a time, each piece a primitive, cut "
                  "between lines (default 524288): Draco holds about 14 times a piece")
      ->check(CLI::Range(uint64_t{1}, uint64_t{1} << 32));
  sub->add_option("--draco-speed", args->gltf.draco_speed,
                  "0 (smallest) .. 10 (fastest), default 5")
      ->check(CLI::Range(0, 10));
  sub->add_flag("--lines", args->lines, "Add the raw lines (one indexed LINES primitive)");
  sub->add_flag("--line-strips", args->gltf.line_strips,
                "With --lines: one LINE_STRIP primitive per polyline instead");
  sub->add_flag("--no-tubes", args->no_tubes, "Leave the tube mesh out (with --lines)");
  sub->add_option("--axes", args->axes,
                  "glTF axes: z-up (the data's +z becomes glTF's +y, as importers expect; "
                  "default) or raw (coordinates as stored)")
      ->check(one_of({"z-up", "raw"}));
  sub->add_option("--memory-budget", args->memory_budget,
                  "Resident memory at most, e.g. 8G (default: half of physical memory, or of the "
                  "cgroup's or ulimit -v's limit when less); "
                  "unlimited")
      ->check(memory_budget_size());
  sub->add_option("--colors", args->colors,
                  "COLOR_0 from a transfer function's colours: a preset (opaque, semi, "
                  "transparent), FILE.json, or none (default semi)");
  // Outputs by extension, and options that only a glTF output (with Draco) reads.
  check_when_parsed(sub, [sub, args] {
    for (const std::string& out : args->outputs) {
      const std::string ext = lowercase_extension(out);
      std::string& slot = ext == ".glb" || ext == ".gltf" ? args->glb
                          : ext == ".vdb"                 ? args->vdb
                                                          : args->cache;
      if (&slot == &args->cache)
        throw OutputError(out, "export writes .glb or .gltf (glTF) or .vdb (OpenVDB)");
      if (!slot.empty())  // one output a format: export writes each from the cache once
        throw UsageError(std::string(&slot == &args->vdb ? "an OpenVDB" : "a glTF") +
                         " output is given twice (" + slot + " and " + out +
                         "); export writes one of each");
      slot = out;
    }
    if (args->glb.empty() && args->vdb.empty())
      throw UsageError("nothing to export: give -o OUT.glb and/or -o OUT.vdb");
    if (!args->glb.empty() && lowercase_extension(args->glb) != ".glb" && !is_gltf_json(args->glb))
      throw OutputError(args->glb, "a glTF output ends in .glb or .gltf");
    refuse_unless(sub, {"draco-bits", "draco-normal-bits", "draco-speed", "draco-piece-vertices"},
                  args->gltf.draco, "with --draco");
    refuse_unless(sub, {"draco", "lines", "no-tubes", "axes", "colors"}, !args->glb.empty(),
                  "with a glTF output (-o OUT.glb)");
    refuse_unless(sub, {"line-strips"}, args->lines, "with --lines");
    if (args->no_tubes && !args->lines)
      throw UsageError("--no-tubes needs --lines: there would be nothing to export");
  });
  const auto body = [args] {
    check_cache_input(args->cache);
    for (const std::string& out : {args->glb, args->vdb})
      if (!out.empty()) check_output_location(out);
    // A .gltf's buffer goes beside it, as a .bin (formats/gltf.cpp).
    std::string buffer;
    if (is_gltf_json(args->glb))
      buffer = std::filesystem::path(output_target(args->glb)).replace_extension(".bin").string();
    check_output_location(buffer);  // a FIFO or directory there, before the export is built
    refuse_clashing_outputs({args->glb, buffer, args->vdb}, {args->cache});
    args->gltf.axes = args->axes == "raw" ? GltfAxes::Raw : GltfAxes::ZUp;
    if (!args->glb.empty() && args->colors != "none") {
      const TransferFunction tf = resolve_transfer_function(args->colors);
      args->gltf.colour_map = colour_map_of(tf);
      args->gltf.colour_range = {float(tf.range[0]), float(tf.range[1])};
    }
    const CacheReader cache(args->cache);
    check_export_memory(*args, cache);
    // Both place the lines at their world coordinates: their origin added (lines/origin.hpp).
    const Origin origin = origin_of(load_line_metadata(cache), args->cache);
    args->gltf.origin = origin;
    if (!args->vdb.empty()) write_vdb(args->vdb, *voxel_pieces(cache), {}, origin);
    if (args->glb.empty()) return;
    // The tube mesh a chunk at a time (formats/gltf.hpp reads each twice).
    TubeChunks tubes;
    if (!args->no_tubes) {
      tubes.description = load_tube_description(cache);
      tubes.chunk = [&cache, &tubes](size_t index) {
        return load_tube_chunk(cache, tubes.description, index);
      };
    }
    LineSet lines;
    if (args->lines) lines = load_lines(cache);
    // Lines without their tubes carry the attribute the cache's tubes were baked with, as they
    // do beside them.
    if (args->lines && args->no_tubes && cache.exists("/assets/tubes")) {
      const TubeMesh description = load_tube_description(cache);
      args->gltf.lines_attribute = description.attribute;
      args->gltf.lines_attribute_range = description.attribute_range;
    }
    write_gltf(args->glb, args->no_tubes ? nullptr : &tubes, args->lines ? &lines : nullptr,
               args->gltf);
  };
  // Every output of the command (an image and its --stats, each frame, both exports) is
  // renamed into place at the end, or none is: a failure or an interruption leaves nothing.
  return [body, args] {
    const auto start = std::chrono::steady_clock::now();
    OutputGroup outputs;
    body();
    // A Ctrl-C that came while a library wrote (Draco's encoder, OpenVDB's writer, the last
    // piece) stops here, before anything is renamed into place.
    throw_if_interrupted();
    outputs.commit();
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    for (const std::string& out : {args->glb, args->vdb})
      if (!out.empty()) say_wrote(out, seconds);
    if (is_gltf_json(args->glb))
      // Beside the file the .gltf names (through a symbolic link, the link's target), where it
      // was written: the link's own name had been said, a file that does not exist.
      say_wrote(std::filesystem::path(output_target(args->glb)).replace_extension(".bin").string(),
                seconds);
  };
}

}  // namespace linebake::cli
