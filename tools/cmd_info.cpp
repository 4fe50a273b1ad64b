// linebake info <input> [--json]: counts, bounds, attributes, sizes and validation of a line set.

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>

#include "cli_contract.hpp"
#include "commands.hpp"
#include "core/interrupt.hpp"
#include "core/json_file.hpp"
#include "core/memory_budget.hpp"
#include "core/progress.hpp"
#include "formats/registry.hpp"
#include "lines/line_info.hpp"
#include "lines/line_reader.hpp"
#include "lines/validate.hpp"
#include "synth/synth.hpp"
#include "whole_output.hpp"

namespace linebake::cli {

Command add_info(CLI::App& app) {
  auto* sub = app.add_subcommand("info", "Print statistics of a line set (file or synth: source)");
  struct Args {
    std::string input, from, origin, memory_budget;
    bool json = false;
  };
  auto args = std::make_shared<Args>();
  sub->add_option("input", args->input, "Input file, or synth:<name>?scale=..&seed=..")->required();
  sub->add_option("--from", args->from, "Input format, overriding the extension");
  sub->add_option("--origin", args->origin, kOriginHelp)->check(origin_value());
  sub->add_option("--memory-budget", args->memory_budget,
                  "Resident memory at most for a format read whole (OBJ, VTK, VTP) or a line "
                  "larger than a batch, e.g. 8G (default: half of physical memory, or of the "
                  "cgroup's or ulimit -v's limit when less); unlimited")
      ->check(memory_budget_size());
  sub->add_flag("--json", args->json, "Machine-readable output (schema in docs/cli.md)");
  return [args] {
    check_input_file(args->input);
    ReadOptions read;
    if (!args->from.empty()) read.format = parse_format(args->from);
    // Statistics and validation gathered a batch (a million points) at a time: the set is never
    // held whole, but by the formats that cannot be read piece by piece (OBJ, VTK, VTP).
    LineSetStats s;
    ValidationReport v;
    std::map<std::string, std::string> metadata;
    {
      TerminalProgress progress("reading");
      read.progress = progress.callback();
      // A format read whole, or a line larger than a batch, is held within the budget.
      const MemoryBudget budget(memory_budget_bytes(args->memory_budget));
      if (!budget.unlimited()) read.memory_limit = budget.available();
      read.origin = resolve_origin(args->origin, {args->input}, read);
      const std::unique_ptr<LineReader> input = open_line_reader(args->input, read);
      metadata = input->header().metadata;
      if (std::optional<LineSet> whole = input->take_whole()) {
        s = compute_stats(*whole);
        v = inspect(*whole);
        metadata = whole->metadata;
      } else {
        LineStatsBuilder builder(input->header());
        // Batches of a million points, fewer where the budget leaves less.
        const uint64_t batch_points =
            batch_points_within(input->header(), read.memory_limit, uint64_t{1} << 20);
        LineSet batch;
        uint64_t line_base = 0;
        while (input->next(batch, batch_points)) {
          throw_if_interrupted();
          builder.add(batch);
          v.add(inspect(batch, line_base));
          line_base += batch.line_count();
        }
        s = builder.stats();
        add_counts_read(metadata, input->counts_read());  // a NetCDF file's splits at gaps
      }
    }
    if (!synth::is_synth_source(args->input)) metadata.emplace("source", args->input);
    if (args->json) {
      const nlohmann::json j =
          line_set_info(s, v, metadata, args->input, source_format_name(args->input, read));
      std::cout << json_text(j, 2) << "\n";
      return;
    }
    std::printf("source      %s (%s)\n", args->input.c_str(),
                source_format_name(args->input, read).c_str());
    std::printf("lines       %llu\n", static_cast<unsigned long long>(s.lines));
    std::printf("points      %llu\n", static_cast<unsigned long long>(s.points));
    std::printf("segments    %llu (LS, Table 1)\n", static_cast<unsigned long long>(s.segments));
    std::printf("line model  %.2f MiB (LM: positions %.2f, offsets %.2f, attributes %.2f)\n",
                static_cast<double>(s.total_bytes()) / (1 << 20),
                static_cast<double>(s.position_bytes) / (1 << 20),
                static_cast<double>(s.offset_bytes) / (1 << 20),
                static_cast<double>(s.attribute_bytes) / (1 << 20));
    // Positions relative to an origin (lines/origin.hpp): it, and the bounds in both frames.
    const auto origin = metadata.find(kOriginKey);
    if (origin != metadata.end()) std::printf("origin      %s\n", origin->second.c_str());
    if (!s.bounds.empty)
      std::printf("bounds      [%g %g %g] - [%g %g %g]%s\n", s.bounds.min[0], s.bounds.min[1],
                  s.bounds.min[2], s.bounds.max[0], s.bounds.max[1], s.bounds.max[2],
                  origin != metadata.end() ? " (relative to the origin)" : "");
    if (!s.bounds.empty && origin != metadata.end()) {
      const Origin o = origin_of(metadata, args->input);
      std::printf("world       [%.10g %.10g %.10g] - [%.10g %.10g %.10g]\n",
                  to_world(s.bounds.min[0], o[0]), to_world(s.bounds.min[1], o[1]),
                  to_world(s.bounds.min[2], o[2]), to_world(s.bounds.max[0], o[0]),
                  to_world(s.bounds.max[1], o[1]), to_world(s.bounds.max[2], o[2]));
    }
    // A range of the finite values; none where no value is finite.
    const auto range_text = [](const ValueRange& r) {
      char text[64] = "no finite value";
      if (r.finite > 0) std::snprintf(text, sizeof text, "[%g, %g]", r.min, r.max);
      return std::string(text) +
             (r.nonfinite ? " " + std::to_string(r.nonfinite) + " non-finite" : "");
    };
    for (const auto& [name, r] : s.attribute_ranges)
      std::printf("attribute   %s %s\n", name.c_str(), range_text(r).c_str());
    for (const auto& [name, r] : s.line_attribute_ranges)
      std::printf("line attr.  %s %s\n", name.c_str(), range_text(r).c_str());
    // Names the file gave twice, or not at all, read under new ones (formats/registry.cpp).
    if (const auto renamed = metadata.find("linebake.renamed_attributes");
        renamed != metadata.end())
      std::printf("renamed     %s\n", renamed->second.c_str());
    // What a NetCDF file's gaps did (the reader's counts, formats/netcdf.cpp).
    std::map<std::string, uint64_t> counts;
    for (const auto& [key, value] : metadata)
      if (key.rfind("netcdf.", 0) == 0 && !value.empty() &&
          value.find_first_not_of("0123456789") == std::string::npos)
        counts[key] = std::stoull(value);
    if (const std::string note = counts_read_note(counts); !note.empty())
      std::printf("gaps        %s\n", note.c_str());
    std::printf(
        "validation  %s%s\n", v.summary().c_str(),
        v.clean() || v.first_problem.empty() ? "" : ("; the first: " + v.first_problem).c_str());
  };
}

}  // namespace linebake::cli
