#include "cli_contract.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <limits>
#include <set>

#include "cache/cache.hpp"
#include "core/error.hpp"
#include "core/h5.hpp"
#include "core/h5_probe.hpp"
#include "core/memory_budget.hpp"
#include "core/nearest.hpp"
#include "formats/registry.hpp"
#include "synth/synth.hpp"
#include "voxels/voxelizer.hpp"

namespace linebake::cli {

namespace {

std::string plain(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.10g", value);
  return text;
}

// A number CLI11 will convert; "" when it is one and passes `ok`, else the message.
CLI::Validator number_check(const std::string& description, const std::function<bool(double)>& ok) {
  return CLI::Validator(
      [description, ok](std::string& text) -> std::string {
        double value = 0;
        size_t used = 0;
        try {
          value = std::stod(text, &used);
        } catch (const std::out_of_range&) {
          return text + " is out of range: expected " + description;
        } catch (const std::exception&) {
          return "'" + text + "' is not a number";
        }
        if (used != text.size()) return "'" + text + "' is not a number";
        if (!std::isfinite(value) || !ok(value))
          return text + " is out of range: expected " + description;
        return {};
      },
      description);
}

}  // namespace

CLI::Validator positive() {
  return number_check("a number > 0", [](double v) { return v > 0; });
}

CLI::Validator positive_float() {
  return number_check("a number > 0 that a float holds (up to 3.4e38)", [](double v) {
    return v > 0 && v <= double(std::numeric_limits<float>::max());
  });
}

CLI::Validator non_negative() {
  return number_check("a number >= 0", [](double v) { return v >= 0; });
}

CLI::Validator within(double lo, double hi) {
  return number_check(plain(lo) + " to " + plain(hi),
                      [lo, hi](double v) { return v >= lo && v <= hi; });
}

CLI::Validator unsigned_integer() {
  return CLI::Validator(
      // Decimal digits only, as synth:NAME?seed=N takes them: CLI11 would take "0x10" as 16 and
      // clamp a number past 2^64 - 1 to it.
      [](std::string& text) -> std::string {
        uint64_t value = 0;
        const char* end = text.data() + text.size();
        const auto r = std::from_chars(text.data(), end, value);
        if (!text.empty() && text[0] == '-') return "Value " + text + " not in range 0 to 2^64 - 1";
        if (r.ptr != end || r.ec == std::errc::invalid_argument)
          return "Value " + text + " is not an unsigned decimal integer";
        if (r.ec != std::errc()) return "Value " + text + " not in range 0 to 2^64 - 1";
        return "";
      },
      "UINT");
}

CLI::Validator byte_size() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        if (text == "unlimited") return {};
        try {
          parse_size(text);
        } catch (const std::exception& e) {
          return e.what();
        }
        return {};
      },
      "SIZE");
}

CLI::Validator memory_budget_size() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        if (text == "unlimited") return {};
        try {
          if (parse_size(text) == 0) return kZeroBudget;
        } catch (const std::exception& e) {
          return e.what();
        }
        return {};
      },
      "SIZE");
}

CLI::Validator grid_check() {
  return CLI::Validator(
      [](std::string& text) {
        VoxelOptions v;
        try {
          parse_grid(text, v);
        } catch (const std::exception& e) {
          const std::string message = e.what();  // CLI11 names the option itself
          return message.rfind("--grid: ", 0) == 0 ? message.substr(8) : message;
        }
        return std::string();
      },
      "GRID");
}

CLI::Validator one_of(const std::vector<std::string>& names) {
  const std::string list = name_list(names);
  return CLI::Validator(
      [names, list](std::string& text) -> std::string {
        if (std::find(names.begin(), names.end(), text) != names.end()) return {};
        return "unknown '" + text + "' (" + list + ")" + did_you_mean(text, names);
      },
      "{" + list + "}");
}

CLI::Validator origin_value() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        if (text == "auto" || parse_origin(text)) return {};
        return "'" + text + "' is not auto nor X,Y,Z (three finite numbers)";
      },
      "auto|X,Y,Z");
}

const std::vector<DeprecatedAlias>& deprecated_aliases() {
  // The spelling each concept has in every command: an asset's or technique's options carry its
  // name (bake's spelling), inputs are positional, outputs are -o.
  static const std::vector<DeprecatedAlias> table = {
      {"render", "--geometry", "--embree-geometry"},
      {"render", "--quality", "--embree-quality"},
      {"render", "--rt-geometry", "--rtx-geometry"},
      {"render", "--no-compaction", "--rtx-no-compaction"},
      {"bench", "--geometry", "--embree-geometry"},
      {"bench", "--quality", "--embree-quality"},
      {"bench", "--input", ""},
  };
  return table;
}

