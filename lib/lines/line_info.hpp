#pragma once
// The `info --json` document of a line set (schema in docs/cli.md): what the CLI prints and
// what the Python module's LineSet.info() returns, from one place.

#include <nlohmann/json.hpp>
#include <string>

#include "lines/line_set.hpp"

namespace linebake {

// `source` and `format` empty: null in the document (a line set built in memory).
nlohmann::json line_set_info(const LineSet& lines, const std::string& source,
                             const std::string& format);

}  // namespace linebake
