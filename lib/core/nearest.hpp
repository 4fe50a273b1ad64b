#pragma once
// Known names in error messages: their list, and "did you mean" the one nearest to a mistyped
// name.

#include <string>
#include <vector>

namespace linebake {

// The names as a message lists them: "a, b, c" ("" for none).
std::string name_list(const std::vector<std::string>& names);
// Levenshtein distance between two names.
size_t edit_distance(const std::string& a, const std::string& b);
// "; did you mean 'NAME'?" for the known name within two edits of `given` (the nearest, the
// first of equals), else "".
std::string did_you_mean(const std::string& given, const std::vector<std::string>& known);

}  // namespace linebake