namespace {

// bench once took its step as a positional anywhere among the options (`bench --input x tubes`);
// the step is now a subcommand, so options given before it move behind it. The step is the first
// of the names that is not the value of the option before it (every option before it takes a
// value except the flags). Warns, as every deprecated spelling does, where it moved any.
void move_options_behind_bench_step(std::vector<std::string>& args) {
  static const std::vector<std::string> steps = {"tubes", "voxels", "embree", "bake", "render"};
  static const std::vector<std::string> flags = {"--json", "--keep", "-h", "--help"};
  const auto takes_value = [](const std::string& arg) {
    return arg.size() > 1 && arg[0] == '-' && arg.find('=') == std::string::npos &&
           std::find(flags.begin(), flags.end(), arg) == flags.end();
  };
  for (size_t i = 0; i < args.size(); ++i) {
    if (i > 0 && takes_value(args[i - 1])) continue;
    if (std::find(steps.begin(), steps.end(), args[i]) == steps.end()) continue;
    if (i == 0) return;
    std::cerr << "linebake: warning: bench options before the step (" << args[0]
              << ") are deprecated; give them after it: linebake bench " << args[i]
              << " ... (docs/cli.md, deprecated spellings)\n";
    std::rotate(args.begin(), args.begin() + i, args.begin() + i + 1);
    return;
  }
}

}  // namespace

void apply_deprecated_aliases(const std::string& command, std::vector<std::string>& args) {
  if (command == "bench") move_options_behind_bench_step(args);
  std::set<std::string> warned;
  std::vector<std::string> out;
  for (const std::string& arg : args) {
    const size_t eq = arg.find('=');
    const std::string name = arg.rfind("--", 0) == 0 ? arg.substr(0, eq) : "";
    const DeprecatedAlias* alias = nullptr;
    for (const DeprecatedAlias& a : deprecated_aliases())
      if (!name.empty() && command == a.command && name == a.old_spelling) alias = &a;
    if (!alias) {
      out.push_back(arg);
      continue;
    }
    const std::string replacement = alias->replacement;
    if (warned.insert(name).second)
      std::cerr << "linebake: warning: " << command << " " << name << " is deprecated; "
                << (replacement.empty() ? std::string("give the value as a positional argument")
                                        : "use " + replacement)
                << " (docs/cli.md, deprecated spellings)\n";
    if (replacement.empty()) {
      if (eq != std::string::npos) out.push_back(arg.substr(eq + 1));
    } else {
      out.push_back(replacement + (eq == std::string::npos ? "" : arg.substr(eq)));
    }
  }
  args = std::move(out);
}

CLI::Option* add_list_option(CLI::App* sub, const std::string& name,
                             std::vector<std::string>& items, const std::string& description) {
  // The long name the messages use ("-t,--techniques": "--techniques").
  std::string label = name;
  for (std::size_t at = 0; at < name.size();) {
    const std::size_t comma = std::min(name.find(',', at), name.size());
    if (name.compare(at, 2, "--") == 0) label = name.substr(at, comma - at);
    at = comma + 1;
  }
  return sub->add_option_function<std::vector<std::string>>(
      name,
      [&items, label](const std::vector<std::string>& values) {
        items.clear();
        for (const std::string& value : values) {
          if (value.empty()) continue;  // refuse_empty_values names it
          for (std::size_t at = 0;;) {
            const std::size_t comma = std::min(value.find(',', at), value.size());
            if (comma == at)
              throw CLI::ValidationError(label + ": an empty item in '" + value +
                                         "'; name one between each two commas, and none "
                                         "before the first or after the last");
            items.push_back(value.substr(at, comma - at));
            if (comma == value.size()) break;
            at = comma + 1;
          }
        }
      },
      description);
}

std::vector<std::string> given_options(const CLI::App* sub) {
  std::vector<std::string> names;
  for (const CLI::Option* option : sub->get_options())
    if (option->count() > 0 && !option->get_lnames().empty())
      names.push_back(option->get_lnames().front());
  return names;
}

bool given(const CLI::App* sub, const std::string& name) {
  for (const std::string& n : given_options(sub))
    if (n == name) return true;
  return false;
}

void refuse_unless(const CLI::App* sub, const std::vector<std::string>& names, bool applies,
                   const std::string& when) {
  if (applies) return;
  std::string list;
  for (const std::string& name : names)
    if (given(sub, name)) list += (list.empty() ? "--" : ", --") + name;
  if (!list.empty()) throw UsageError(list + ": read only " + when);
}

namespace {

// An empty value of one of `sub`'s own options: a UsageError naming it.
void refuse_empty_values_of(const CLI::App* sub) {
  for (const CLI::Option* option : sub->get_options()) {
    if (option->count() == 0 || option->get_type_size_max() == 0) continue;  // flags
    const auto& results = option->results();
    if (std::find(results.begin(), results.end(), std::string()) == results.end()) continue;
    if (option->get_snames().empty() && option->get_lnames().empty())  // a positional
      throw UsageError(option->get_name(true) + ": an empty value names no file");
    const std::string name = !option->get_snames().empty() ? "-" + option->get_snames()[0]
                                                           : "--" + option->get_lnames()[0];
    throw UsageError(name + ": an empty value names no file and no setting; give one, or leave " +
                     name + " out");
  }
}

}  // namespace

