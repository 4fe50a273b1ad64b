// linebake synth <name> -o <out>: generate one of the built-in synthetic data sets.

#include <chrono>
#include <iostream>

#include "cache/line_store.hpp"
#include "cli_contract.hpp"
#include "commands.hpp"
#include "core/atomic_file.hpp"
#include "core/interrupt.hpp"
#include "core/nearest.hpp"
#include "core/progress.hpp"
#include "formats/registry.hpp"
#include "synth/synth.hpp"
#include "whole_output.hpp"

namespace linebake::cli {

Command add_synth(CLI::App& app) {
  auto* sub = app.add_subcommand("synth",
                                 "Generate a synthetic data set (aneurysm, convection, "
                                 "turbulence, clouds)");
  struct Args {
    synth::SynthParams params;
    std::string output, to, memory_budget;
    bool adaptive = false;
  };
  auto args = std::make_shared<Args>();
  sub->add_option("name", args->params.name, "Data set")
      ->required()
      ->check(one_of({"aneurysm", "convection", "turbulence", "clouds"}));
  sub->add_option("-o,--output", args->output, "Output file (any writable format)")->required();
  sub->add_option("--scale", args->params.scale,
                  "Fraction of the paper's size (default 1.0; up to 100, generated and written "
                  "batch by batch to .binlines)")
      ->check(within(synth::kMinScale, synth::kMaxScale));
  sub->add_option("--seed", args->params.seed, "Random seed (default 1)")
      ->check(unsigned_integer());
  sub->add_flag("--adaptive", args->adaptive, "Adaptive RK4 step (default: fixed step)");
  sub->add_option("--to", args->to, "Output format, overriding the extension");
  sub->add_option("--memory-budget", args->memory_budget,
                  "Resident memory at most, e.g. 8G (default: half of physical memory, or of the "
                  "cgroup's or ulimit -v's limit when less); "
                  "unlimited")
      ->check(memory_budget_size());
  return [args] {
    args->params.adaptive = args->adaptive;
    const auto start = std::chrono::steady_clock::now();
    WriteOptions write;
    if (!args->to.empty()) write.format = parse_format(args->to);
    // Before generating: a format linebake cannot write, a missing directory.
    resolve_output_format(args->output, write.format);
    check_output_location(args->output);
    // Generated batch by batch; .binlines is written as the batches come, so any scale fits in
    // memory. Other formats collect the line set first.
    TerminalProgress progress("generating " + args->params.name);
    const std::unique_ptr<LineReader> generator =
        synth::open_generator(args->params, progress.callback());
    const std::unique_ptr<LineWriter> writer =
        open_line_writer(args->output, generator->header(), write);
    // Collected for a format written whole: held within --memory-budget with what writing it
    // takes, refused with the figures past it, before anything is written.
    const WholeOutput whole(args->memory_budget, resolve_output_format(args->output, write.format));
    LineSet batch;
    uint64_t segments = 0, points = 0, held = 0;
    // .binlines in batches the budget holds; the other formats in batches of a million points,
    // collected (and checked) as they come.
    const uint64_t max_points = whole.streams()
                                    ? whole.batch_points(generator->header(), uint64_t{1} << 20)
                                    : uint64_t{1} << 20;
    while (generator->next(batch, max_points)) {
      throw_if_interrupted();
      segments += batch.segment_count();
      points += batch.point_count();
      if (whole.streams()) whole.check_resident(args->output);
      if (!whole.streams()) {
        held += line_set_bytes(batch);
        whole.check(
            held, points, whole.writing(), args->output,
            std::string(format_info(resolve_output_format(args->output, write.format)).name) +
                " is written whole: the first",
            "write .binlines (written as it is generated)");
      }
      writer->write(batch);
    }
    writer->close();
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    // What the format cannot hold is named (the generator's parameters are metadata).
    const std::string lost = name_list(
        lost_in_format(generator->header(), resolve_output_format(args->output, write.format)));
    progress.finish();
    say(args->params.name + ": " + std::to_string(generator->lines_read()) + " lines, " +
        std::to_string(segments) + " segments");
    say_wrote(args->output, seconds);
    if (!lost.empty())
      warn(args->output + ": not kept by this format: " + lost + " (.h5, .vtk and .vtp keep it)");
  };
}

}  // namespace linebake::cli
