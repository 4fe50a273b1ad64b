#pragma once
// The radius and attribute of curves and capsules over the lines, shared by embree and rtx
// (lib/techniques).

#include <optional>
#include <string>
#include <utility>

#include "cache/cache.hpp"
#include "lines/line_set.hpp"

namespace linebake {

// The flags, else the cached tubes' (from their provenance), else 0.001 x the diagonal and the
// first vertex attribute.
std::pair<float, std::string> curve_defaults(float radius, std::string attribute,
                                             const std::optional<Provenance>& tube_provenance,
                                             const LineSet& lines);

}  // namespace linebake
