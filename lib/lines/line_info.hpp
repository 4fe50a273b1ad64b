#pragma once
// The `info --json` document of a line set (schema in docs/cli.md): what the CLI prints and
// what the Python module's LineSet.info() returns, from one place.

#include <map>
#include <nlohmann/json.hpp>
#include <string>

#include "lines/line_set.hpp"
#include "lines/validate.hpp"

namespace linebake {

// `source` and `format` empty: null in the document (a line set built in memory).
nlohmann::json line_set_info(const LineSet& lines, const std::string& source,
                             const std::string& format);
// The same document from statistics and a validation report gathered batch by batch (a line
// set read piece by piece, never held whole).
nlohmann::json line_set_info(const LineSetStats& stats, const ValidationReport& validation,
                             const std::map<std::string, std::string>& metadata,
                             const std::string& source, const std::string& format);

}  // namespace linebake