void check_when_parsed(CLI::App* sub, std::function<void()> check) {
  sub->parse_complete_callback([sub, check = std::move(check)] {
    try {
      // First, as refuse_empty_values would after the parse: convert's check had said "-o OUT
      // is required" of -o '', export's "export writes .glb ..." of its empty name.
      refuse_empty_values_of(sub);
      check();
    } catch (const UsageError& e) {
      throw CLI::ValidationError(e.what());
    }
  });
}

void refuse_empty_values(const CLI::App& app) {
  for (const CLI::App* sub : app.get_subcommands()) {
    refuse_empty_values_of(sub);
    refuse_empty_values(*sub);
  }
}

void check_input_file(const std::string& path) {
  if (synth::is_synth_source(path)) return;
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  // A directory on the way that may not be searched reads as "not found" to exists(): name it.
  if (ec && ec != std::errc::no_such_file_or_directory && ec != std::errc::not_a_directory)
    throw InputError(path, "", ec.message());
  if (!std::filesystem::exists(status)) throw InputError(path, "", "no such file");
  if (std::filesystem::is_directory(status))
    throw InputError(path, "", "is a directory, not a file");
  // Every reader reads by offset, some more than once (a header first, HDF5 anywhere): a pipe
  // has no offsets, and opening a FIFO with no writer waits for one (a signal restarted that wait
  // or failed it as "cannot open: Interrupted system call"; <(...) read as an empty file).
  if (std::filesystem::is_fifo(status) || std::filesystem::is_socket(status))
    throw InputError(path, "",
                     std::string("is a ") +
                         (std::filesystem::is_fifo(status) ? "FIFO (a pipe)" : "socket") +
                         ", not a file: linebake reads its inputs by offset; write it to a file "
                         "first");
}

void check_cache_input(const std::string& path) {
  if (synth::is_synth_source(path))
    throw InputError(path, "",
                     "a synthetic line source, not a linebake cache; bake it first: linebake "
                     "bake '" +
                         path + "' -o NAME.lbc.h5");
  check_input_file(path);
  // Every caller reads the cache next, which walks the whole file in an isolated child first
  // (core/h5_probe.hpp): walking it whole here makes that one walk, not two (the root's, then
  // the whole file's).
  if (h5::is_hdf5_file(path)) h5::probe(path, {"/"});
  // A damaged cache is left to the cache reader, which names the dataset.
  if (is_linebake_cache(path)) return;
  if (h5::is_hdf5_file(path))
    throw InputError(path, "",
                     "an HDF5 file without the linebake_cache_format attribute, not a linebake "
                     "cache; bake it first: linebake bake " +
                         path);
  const auto format = format_from_extension(path);
  if (format && *format != Format::hdf5)
    throw InputError(path, "",
                     std::string("a line file (") + format_info(*format).name +
                         "), not a linebake cache; bake it first: linebake bake " + path);
}

void speak_with_one_voice(CLI::App& app, const std::string& program) {
  app.failure_message([program](const CLI::App* failed, const CLI::Error& e) {
    std::string command = failed->get_name();
    for (const CLI::App* sub = failed; sub;) {
      const CLI::App* next = nullptr;
      for (const CLI::App* s : sub->get_subcommands())
        if (s->parsed()) next = s;
      if (next) command += " " + next->get_name();
      sub = next;
    }
    return program + ": error: " + std::string(e.what()) + "\n(" + command +
           " --help lists the options)\n";
  });
}

void say(const std::string& message) {
  std::cerr << "linebake: " << message << "\n";
}

void warn(const std::string& message) {
  std::cerr << "linebake: warning: " << message << "\n";
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::string format_seconds(double seconds) {
  char text[32];
  if (seconds >= 100)
    std::snprintf(text, sizeof text, "%.0f s", seconds);
  else
    std::snprintf(text, sizeof text, "%.3g s", seconds);
  return text;
}

void say_wrote(const std::string& path, double seconds) {
  std::error_code ec;
  const uint64_t bytes = std::filesystem::file_size(path, ec);
  say("wrote " + path + (ec ? std::string() : " (" + format_bytes(bytes) + ")") + " in " +
      format_seconds(seconds));
}

const CLI::Validator& bake_number_check(const std::string& option) {
  static const std::vector<std::pair<std::string, CLI::Validator>> table = {
      {"--tube-sides", CLI::Range(3, 32)},
      {"--radius", positive_float()},
      {"--compression-level", CLI::Range(1, 9)},
      {"--chunk-bytes", CLI::Range(uint64_t{1024}, uint64_t{1} << 40)},
      {"--quantization", CLI::IsMember({16, 32, 64})},
      {"--max-chords", CLI::Range(1, 65535)},
      {"--embree-max-primitives", CLI::Range(uint64_t{1}, uint64_t{0xFFFFFFFF})},
  };
  for (const auto& [name, check] : table)
    if (name == option) return check;
  throw std::logic_error("bake_number_check: no check for " + option);
}

std::string bake_number_problem(const std::string& option, const std::string& value) {
  std::string text = value;
  std::string problem;
  try {
    problem = bake_number_check(option)(text);
  } catch (const CLI::ValidationError& e) {  // as CLI11's Option::_validate reports it
    problem = e.what();
  }
  return problem.empty() ? "" : option + ": " + problem;
}

}  // namespace linebake::cli
