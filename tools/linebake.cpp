// linebake: converters, exports and renders for large 3D line sets.

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <new>
#include <string>
#include <vector>

#include "cli_contract.hpp"
#include "commands.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/h5.hpp"
#include "core/interrupt.hpp"
#include "core/nearest.hpp"

namespace {

// What a command printed (--json, a report, help) is one of its outputs: a write that failed
// there (a full disk behind a redirection) fails the command, exit 3, so that nothing, `run`
// included, takes a cut-short output for a whole one. The outputs the command had already
// renamed into place are whole, and the message names them. std::cout, synchronised with stdio,
// flushes stdout itself: the failing fflush is usually that one, and the second finds nothing
// left to write.
int standard_output_written() {
  errno = 0;
  const bool was_good = static_cast<bool>(std::cout);
  std::cout.flush();
  const int cout_error = was_good && !std::cout ? errno : 0;
  errno = 0;
  const bool flushed = std::fflush(stdout) == 0;
  const int error = !flushed ? errno : cout_error;
  if (std::cout && flushed && !std::ferror(stdout)) return linebake::cli::kOk;
  // The reason only where these flushes failed: an earlier write's errno is gone.
  std::string message = "linebake: error: standard output: a write failed";
  if (error != 0) message += std::string(": ") + std::strerror(error);
  const std::vector<std::string> whole = linebake::outputs_written();
  for (size_t i = 0; i < whole.size(); ++i)
    message += (i == 0 ? " (written whole before it: " : ", ") + whole[i];
  std::cerr << message << (whole.empty() ? "" : ")") << "\n";
  return linebake::cli::kOutput;
}

// What a signal that came too late to stop the command leaves: its outputs, whole.
std::string as_the_command_finished(const std::vector<std::string>& whole) {
  if (whole.empty()) return "as the command finished, which wrote no file";
  std::string names = whole.front();
  if (whole.size() == 2) names += ", " + whole.back();
  if (whole.size() > 2)
    names = std::to_string(whole.size()) + " files, " + whole.front() + " .. " + whole.back();
  return "as the command finished: " + names + (whole.size() == 1 ? " was" : " were") +
         " written whole";
}

}  // namespace

