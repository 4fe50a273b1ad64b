// linebake run <pipeline>: plans the pipeline's steps (bake, render, compare), runs each as
// a linebake child process in dependency order, reuses steps whose key and outputs are unchanged
// (the state lives in <output>/.linebake-run.json), and writes report.html / report.md /
// report.json and the plots.

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <set>
#include <sstream>
#include <thread>

#include "cli_contract.hpp"
#include "commands.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/hash.hpp"
#include "core/interrupt.hpp"
#include "core/json_file.hpp"
#include "core/nearest.hpp"
#include "core/output_lock.hpp"
#include "flight_plan.hpp"
#include "pipeline/bake.hpp"
#include "pipeline/evaluation_report.hpp"
#include "pipeline/html_report.hpp"
#include "pipeline/pipeline.hpp"
#include "render/camera.hpp"
#include "render/transfer_function.hpp"
#include "render/vulkan/context.hpp"
#include "render/vulkan/raster_renderer.hpp"
#include "synth/synth.hpp"
#include "techniques/technique.hpp"

extern char** environ;

namespace linebake::cli {
namespace {

std::string quoted(const std::vector<std::string>& args) {
  std::string out = "linebake";
  for (const std::string& a : args)
    out += " " + (a.find_first_of(" '\"?&") == std::string::npos ? a : "'" + a + "'");
  return out;
}

// Runs this executable with `args`; stdout to `stdout_file` when given. Returns the exit code.
int run_child(const std::vector<std::string>& args, const std::string& stdout_file) {
  // /proc/self/exe, not the path it links to: a rebuild during a long run replaces the file, and
  // every step should run the same linebake as the first.
  const std::string self = "/proc/self/exe";
  std::string name = "linebake";
  std::vector<char*> argv;
  argv.push_back(name.data());
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  // Its standard output goes to a temporary file (removed unless the step passes), renamed
  // into place once the step exits 0: linebake fails a command whose output could not be
  // written, so that name only ever holds a whole output.
  std::optional<AtomicFile> output;
  if (!stdout_file.empty()) output.emplace(stdout_file);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  if (output)
    posix_spawn_file_actions_addopen(&actions, 1, output->temp_path().c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
  // The step runs in its own process group, so a Ctrl-C at the terminal reaches only this
  // process, which passes it on once: the step stops at its next safe point and cleans up.
  posix_spawnattr_t attributes;
  posix_spawnattr_init(&attributes);
  posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETPGROUP);
  posix_spawnattr_setpgroup(&attributes, 0);
  pid_t pid = 0;
  const int spawned = posix_spawn(&pid, self.c_str(), &actions, &attributes, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attributes);
  if (spawned != 0) throw Error("run: cannot start linebake again (" + self + ")");
  int status = 0;
  bool passed_on = false;
  while (waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) throw Error("run: waitpid failed");
    if (interrupt_signal() && !passed_on) {
      ::kill(pid, interrupt_signal());
      passed_on = true;
    }
  }
  const int code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  if (output && code == 0) output->commit();
  return code;
}

nlohmann::json machine_info() {
  nlohmann::json m;
  std::ifstream cpuinfo("/proc/cpuinfo");
  for (std::string line; std::getline(cpuinfo, line);)
    if (line.rfind("model name", 0) == 0) {
      m["cpu"] = line.substr(line.find(':') + 2);
      break;
    }
  m["cores"] = std::thread::hardware_concurrency();
  std::string devices;
  try {
    for (const vk::DeviceInfo& d : vk::list_devices())
      devices += (devices.empty() ? "" : "; ") + d.name + (d.ray_tracing ? " (ray tracing)" : "");
  } catch (const Error&) {
  }
  m["vulkan"] = devices.empty() ? "none" : devices;
  return m;
}

// Every option of the pipeline, checked as the steps will read it, before any step runs: each
// technique's options through `render`'s own parser (names, values, ranges) and against what the
// technique reads, the bake options through `bake`'s, the transfer functions, the flight and the
// size. Errors name the pipeline file and the JSON path of the bad value.
void validate_pipeline(const Pipeline& p) {
  const auto parse = [&](Command (*add)(CLI::App&), std::vector<std::string> args,
                         const std::string& where) {
    CLI::App scratch;
    const Command keep = add(scratch);  // holds what the options write into
    // A mistyped option name: the nearest one the command has.
    const CLI::App* command = scratch.get_subcommands({}).front();
    std::vector<std::string> names;
    for (const CLI::Option* option : command->get_options())
      for (const std::string& n : option->get_lnames()) names.push_back(n);
    for (const std::string& a : args)
      if (a.rfind("--", 0) == 0 &&
          std::find(names.begin(), names.end(), a.substr(2)) == names.end())
        throw InputError(p.file, where,
                         "unknown option '" + a.substr(2) + "'" + did_you_mean(a.substr(2), names));
    std::reverse(args.begin(), args.end());  // CLI11 takes a vector last argument first
    try {
      scratch.parse(args);
    } catch (const CLI::ParseError& e) {
      throw InputError(p.file, where, e.what());
    }
  };
  // What the pipeline sets on every step's command line itself: given again as an option, the
  // step's command would get it twice.
  const auto refuse_controlled = [&](const std::vector<std::string>& options,
                                     const std::set<std::string>& controlled,
                                     const std::string& where, const std::string& why) {
    for (const std::string& a : options)
      if (a.rfind("--", 0) == 0 && controlled.count(a.substr(2)))
        throw InputError(p.file, where + "." + a.substr(2), why);
  };
  // The pipeline file stands in for the cache, which the bake has not made yet.
  for (size_t i = 0; i < p.techniques.size(); ++i) {
    const PipelineTechnique& t = p.techniques[i];
    const std::string where = "techniques[" + std::to_string(i) + "].options";
    refuse_controlled(t.options,
                      {"output", "technique", "tf", "flight", "frame-count", "frame", "frames",
                       "size", "stats", "json", "depth-complexity", "help", "warm-up"},
                      where,
                      "set by the pipeline for every render (its technique, transfer functions, "
                      "flight, frames, warm_up, size and outputs), not a technique's option");
    std::vector<std::string> options = t.options;
    apply_deprecated_aliases("render", options);
    std::vector<std::string> args = {"render", p.file, "-o", "x.png", "--technique", t.technique};
    args.insert(args.end(), options.begin(), options.end());
    parse(add_render, args, where);
    // Ranges a technique narrows (mlabdb's layers), which the render checks only as it starts.
    if (t.technique == "mlab" || t.technique == "mlabdb")
      for (size_t k = 0; k + 1 < options.size(); ++k)
        if (options[k] == "--layers") {
          const int least = vk::min_layers(vk::parse_raster_technique(t.technique));
          // As CLI11 reads an integer: decimal, 0x hexadecimal, 0 octal.
          if (std::strtol(options[k + 1].c_str(), nullptr, 0) < least)
            throw InputError(p.file, where + ".layers",
                             t.technique + " takes " + std::to_string(least) +
                                 " to 64 layers, not " + options[k + 1]);
        }
    std::vector<std::string> given;
    for (const std::string& a : options)
      if (a.rfind("--", 0) == 0) given.push_back(a.substr(2));
    try {
      check_technique_options(find_technique(t.technique).info, given);
    } catch (const UsageError& e) {
      throw InputError(p.file, where, e.what());
    }
  }
  refuse_controlled(p.bake_options, {"output", "help", "dry-run"}, "assets",
                    "set by the pipeline for every bake (the cache is <output>/<data set>.lbc.h5)");
  std::vector<std::string> bake = {"bake", p.file};
  bake.insert(bake.end(), p.bake_options.begin(), p.bake_options.end());
  parse(add_bake, bake, "assets");
  // What each technique reads of the cache must be baked (a render had failed after the bake).
  const std::vector<std::string> baked = pipeline_assets(p);
  for (size_t i = 0; i < p.techniques.size(); ++i)
    for (const std::string& asset : find_technique(p.techniques[i].technique).info.assets)
      if (asset != "lines" && std::find(baked.begin(), baked.end(), asset) == baked.end())
        throw InputError(p.file, "techniques[" + std::to_string(i) + "]",
                         p.techniques[i].technique + " reads the cache's " + asset +
                             ", which the pipeline's assets do not bake (add it to assets)");
  for (size_t i = 0; i < p.transfer_functions.size(); ++i) try {
      resolve_transfer_function(transfer_function_argument(p, p.transfer_functions[i]));
    } catch (const Error& e) {
      throw InputError(p.file, "transfer_functions[" + std::to_string(i) + "]", e.what());
    }
  if (parse_flight_kind(p.flight) == FlightKind::Keyframes && !std::filesystem::exists(p.flight))
    throw InputError(p.file, "flight",
                     "'" + p.flight + "' is neither orbit-zoom, orbit nor a keyframe file" +
                         did_you_mean(p.flight, {"orbit-zoom", "orbit"}));
  try {
    const auto [width, height] = parse_image_size(p.size);
    if (width < 11 || height < 11)
      throw Error("'" + p.size +
                  "': the report compares frames by SSIM, which needs at least 11x11 pixels");
  } catch (const Error& e) {
    throw InputError(p.file, "size", e.what());
  }
  // Sources as the bake will read them: synthetic ones parsed, files there.
  for (size_t i = 0; i < p.datasets.size(); ++i) {
    const std::string& source = p.datasets[i].source;
    const std::string where = "datasets[" + std::to_string(i) + "].source";
    if (synth::is_synth_source(source)) try {
        synth::parse_synth_source(source);
      } catch (const Error& e) {
        throw InputError(p.file, where, e.what());
      }
    else if (std::error_code ec; !std::filesystem::exists(source, ec))
      throw InputError(p.file, where,
                       "'" + source +
                           "': no such file (a source is found relative to the "
                           "pipeline file)");
  }
}

// `directory` and those above it, made where they are not: what stands in the way is an
// OutputError naming it (std::filesystem's own message had ended the run as exit 4).
void make_directory(const std::filesystem::path& directory) {
  std::error_code ec;
  std::filesystem::create_directories(directory, ec);
  if (ec || !std::filesystem::is_directory(directory))
    throw OutputError(directory.string(), "cannot be made a directory for the run's outputs" +
                                              (ec ? ": " + ec.message() : std::string()));
}

// Before any step runs: every place the run writes is free to be written, so that nothing in the
// output directory (a file where a step's directory goes, a directory where a report goes) fails
// the run after its bakes. A report's directory had been removed when empty and failed the run
// with std::filesystem's message when not.
void check_run_places(const Pipeline& p, const std::vector<PipelineStep>& steps) {
  std::error_code ec;
  const auto in_the_way = [&](const std::filesystem::path& place, bool want_directory) {
    const auto status = std::filesystem::symlink_status(place, ec);
    if (!std::filesystem::exists(status)) return;
    if (want_directory && !std::filesystem::is_directory(std::filesystem::status(place, ec)))
      throw OutputError(place.string(), "is in the way: the run writes a directory here; move it");
    if (!want_directory && std::filesystem::is_directory(status))
      throw OutputError(place.string(), "is a directory where the run writes a file; move it");
  };
  for (const PipelineStep& s : steps)
    for (const std::vector<std::string>* files : {&s.outputs, &s.optional_outputs})
      for (const std::string& o : *files) {
        in_the_way(o, false);
        // Each directory on the way, from the output directory down.
        const std::filesystem::path parent = std::filesystem::path(o).parent_path();
        std::filesystem::path walked;
        for (const auto& part : parent) {
          walked /= part;
          if (walked.string().size() > p.output.size()) in_the_way(walked, true);
        }
      }
  for (const char* report : {"report.html", "report.md", "report.json"})
    in_the_way(p.output + "/" + report, false);
  in_the_way(p.output + "/plots", true);
}

// The run's output directory, made where missing and held for the run: two runs into one
// directory at once would each record their steps over the other's (a later run then reused
// files the other made). An OutputLock on <output>/.linebake-run (its file .linebake-run.lock,
// removed when the run ends), refused rather than waited for; the steps' processes do not
// inherit it.
class OutputDirectoryLock {
 public:
  explicit OutputDirectoryLock(const std::string& output) : lock_(take(output)) {}

