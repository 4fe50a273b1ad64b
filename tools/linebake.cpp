// linebake: converters, exports and renders for large 3D line sets.

#include <cstdio>
#include <iostream>

#include "commands.hpp"
#include "core/error.hpp"
#include "core/h5.hpp"
#include "core/interrupt.hpp"

int main(int argc, char** argv) {
  using namespace linebake::cli;
  linebake::h5::init();  // before anything else touches HDF5 (see h5::init)
  CLI::App app{"linebake " LINEBAKE_VERSION ": assets, exports and renders for large 3D line sets",
               "linebake"};
  app.set_version_flag("--version", LINEBAKE_VERSION);
  app.require_subcommand(1);
  std::vector<std::pair<CLI::App*, Command>> commands;
  for (auto add : {add_info, add_convert, add_synth, add_bake, add_report, add_export, add_render,
                   add_depth_complexity, add_compare, add_bench, add_run, add_view}) {
    const size_t before = app.get_subcommands({}).size();
    Command run = add(app);
    commands.emplace_back(app.get_subcommands({})[before], std::move(run));
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? kOk : kUsage;
  }
  // Every command stops at its next safe point on SIGINT, SIGTERM or SIGHUP, removing its
  // temporary files (core/interrupt.hpp).
  linebake::install_interrupt_handlers();
  try {
    for (auto& [sub, run] : commands)
      if (sub->parsed()) run();
    return kOk;
  } catch (const linebake::Interrupted& e) {
    std::cerr << "linebake: " << e.what() << "; its temporary files are removed\n";
    return 128 + e.signal();
  } catch (const linebake::UsageError& e) {
    std::cerr << "linebake: error: " << e.what() << "\n";
    return kUsage;
  } catch (const linebake::InputError& e) {
    std::cerr << "linebake: error: " << e.what() << "\n";
    return kInput;
  } catch (const linebake::OutputError& e) {
    std::cerr << "linebake: error: " << e.what() << "\n";
    return kOutput;
  } catch (const std::exception& e) {
    std::cerr << "linebake: error: " << e.what() << "\n";
    return kFailure;
  }
}
