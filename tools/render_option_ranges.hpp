#pragma once
// The values `linebake render`'s options take, in one place: tools/cmd_render.cpp attaches these
// checks to its options, and the Python module (python/src/rendering.cpp) runs the same checks on
// render()'s and Renderer's arguments, so the two take the same values and refuse the rest with
// the same message.

#include <CLI/CLI.hpp>
#include <array>
#include <optional>
#include <string>
#include <vector>

namespace linebake::cli {

struct RenderOptionCheck {
  std::string option;    // the long option: "--layers"
  CLI::Validator check;  // CLI11's check, as `linebake render` attaches it (a real range
                         // refuses NaN too)
};

// Every option of `linebake render` whose value is checked, with its check.
const std::vector<RenderOptionCheck>& render_option_checks();

// The check of `option` ("--layers"); std::logic_error for an option that has none.
const CLI::Validator& render_option_check(const std::string& option);

// "" when `value` (the value's text, as on the command line) passes `option`'s check, else the
// CLI's message: "--layers: Value 0 not in range 1 to 64", "--beta: Value nan not in range
// 0.000000 to 1.000000". An option without a check passes.
std::string render_option_problem(const std::string& option, const std::string& value);

}  // namespace linebake::cli
