#pragma once
// JSON files users write by hand (transfer functions, keyframes, pipelines): parsed, and every
// way nlohmann::json can refuse them (bad syntax, a number past double's range, invalid UTF-8,
// a value of the wrong type while parsing) turned into an InputError naming the file and, where
// known, the byte offset.

#include <nlohmann/json.hpp>
#include <string>

#include "core/error.hpp"

namespace linebake {

// Throws InputError: "cannot open the WHAT", or not valid JSON at a byte offset.
nlohmann::json read_json_file(const std::string& path, const std::string& what);

}  // namespace linebake
