// linebake convert <in> -o <out>: read any supported input, validate (reject or repair), optionally
// add derived attributes, and write any writable format.

#include <algorithm>
#include <chrono>
#include <iostream>

#include "cache/line_store.hpp"
#include "cli_contract.hpp"
#include "commands.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/interrupt.hpp"
#include "core/measure.hpp"
#include "core/memory_budget.hpp"
#include "core/nearest.hpp"
#include "core/progress.hpp"
#include "formats/registry.hpp"
#include "lines/derived.hpp"
#include "lines/line_reader.hpp"
#include "lines/validate.hpp"
#include "synth/synth.hpp"
#include "whole_output.hpp"

namespace linebake::cli {

namespace {

// Adds a derived attribute, replacing one of the same name. Whether it replaced one.
bool add_derived(LineSet& lines, const std::string& name) {
  Attribute a = derive_attribute(lines, name);
  bool replaced = false;
  for (auto* list : {&lines.attributes, &lines.line_attributes})
    for (auto it = list->begin(); it != list->end(); ++it)
      if (it->name == name) {
        list->erase(it);
        replaced = true;
        break;
      }
  (is_line_attribute(name) ? lines.line_attributes : lines.attributes).push_back(std::move(a));
  return replaced;
}

// Points per batch: a sixteenth of what the budget leaves (at 16 bytes a point with one
// attribute, and as much again for the batch's copies), at least 64 Ki, at most 4 Mi.
uint64_t batch_points(const MemoryBudget& budget, const LineSet& header) {
  const uint64_t per_point = 12 + 4 * header.attributes.size();
  const uint64_t room = budget.unlimited() ? UINT64_MAX : budget.available() / 16;
  return std::clamp<uint64_t>(room / per_point, uint64_t{1} << 16, uint64_t{1} << 22);
}

}  // namespace

Command add_convert(CLI::App& app) {
  auto* sub = app.add_subcommand("convert", "Convert a line set between formats");
  struct Args {
    std::string input, output, positional_output, from, to,
        on_invalid = "repair", vtp_encoding = "appended", memory_budget, origin;
    std::vector<std::string> derive;
    bool ascii = false, no_compress = false, strict = false;
    uint32_t binlines_version = 2;
    Format format = Format::binlines;
  };
  auto args = std::make_shared<Args>();
  sub->add_option("input", args->input,
                  "Input file (a linebake cache too), or synth:<name>?scale=..&seed=..")
      ->required();
  sub->add_option("-o,--output", args->output, "Output file; the format from its extension");
  // The output as a second positional: the spelling before -o, kept for one release.
  sub->add_option("output", args->positional_output,
                  "Deprecated: the output as a second positional (use -o)");
  sub->add_option("--from", args->from, "Input format, overriding the extension");
  sub->add_option("--to", args->to, "Output format, overriding the extension");
  sub->add_option("--on-invalid", args->on_invalid,
                  "reject: fail on invalid data; repair: drop/split and report (default)")
      ->check(one_of({"reject", "repair"}));
  sub->add_option("--origin", args->origin, kOriginHelp)->check(origin_value());
  add_list_option(sub, "--derive", args->derive,
                  "Add derived attributes: segment_length, arc_length, curvature, "
                  "index_along_line, line_length (one of the input's own names is replaced)")
      ->allow_extra_args(false);
  sub->add_flag("--ascii", args->ascii, "vtk, vtp: write text instead of binary");
  sub->add_option("--binlines-version", args->binlines_version,
                  "binlines: 1 (what LineVis reads, no names) or 2 (with attribute names, "
                  "default)")
      ->check(CLI::Range(1, 2));
  sub->add_option("--vtp-encoding", args->vtp_encoding,
                  "vtp: appended | appended-base64 | base64 | ascii")
      ->check(one_of({"appended", "appended-base64", "base64", "ascii"}));
  sub->add_flag("--no-compress", args->no_compress, "vtp: no zlib compression");
  sub->add_option("--memory-budget", args->memory_budget,
                  "Resident memory at most, e.g. 8G (default: half of physical memory, or of the "
                  "cgroup's or ulimit -v's limit when less); "
                  "unlimited")
      ->check(memory_budget_size());
  sub->add_flag("--strict", args->strict,
                "Fail (exit 4) instead of warning when the output format cannot hold something "
                "of the input (line attributes, metadata, attribute names)");
  check_when_parsed(sub, [sub, args] {
    if (!args->positional_output.empty()) {
      if (!args->output.empty())
        throw UsageError("two outputs: " + args->positional_output + " and -o " + args->output);
      warn(
          "convert IN OUT is deprecated; use convert IN -o OUT (docs/cli.md, deprecated "
          "spellings)");
      args->output = args->positional_output;
    }
    if (args->output.empty()) throw UsageError("-o OUT is required");
    std::optional<Format> forced;
    if (!args->to.empty()) forced = parse_format(args->to);
    // An output format linebake cannot write is refused when the command runs (exit 4).
    try {
      args->format = resolve_output_format(args->output, forced);
    } catch (const UsageError&) {
      throw;
    } catch (const Error&) {
      return;
    }
    for (const std::string& name : args->derive) {
      const auto& known = derived_attribute_names();
      if (std::find(known.begin(), known.end(), name) == known.end())
        throw UsageError("--derive: unknown derived attribute '" + name + "' (" + name_list(known) +
                         ")" + did_you_mean(name, known));
    }
    const Format f = args->format;
    refuse_unless(sub, {"ascii"}, f == Format::vtk || f == Format::vtp, "for vtk and vtp outputs");
    refuse_unless(sub, {"vtp-encoding", "no-compress"}, f == Format::vtp, "for vtp outputs");
    refuse_unless(sub, {"binlines-version"}, f == Format::binlines, "for binlines outputs");
    if (args->ascii && given(sub, "vtp-encoding") && args->vtp_encoding != "ascii")
      throw UsageError("--ascii and --vtp-encoding " + args->vtp_encoding + " contradict");
  });
  return [args] {
    const auto start = std::chrono::steady_clock::now();
    check_input_file(args->input);
    refuse_input_as_output(args->output, {args->input});
    ReadOptions read;
    if (!args->from.empty()) read.format = parse_format(args->from);
    WriteOptions write;
    write.format = resolve_output_format(
        args->output, args->to.empty() ? std::nullopt : std::optional(parse_format(args->to)));
    write.ascii = args->ascii;
    write.binlines_version = args->binlines_version;
    write.vtp_encoding = args->ascii ? "ascii" : args->vtp_encoding;
    write.vtp_compress = !args->no_compress;
    // A missing directory is found before reading a large input.
    check_output_location(args->output);

    // The lines go from the reader to the writer a batch at a time: into a .binlines output as
    // they come, in bounded memory; the other formats are written whole at the end, and their
    // lines are held within --memory-budget (refused with the figures past it, before anything
    // is written). Formats that cannot be read piece by piece are read whole first.
    const MemoryBudget budget(memory_budget_bytes(args->memory_budget));
    const InvalidPolicy policy = parse_invalid_policy(args->on_invalid);
    TerminalProgress progress("converting");
    read.progress = progress.callback();
    // The lines held whole (a format read whole, or an output written whole), with what writing
    // them takes, within what the budget left before them; past it, refused with the figures
    // before anything is written.
    const WholeOutput whole_output(args->memory_budget, *write.format);
    const std::string advice = "convert to .binlines (written as it is read)";
    if (!budget.unlimited()) read.memory_limit = budget.available();
    read.origin = resolve_origin(args->origin, {args->input}, read);
    std::unique_ptr<LineReader> input = open_line_reader(args->input, read);
    ValidationReport report;
    std::optional<LineSet> whole;
    if (!input->streams()) {
      whole = input->take_whole();
      // Held whole, and again by an output written whole (its copy, and the writing).
      whole_output.check(
          line_set_bytes(*whole), whole->point_count(),
          whole_output.streams() ? 0.0 : 1.0 + whole_output.writing(), args->input,
          std::string(format_info(resolve_input_format(args->input, read.format)).name) +
              " is read whole: its",
          advice);
      report = validate(*whole, policy, args->input);
      input = MemoryLineReader::view(*whole);
    }
    LineSet header = header_of(input->header());
    if (!synth::is_synth_source(args->input)) header.metadata.emplace("source", args->input);
    for (const std::string& name : args->derive)
      if (add_derived(header, name))
        say("--derive " + name + ": replaces the input's attribute of that name");
    // Nothing silent: what the output format cannot hold is named.
    const std::vector<std::string> lost = lost_in_format(header, *write.format, write);
    if (!lost.empty()) {
      const std::string message = args->output + ": " + format_info(*write.format).name +
                                  " cannot hold " + name_list(lost) + "; they are not written";
      if (args->strict) throw Error(message + " (--strict)");
      warn(message + " (hdf5, vtk and vtp keep line attributes and metadata)");
    }
    std::unique_ptr<LineWriter> output = open_line_writer(args->output, header, write);
    const uint64_t max_points = batch_points(budget, header);
    LineSet batch;
    uint64_t line_base = 0, points = 0, held = 0;
    while (input->next(batch, max_points)) {
      throw_if_interrupted();
      if (!whole) {
        const std::string where = args->input + " (lines " + std::to_string(line_base) + ".." +
                                  std::to_string(line_base + batch.line_count() - 1) + ")";
        report.add(validate(batch, policy, where, line_base));
      }
      line_base += batch.line_count();
      points += batch.point_count();
      for (const std::string& name : args->derive) add_derived(batch, name);
      if (output->streams()) whole_output.check_resident(args->output);
      if (!output->streams()) {
        held += line_set_bytes(batch);
        if (!whole)
          whole_output.check(
              held, points, whole_output.writing(), args->input,
              std::string(format_info(*write.format).name) + " is written whole: the first",
              advice);
      }
      output->write(batch);
    }
    input.reset();
    whole.reset();
    if (!report.clean()) say(args->input + ": " + report.summary());
    output->close();
    progress.finish();
    say_wrote(args->output,
              std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  };
}

}  // namespace linebake::cli
