// linebake convert <in> -o <out>: read any supported input, validate (reject or repair), optionally
// add derived attributes, and write any writable format.

#include <algorithm>
#include <chrono>
#include <iostream>

#include "cli_contract.hpp"
#include "commands.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/nearest.hpp"
#include "core/progress.hpp"
#include "formats/registry.hpp"
#include "lines/derived.hpp"
#include "lines/validate.hpp"

namespace linebake::cli {

namespace {

// Adds a derived attribute, replacing one of the same name (and saying so).
void add_derived(LineSet& lines, const std::string& name) {
  Attribute a = derive_attribute(lines, name);
  for (auto* list : {&lines.attributes, &lines.line_attributes})
    for (auto it = list->begin(); it != list->end(); ++it)
      if (it->name == name) {
        say("--derive " + name + ": replaces the input's attribute of that name");
        list->erase(it);
        break;
      }
  (is_line_attribute(name) ? lines.line_attributes : lines.attributes).push_back(std::move(a));
}

}  // namespace

Command add_convert(CLI::App& app) {
  auto* sub = app.add_subcommand("convert", "Convert a line set between formats");
  struct Args {
    std::string input, output, positional_output, from, to, on_invalid = "repair",
                                                            vtp_encoding = "appended";
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
      ->check(CLI::IsMember({"reject", "repair"}));
  sub->add_option("--derive", args->derive,
                  "Add derived attributes: segment_length, arc_length, curvature, "
                  "index_along_line, line_length (one of the input's own names is replaced)")
      ->delimiter(',')
      ->allow_extra_args(false);
  sub->add_flag("--ascii", args->ascii, "vtk, vtp: write text instead of binary");
  sub->add_option("--binlines-version", args->binlines_version,
                  "binlines: 1 (what LineVis reads, no names) or 2 (with attribute names, "
                  "default)")
      ->check(CLI::Range(1, 2));
  sub->add_option("--vtp-encoding", args->vtp_encoding,
                  "vtp: appended | appended-base64 | base64 | ascii")
      ->check(CLI::IsMember({"appended", "appended-base64", "base64", "ascii"}));
  sub->add_flag("--no-compress", args->no_compress, "vtp: no zlib compression");
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

    LineSet lines;
    {
      TerminalProgress progress("reading");
      read.progress = progress.callback();
      lines = read_line_set(args->input, read);
    }
    const ValidationReport report =
        validate(lines, parse_invalid_policy(args->on_invalid), args->input);
    if (!report.clean()) say(args->input + ": " + report.summary());
    for (const std::string& name : args->derive) add_derived(lines, name);
    // Nothing silent: what the output format cannot hold is named.
    const std::vector<std::string> lost = lost_in_format(lines, *write.format, write);
    if (!lost.empty()) {
      const std::string message = args->output + ": " + format_info(*write.format).name +
                                  " cannot hold " + name_list(lost) + "; they are not written";
      if (args->strict) throw Error(message + " (--strict)");
      warn(message + " (hdf5, vtk and vtp keep line attributes and metadata)");
    }
    {
      TerminalProgress progress("writing");
      write.progress = progress.callback();
      write_line_set(lines, args->output, write);
    }
    say_wrote(args->output,
              std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  };
}

}  // namespace linebake::cli
