// linebake synth <name> -o <out>: generate one of the built-in synthetic data sets.

#include <chrono>
#include <iostream>

#include "commands.hpp"
#include "core/progress.hpp"
#include "formats/registry.hpp"
#include "synth/synth.hpp"

namespace linebake::cli {

Command add_synth(CLI::App& app) {
  auto* sub = app.add_subcommand("synth",
                                 "Generate a synthetic data set (aneurysm, convection, "
                                 "turbulence, clouds)");
  struct Args {
    synth::SynthParams params;
    std::string output, to;
    bool adaptive = false;
  };
  auto args = std::make_shared<Args>();
  sub->add_option("name", args->params.name, "Data set")
      ->required()
      ->check(CLI::IsMember({"aneurysm", "convection", "turbulence", "clouds"}));
  sub->add_option("-o,--output", args->output, "Output file (any writable format)")->required();
  sub->add_option("--scale", args->params.scale, "Fraction of the paper's size (default 1.0)")
      ->check(CLI::Range(1e-6, 4.0));
  sub->add_option("--seed", args->params.seed, "Random seed (default 1)");
  sub->add_flag("--adaptive", args->adaptive, "Adaptive RK4 step (default: fixed step)");
  sub->add_option("--to", args->to, "Output format, overriding the extension");
  return [args] {
    args->params.adaptive = args->adaptive;
    const auto start = std::chrono::steady_clock::now();
    LineSet lines;
    {
      TerminalProgress progress("generating " + args->params.name);
      lines = synth::generate(args->params, progress.callback());
    }
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::cerr << "linebake: " << args->params.name << ": " << lines.line_count() << " lines, "
              << lines.segment_count() << " segments in " << seconds << " s\n";
    WriteOptions write;
    if (!args->to.empty()) write.format = parse_format(args->to);
    TerminalProgress progress("writing");
    write.progress = progress.callback();
    write_line_set(lines, args->output, write);
  };
}

}  // namespace linebake::cli
