#pragma once
// Validation of a line set: every problem is counted and reported, never silently dropped.

#include <cstdint>
#include <string>
#include <vector>

#include "lines/line_set.hpp"

namespace linebake {

enum class InvalidPolicy {
  reject,  // any problem is an error
  repair,  // drop bad points (splitting lines there), repeated points, short lines; report it
};

struct ValidationReport {
  uint64_t invalid_points = 0;   // NaN/Inf or |c| > kMaxCoordinate
  uint64_t repeated_points = 0;  // equal to the previous point of the same line
  uint64_t short_lines = 0;      // fewer than 2 points (after the repairs above)
  uint64_t bad_offsets = 0;      // offsets not starting at 0, decreasing, or past the end
  std::vector<std::string> attribute_length_mismatches;  // names; vertex and line attributes
  uint64_t nonfinite_attribute_values = 0;  // reported only: a transfer function may map them
  // Where the first invalid point, repeated point or short line is ("line 7, point 2 (of 0..):
  // ..."), lines counted from the `line_base` given; "" when there is none.
  std::string first_problem;

  // What repair changed.
  uint64_t lines_split = 0;
  uint64_t lines_dropped = 0;
  uint64_t points_dropped = 0;
  uint64_t attributes_dropped = 0;
  bool repaired = false;

  // Adds the counts of a report on another batch of the same line set (a streamed read).
  void add(const ValidationReport& batch);
  // True when nothing needs repair (nonfinite attribute values do not count).
  bool clean() const;
  std::string summary() const;  // one line, counts of every non-zero category
};

// Counts problems, changes nothing. `line_base`: the number of the set's first line in messages
// (a batch's place in the whole line set).
ValidationReport inspect(const LineSet& lines, uint64_t line_base = 0);

// Applies the policy. reject: throws InputError(source, the summary and the first problem's
// place) unless clean. repair: fixes `lines` in place and returns what was done.
ValidationReport validate(LineSet& lines, InvalidPolicy policy, const std::string& source,
                          uint64_t line_base = 0);

InvalidPolicy parse_invalid_policy(const std::string& name);

}  // namespace linebake
