#pragma once
// The linebake subcommands. Each registers itself on the app and returns the function to run.

#include <CLI/CLI.hpp>
#include <functional>

namespace linebake {
struct BakeOptions;
struct BakeResult;
}  // namespace linebake

namespace linebake::cli {

// Exit codes (docs/cli.md, "Exit codes").
enum ExitCode : int {
  kOk = 0,
  kUsage = 1,   // bad command line
  kInput = 2,   // unreadable, malformed or (under --on-invalid reject) invalid input
  kOutput = 3,  // an output could not be written
  kFailure = 4  // anything else
};

using Command = std::function<void()>;
Command add_info(CLI::App& app);
Command add_convert(CLI::App& app);
Command add_synth(CLI::App& app);
Command add_bench(CLI::App& app);
Command add_bake(CLI::App& app);
// bake with another driver (linebake-mpi's); `print`: this process prints the report.
// `together` runs what only the printing process does before `run` (taking the output's lock)
// so that every process learns of its failure (linebake-mpi: Ranks::agree; the other ranks had
// waited for rank 0 in the bake for ever); none: runs it.
using Together = std::function<void(const std::function<void()>&)>;
Command add_bake_with(CLI::App& app, std::function<BakeResult(const BakeOptions&)> run, bool print,
                      Together together = {});
Command add_report(CLI::App& app);
Command add_export(CLI::App& app);
Command add_render(CLI::App& app);
Command add_compare(CLI::App& app);
Command add_depth_complexity(CLI::App& app);
Command add_run(CLI::App& app);
Command add_view(CLI::App& app);
Command add_techniques(CLI::App& app);
Command add_formats(CLI::App& app);
Command add_version(CLI::App& app);
Command add_help(CLI::App& app);

}  // namespace linebake::cli
