#pragma once
// "Did you mean": the known name nearest to a mistyped one, for error messages.

#include <string>
#include <vector>

namespace linebake {

// Levenshtein distance between two names.
size_t edit_distance(const std::string& a, const std::string& b);
// "; did you mean 'NAME'?" for the known name within two edits of `given` (the nearest, the
// first of equals), else "".
std::string did_you_mean(const std::string& given, const std::vector<std::string>& known);

}  // namespace linebake
