#pragma once
// What every linebake command shares on the command line (docs/cli.md, "One contract"): checks
// that state ranges in plain numbers, the deprecated spellings and what replaced them, options
// that belong to something the user did not ask for, inputs that must exist (exit 2 in every
// command), and one voice on stderr ("linebake: error:", "linebake: warning:").

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

namespace linebake::cli {

// Finite numbers only (CLI11's own checks take inf and nan, and print DBL_MAX in full).
CLI::Validator positive();                    // > 0
CLI::Validator positive_float();              // > 0, at most float's largest
CLI::Validator non_negative();                // >= 0
CLI::Validator within(double lo, double hi);  // lo..hi, both included
CLI::Validator unsigned_integer();            // no sign: CLI11 takes "-1" as 2^64 - 1
CLI::Validator byte_size();                   // 2G, 1.5GiB, 512M, 4096, unlimited
CLI::Validator memory_budget_size();          // byte_size, and not 0 (unlimited is the word)
// A voxel grid: auto, N or NxNxN (parse_grid's rule).
CLI::Validator grid_check();
// One of `names`; else the list and the nearest ("did you mean").
CLI::Validator one_of(const std::vector<std::string>& names);
// --origin (lines/origin.hpp): "auto" or X,Y,Z.
CLI::Validator origin_value();
// --origin's help, the same in every command that reads lines.
inline constexpr const char* kOriginHelp =
    "Keep positions relative to this origin, subtracted in double before float32 (for UTM or "
    "ECEF coordinates): X,Y,Z, or auto (the first valid point, rounded); exports add it back";
// The numbers `linebake bake` takes (--tube-sides, --radius, --compression-level, --chunk-bytes,
// --quantization, --max-chords, --embree-max-primitives): its options and the Python module's
// bake() check them alike. std::logic_error for another option.
const CLI::Validator& bake_number_check(const std::string& option);
// "" when `value` (as on the command line) passes the option's check, else "OPTION: " and the
// CLI's message.
std::string bake_number_problem(const std::string& option, const std::string& value);

// An old spelling kept for one release: `command` ("render", "bench", ...; "" for any), the old
// option (or technique value) and its replacement ("" when the value becomes a positional).
struct DeprecatedAlias {
  const char* command;
  const char* old_spelling;
  const char* replacement;
};
const std::vector<DeprecatedAlias>& deprecated_aliases();
// Rewrites old spellings in the arguments of `command` (which follow it in `args`) to the new
// ones, warning once for each on stderr. `--opt=value` forms are rewritten too.
void apply_deprecated_aliases(const std::string& command, std::vector<std::string>& args);

// A list option: items separated by commas in one value, or the option given again
// ("--techniques ll,tiles", "--techniques ll --techniques tiles"), in `items` in that order. An
// empty item ("ll,", "ll,,tiles", "") is a usage error naming the option: CLI11's own delimiter
// dropped empty items, and an option whose items were all empty (",") took the next argument
// ("--frames") as its value.
CLI::Option* add_list_option(CLI::App* sub, const std::string& name,
                             std::vector<std::string>& items, const std::string& description);

// Long names (without "--") of the options given on the command line.
std::vector<std::string> given_options(const CLI::App* sub);
bool given(const CLI::App* sub, const std::string& name);
// UsageError naming those of `names` that were given, unless `applies`: "--draco-bits: read only
// with --draco".
void refuse_unless(const CLI::App* sub, const std::vector<std::string>& names, bool applies,
                   const std::string& when);

// Runs `check` as soon as the command line is parsed, before the command runs (and when `run`
// validates a pipeline's steps with the command's parser): a UsageError it throws is a parse
// error, exit 1.
void check_when_parsed(CLI::App* sub, std::function<void()> check);

// A UsageError naming the first option of a parsed command (or a subcommand of it) given an
// empty value ("-o ''", "--stats ''"): it names no file and no setting. Each command had taken
// one its own way (ignored it, failed on its format, said the option was missing).
void refuse_empty_values(const CLI::App& app);

// InputError (exit 2) when `path` does not exist or is a directory, a FIFO or a socket; synth:
// sources pass.
void check_input_file(const std::string& path);
// check_input_file, and an InputError saying what the file is when it is not a linebake cache
// ("a line file (binlines): bake it first: linebake bake c.binlines").
void check_cache_input(const std::string& path);

// CLI11's parse errors in the voice of every other error: "PROGRAM: error: MESSAGE" and the
// command whose --help lists the options (linebake, linebake-mpi).
void speak_with_one_voice(CLI::App& app, const std::string& program);

// One voice on stderr.
void say(const std::string& message);   // "linebake: MESSAGE"
void warn(const std::string& message);  // "linebake: warning: MESSAGE"
// "wrote c.glb (12.3 MiB) in 1.84 s": what a command that writes files leaves on the terminal.
void say_wrote(const std::string& path, double seconds);
// Seconds rounded to what they mean: 3 significant digits ("0.0949 s", "12.3 s", "184 s").
std::string format_seconds(double seconds);
// The median: the middle value, or the mean of the middle two of an even count (0 for none).
// Every command's "median" (render's frames, bench's runs and frames) is this one.
double median(std::vector<double> values);

}  // namespace linebake::cli