int main(int argc, char** argv) {
  using namespace linebake::cli;
  linebake::h5::init();  // before anything else touches HDF5 (see h5::init)
  CLI::App app{"linebake " LINEBAKE_VERSION ": assets, exports and renders for large 3D line sets",
               "linebake"};
  app.set_version_flag("--version", LINEBAKE_VERSION);
  app.require_subcommand(1);
  // One voice: CLI11's parse errors get the prefix every other error has.
  speak_with_one_voice(app, "linebake");
  std::vector<std::pair<CLI::App*, Command>> commands;
  for (auto add : {add_info, add_convert, add_synth, add_bake, add_report, add_export, add_render,
                   add_depth_complexity, add_compare, add_bench, add_run, add_view, add_techniques,
                   add_formats, add_version, add_help}) {
    const size_t before = app.get_subcommands({}).size();
    Command run = add(app);
    commands.emplace_back(app.get_subcommands({})[before], std::move(run));
  }
  std::vector<std::string> args(argv + 1, argv + argc);
  auto command = std::find_if(args.begin(), args.end(),
                              [](const std::string& a) { return a.empty() || a[0] != '-'; });
  if (command != args.end()) {
    std::vector<std::string> names;
    for (const auto& [sub, run] : commands) names.push_back(sub->get_name());
    if (std::find(names.begin(), names.end(), *command) == names.end()) {
      std::cerr << "linebake: error: unknown command '" << *command << "'"
                << linebake::did_you_mean(*command, names) << " (linebake --help lists them)\n";
      return kUsage;
    }
    // `linebake --help CMD` is `linebake CMD --help`; `--version` before a command is itself.
    for (auto a = args.begin(); a != command; ++a) {
      if (*a == "--version") {
        std::cout << LINEBAKE_VERSION << "\n";
        return standard_output_written();
      }
      if (*a == "-h" || *a == "--help")
        for (const auto& [sub, run] : commands)
          if (sub->get_name() == *command) {
            std::cout << sub->help("linebake");
            return standard_output_written();
          }
    }
    const auto at = command - args.begin();
    std::vector<std::string> rest(command + 1, args.end());
    apply_deprecated_aliases(*command, rest);
    args.erase(command + 1, args.end());
    args.insert(args.end(), rest.begin(), rest.end());
    command = args.begin() + at;
    // A command of kinds (bench) names one: CLI11 said "A subcommand is required" of a kind
    // it did not know, and of none. After the old spellings are rewritten (bench's options
    // before its kind move behind it).
    for (const auto& [sub, run] : commands) {
      const std::vector<CLI::App*> kinds = sub->get_subcommands({});
      if (sub->get_name() != *command || kinds.empty()) continue;
      const auto kind = std::find_if(command + 1, args.end(),
                                     [](const std::string& a) { return a.empty() || a[0] != '-'; });
      const bool helped = std::any_of(
          command + 1, args.end(), [](const std::string& a) { return a == "-h" || a == "--help"; });
      std::vector<std::string> kind_names;
      for (const CLI::App* k : kinds) kind_names.push_back(k->get_name());
      if (kind == args.end() && !helped) {
        std::cerr << "linebake: error: " << *command
                  << " needs a kind: " << linebake::name_list(kind_names) << " (linebake "
                  << *command << " --help lists them)\n";
        return kUsage;
      }
      if (kind != args.end() &&
          std::find(kind_names.begin(), kind_names.end(), *kind) == kind_names.end()) {
        std::cerr << "linebake: error: unknown kind '" << *kind << "' of " << *command
                  << linebake::did_you_mean(*kind, kind_names) << " ("
                  << linebake::name_list(kind_names) << ")\n";
        return kUsage;
      }
    }
  }
  std::reverse(args.begin(), args.end());  // CLI11 takes a vector last argument first
  // Every failure, whether the command line's (found while parsing) or the work's, maps to the
  // exit code of its class (docs/cli.md, "Exit codes").
  const auto fail = [](const char* prefix, const std::exception& e, int code) {
    std::cerr << "linebake: " << prefix << e.what() << "\n";
    return code;
  };
  try {
    try {
      app.parse(args);
    } catch (const CLI::ParseError& e) {
      const int code = app.exit(e);  // help and --version print to stdout and give 0
      return code == 0 ? standard_output_written() : kUsage;
    }
    refuse_empty_values(app);
    // Every command stops at its next safe point on SIGINT, SIGTERM or SIGHUP, removing its
    // temporary files (core/interrupt.hpp).
    linebake::install_interrupt_handlers();
    // A write past `ulimit -f` fails with EFBIG, said and exit 3 as a full disk is, its
    // temporary files removed; the signal's default would end the process and leave them.
    std::signal(SIGXFSZ, SIG_IGN);
    for (auto& [sub, run] : commands)
      if (sub->parsed()) run();
    // A signal that came after the command's last safe point (during a render's last frame, a
    // bake's report) still ends it so, naming what it wrote whole.
    if (const int signal = linebake::interrupt_signal(); signal != 0)
      throw linebake::Interrupted(signal, as_the_command_finished(linebake::outputs_written()));
    return standard_output_written();
  } catch (const linebake::Interrupted& e) {
    std::cerr << "linebake: " << e.what() << "; its temporary files are removed\n";
    return 128 + e.signal();
  } catch (const linebake::UsageError& e) {
    return fail("error: ", e, kUsage);
  } catch (const linebake::InputError& e) {
    return fail("error: ", e, kInput);
  } catch (const linebake::OutputError& e) {
    return fail("error: ", e, kOutput);
  } catch (const std::bad_alloc&) {
    // An allocation the budget's estimates did not foresee, past what the kernel gives (an
    // address-space limit, overcommit off): said as such, not as "std::bad_alloc".
    std::cerr << "linebake: error: out of memory: an allocation failed past what this process "
                 "may have (ulimit -v, the cgroup's limit, or the machine's memory); give a "
                 "smaller --memory-budget, or ask for less\n";
    return kFailure;
  } catch (const std::exception& e) {
    return fail("error: ", e, kFailure);
  }
}
