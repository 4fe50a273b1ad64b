// linebake convert <in> <out>: read any supported input, validate (reject or repair), optionally
// add derived attributes, and write any writable format.

#include <iostream>

#include "commands.hpp"
#include "core/atomic_file.hpp"
#include "core/progress.hpp"
#include "formats/registry.hpp"
#include "lines/derived.hpp"
#include "lines/validate.hpp"

namespace linebake::cli {

Command add_convert(CLI::App& app) {
  auto* sub = app.add_subcommand("convert", "Convert a line set between formats");
  struct Args {
    std::string input, output, from, to, on_invalid = "repair", vtp_encoding = "appended";
    std::vector<std::string> derive;
    bool ascii = false, no_compress = false;
    uint32_t binlines_version = 2;
  };
  auto args = std::make_shared<Args>();
  sub->add_option("input", args->input, "Input file, or synth:<name>?scale=..&seed=..")->required();
  sub->add_option("output", args->output, "Output file")->required();
  sub->add_option("--from", args->from, "Input format, overriding the extension");
  sub->add_option("--to", args->to, "Output format, overriding the extension");
  sub->add_option("--on-invalid", args->on_invalid,
                  "reject: fail on invalid data; repair: drop/split and report (default)")
      ->check(CLI::IsMember({"reject", "repair"}));
  sub->add_option("--derive", args->derive,
                  "Add derived attributes: segment_length, arc_length, curvature, "
                  "index_along_line, line_length")
      ->delimiter(',');
  sub->add_flag("--ascii", args->ascii, "vtk/vtp: write text instead of binary");
  sub->add_option("--binlines-version", args->binlines_version,
                  "1 (what LineVis reads, no names) or 2 (with attribute names, default)")
      ->check(CLI::Range(1, 2));
  sub->add_option("--vtp-encoding", args->vtp_encoding,
                  "appended | appended-base64 | base64 | ascii")
      ->check(CLI::IsMember({"appended", "appended-base64", "base64", "ascii"}));
  sub->add_flag("--no-compress", args->no_compress, "vtp: no zlib compression");
  return [args] {
    refuse_input_as_output(args->output, {args->input});
    ReadOptions read;
    if (!args->from.empty()) read.format = parse_format(args->from);
    WriteOptions write;
    if (!args->to.empty()) write.format = parse_format(args->to);
    write.ascii = args->ascii;
    write.binlines_version = args->binlines_version;
    write.vtp_encoding = args->ascii ? "ascii" : args->vtp_encoding;
    write.vtp_compress = !args->no_compress;
    // Fail on an unknown or read-only output format, or a missing directory, before reading a
    // large input.
    resolve_output_format(args->output, write.format);
    check_output_location(args->output);

    LineSet lines;
    {
      TerminalProgress progress("reading");
      read.progress = progress.callback();
      lines = read_line_set(args->input, read);
    }
    const ValidationReport report =
        validate(lines, parse_invalid_policy(args->on_invalid), args->input);
    if (!report.clean())
      std::cerr << "linebake: " << args->input << ": " << report.summary() << "\n";
    for (const std::string& name : args->derive) {
      Attribute a = derive_attribute(lines, name);
      (is_line_attribute(name) ? lines.line_attributes : lines.attributes).push_back(std::move(a));
    }
    TerminalProgress progress("writing");
    write.progress = progress.callback();
    write_line_set(lines, args->output, write);
  };
}

}  // namespace linebake::cli
