#pragma once
// JSON files users write by hand (transfer functions, keyframes, pipelines): parsed, and every
// way nlohmann::json can refuse them (bad syntax, a number past double's range, invalid UTF-8,
// a value of the wrong type while parsing) turned into an InputError naming the file and, where
// known, the byte offset. And JSON text as linebake writes it (stats, reports, cache metadata).

#include <nlohmann/json.hpp>
#include <string>

#include "core/error.hpp"

namespace linebake {

// Throws InputError: "cannot open the WHAT", or not valid JSON at a byte offset.
nlohmann::json read_json_file(const std::string& path, const std::string& what);

// `value` as JSON text, compact (indent -1) or indented. A string that is not UTF-8 (a Linux
// file name may be any bytes) is written with U+FFFD in place of its bad bytes, where
// nlohmann::json's dump() would throw: such strings are only ever shown, never looked up.
std::string json_text(const nlohmann::json& value, int indent = -1);

}  // namespace linebake