 private:
  static std::unique_ptr<OutputLock> take(const std::string& output) {
    std::error_code ec;
    std::filesystem::create_directories(output, ec);
    if (ec || !std::filesystem::is_directory(output))
      throw OutputError(output, "cannot be the run's output directory" +
                                    (ec ? ": " + ec.message() : std::string(": not a directory")));
    try {
      return std::make_unique<OutputLock>(output + "/.linebake-run", OutputLock::Wait::no);
    } catch (const OutputBusy&) {
      throw OutputError(output,
                        "another linebake run is writing into this directory; wait for it to "
                        "end or give another -o");
    }
  }
  std::unique_ptr<OutputLock> lock_;
};

}  // namespace

Command add_run(CLI::App& app) {
  auto* sub = app.add_subcommand(
      "run", "Run a pipeline: bake, render and compare every step, then write the report");
  struct Args {
    std::string pipeline, output;
    bool dry_run = false, force = false;
  };
  auto args = std::make_shared<Args>();
  sub->add_option("pipeline", args->pipeline,
                  "Pipeline file (.json, .yaml; the extension may be left out), or the name of "
                  "a pipeline shipped with linebake: quickstart, ci, paper-small, paper")
      ->required();
  sub->add_option("-o,--output", args->output, "Output directory (default: the pipeline's)");
  sub->add_flag("--dry-run", args->dry_run,
                "List the steps and whether each would run or be reused");
  sub->add_flag("--force", args->force, "Run every step, even unchanged ones");
  return [args] {
    Pipeline p = load_pipeline(find_pipeline(args->pipeline, LINEBAKE_PIPELINES_DIR));
    if (!args->output.empty()) p.output = args->output;
    // One spelling of the directory for the steps' command lines, which their keys hold: "out/p/"
    // and "./out/p" reuse what "out/p" ran.
    p.output = std::filesystem::path(p.output).lexically_normal().string();
    while (p.output.size() > 1 && p.output.back() == '/') p.output.pop_back();
    validate_pipeline(p);
    PlanContext context;
    try {
      for (const vk::DeviceInfo& d : vk::list_devices()) context.ray_tracing |= d.ray_tracing;
    } catch (const Error&) {
      context.vulkan = false;
    }
    context.file_hash = [](const std::string& file) { return hash_file(file); };
    const std::vector<PipelineStep> steps = plan_pipeline(p, context);
    std::optional<OutputDirectoryLock> lock;
    if (!args->dry_run) {
      lock.emplace(p.output);
    } else if (std::error_code ec; std::filesystem::exists(p.output, ec) &&
                                   !std::filesystem::is_directory(p.output, ec)) {
      throw OutputError(p.output, "cannot be the run's output directory: not a directory");
    }
    if (!args->dry_run) check_run_places(p, steps);
    const std::string state_path = p.output + "/.linebake-run.json";
    nlohmann::json state = nlohmann::json::object();
    if (std::ifstream in(state_path); in) {
      try {
        state = nlohmann::json::parse(in);
        if (!state.is_object()) throw std::runtime_error("not an object");
      } catch (const std::exception&) {
        state = nlohmann::json::object();  // unreadable state: run everything again
        std::cerr << "linebake: run: " << state_path << " is unreadable: every step runs again\n";
      }
    }
    // A finished step's record: {"key": its key, "made": the optional outputs it made} (a bare
    // key in the state of earlier versions, which recorded no optional outputs).
    const auto reusable = [&](const PipelineStep& s) {
      if (args->force || !state.contains(s.id)) return false;
      const nlohmann::json& record = state[s.id];
      const nlohmann::json key =
          record.is_object() ? record.value("key", nlohmann::json()) : record;
      if (key != s.key) return false;
      std::vector<std::string> made = s.outputs;
      if (record.is_object() && record.contains("made") && record["made"].is_array())
        for (const nlohmann::json& o : record["made"])
          if (o.is_string()) made.push_back(o.get<std::string>());
      for (const std::string& o : made)
        if (!std::filesystem::exists(o)) return false;
      return true;
    };
    size_t ran = 0, reused = 0, skipped = 0;
    bool reports_removed = false;
    std::map<std::string, std::string> status;  // id -> ran | reused | skipped
    for (const PipelineStep& s : steps) {
      std::string what = !s.skip_reason.empty() ? "skip" : reusable(s) ? "reuse" : "run";
      for (const std::string& d : s.depends)
        if (what == "reuse" && status[d] == "run") what = "run";
      status[s.id] = what;
      if (args->dry_run) {
        std::cout << what << " " << s.id << ": "
                  << (what == "skip" ? s.skip_reason : quoted(s.args)) << "\n";
        continue;
      }
      if (what == "skip") {
        ++skipped;
        std::cerr << "linebake: run: " << s.id << ": skipped (" << s.skip_reason << ")\n";
        continue;
      }
      if (what == "reuse") {
        ++reused;
        continue;
      }
      // The reports describe the outputs as the last whole run left them: once a step is to
      // change those, they go (a failed or interrupted run leaves none, not a stale one).
      if (!reports_removed) {
        std::vector<std::string> reports;
        for (const char* report : {"report.html", "report.md", "report.json"})
          reports.push_back(p.output + "/" + report);
        // And their plots (an interrupted run had left the last run's beside no report).
        std::error_code listed;
        for (const auto& entry : std::filesystem::directory_iterator(p.output + "/plots", listed))
          if (entry.path().extension() == ".svg") reports.push_back(entry.path().string());
        for (const std::string& report : reports)
          if (std::error_code ec; !std::filesystem::remove(report, ec) && ec)
            throw OutputError(report, "cannot remove the last run's report: " + ec.message());
        reports_removed = true;
      }
      // The step's record goes before its outputs change: interrupted or failed, it runs again
      // next time (its record had stood beside its half-replaced outputs, and was reused).
      if (state.contains(s.id)) {
        state.erase(s.id);
        write_file_atomically(state_path, json_text(state, 1) + "\n");
      }
      for (const std::string& o : s.outputs) make_directory(std::filesystem::path(o).parent_path());
      // What it may make is known once it ran: none of an earlier run's may be taken for its own.
      for (const std::string& o : s.optional_outputs)
        if (std::error_code ec; !std::filesystem::remove(o, ec) && ec)
          throw OutputError(o, "cannot remove the last run's output: " + ec.message());
      std::cerr << "linebake: run: " << s.id << "\n";
      throw_if_interrupted();
      const int code = run_child(s.args, s.stdout_file);
      if (interrupt_signal())
        throw Interrupted(interrupt_signal(),
                          "at step " + s.id + "; the " + std::to_string(ran + reused) +
                              " step(s) run or reused before it are kept for the next run");
      if (code != 0)
        throw Error("run: step " + s.id + " failed (exit " + std::to_string(code) +
                    "): " + quoted(s.args) + "; finished outputs are kept in " + p.output);
      nlohmann::json made = nlohmann::json::array();
      for (const std::string& o : s.optional_outputs)
        if (std::filesystem::exists(o)) made.push_back(o);
      state[s.id] = {{"key", s.key}, {"made", made}};
      write_file_atomically(state_path, json_text(state, 1) + "\n");
      ++ran;
    }
    if (args->dry_run) return;
    const std::vector<CacheSummary> caches = pipeline_caches(p);
    const nlohmann::json evaluation = evaluation_json(p, caches, steps, machine_info());
    // The reports and their plots are renamed into place together, or none is: never a new
    // report.json beside an old report.html.
    OutputGroup reports;
    write_file_atomically(p.output + "/report.json", json_text(evaluation, 2) + "\n");
    const std::map<std::string, std::string> plots = evaluation_plots(p, evaluation);
    make_directory(p.output + "/plots");
    for (const auto& [name, svg] : plots) write_file_atomically(p.output + "/plots/" + name, svg);
    write_file_atomically(p.output + "/report.md", evaluation_markdown(p, caches, evaluation));
    write_file_atomically(p.output + "/report.html", evaluation_html(p, caches, evaluation, plots));
    reports.commit();
    std::cerr << "linebake: run: " << ran << " step(s) run, " << reused << " reused, " << skipped
              << " skipped\n";
    std::cout << p.output << "/report.html\n" << p.output << "/report.md\n";
  };
}

}  // namespace linebake::cli
