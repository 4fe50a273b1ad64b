#pragma once
// Attributes derived from the geometry, computed on demand.

#include <string>
#include <vector>

#include "lines/line_set.hpp"

namespace linebake {

// Per-point attributes:
//   segment_length   length of the segment leaving the point (the last point repeats the
//                    previous segment's length)
//   arc_length       distance along the line from its first point
//   curvature        1/R of the circle through the point and its two neighbours (exact for points
//                    on a circle); line ends copy their neighbour's value
//   index_along_line 0, 1, 2, ... within each line
// Per-line attribute:
//   line_length      total length of the line
// All sums are done in double and rounded once to float32.
const std::vector<std::string>& derived_attribute_names();
bool is_line_attribute(const std::string& derived_name);

// Throws Error for an unknown name.
Attribute derive_attribute(const LineSet& lines, const std::string& name);

}  // namespace linebake
