#include "lines/validate.hpp"

#include <cmath>
#include <cstdio>

#include "core/error.hpp"

namespace linebake {

namespace {

bool same_point(const float* a, const float* b) {
  return a[0] == b[0] && a[1] == b[1] && a[2] == b[2];
}

bool offsets_consistent(const LineSet& lines) {
  const auto& o = lines.line_offsets;
  if (o.empty() || o.front() != 0 || o.back() != lines.point_count()) return false;
  for (size_t i = 1; i < o.size(); ++i)
    if (o[i] < o[i - 1]) return false;
  return true;
}

// The repaired line set as index lists: which points survive, and the new lines.
struct RepairPlan {
  std::vector<uint64_t> kept_points;
  std::vector<uint64_t> offsets{0};
  std::vector<uint64_t> source_line;  // original line of each new line
};

std::string coordinates(const float* p) {
  char text[96];
  std::snprintf(text, sizeof text, "(%g, %g, %g)", double(p[0]), double(p[1]), double(p[2]));
  return text;
}

// Walks every line once; fills the report's counts, and the plan when one is given.
void walk(const LineSet& lines, ValidationReport& report, RepairPlan* plan, uint64_t line_base) {
  std::vector<uint64_t> piece;
  // The first problem's place, in the words of the set's lines and their points.
  const auto first = [&](size_t line, const std::string& what) {
    if (report.first_problem.empty())
      report.first_problem = "line " + std::to_string(line_base + line) + what;
  };
  const auto point_of = [&](size_t line, uint64_t i) {
    return ", point " + std::to_string(i - lines.line_offsets[line]) + " (from 0)";
  };
  for (size_t line = 0; line < lines.line_count(); ++line) {
    uint64_t pieces_kept = 0;
    bool broken = false;  // an invalid point split this line
    auto close_piece = [&] {
      if (piece.size() >= 2) {
        ++pieces_kept;
        if (plan) {
          plan->kept_points.insert(plan->kept_points.end(), piece.begin(), piece.end());
          plan->offsets.push_back(plan->kept_points.size());
          plan->source_line.push_back(line);
        }
      } else {
        ++report.short_lines;
        report.points_dropped += piece.size();
        first(line, broken ? ": a piece of " + std::to_string(piece.size()) +
                                 " point(s) between invalid points"
                           : ": fewer than 2 distinct points");
      }
      piece.clear();
    };
    for (uint64_t i = lines.line_offsets[line]; i < lines.line_offsets[line + 1]; ++i) {
      const float* p = &lines.positions[3 * i];
      if (!valid_point(p)) {
        first(line, point_of(line, i) + ": " + coordinates(p) +
                        ", a NaN/Inf coordinate or one past 1e10");
        ++report.invalid_points;
        ++report.points_dropped;
        if (!piece.empty()) close_piece();
        broken = true;
        continue;
      }
      if (!piece.empty() && same_point(&lines.positions[3 * piece.back()], p)) {
        first(line, point_of(line, i) + ": " + coordinates(p) + ", the same as the point before");
        ++report.repeated_points;
        ++report.points_dropped;
        continue;
      }
      piece.push_back(i);
    }
    if (!piece.empty() || !broken) close_piece();
    if (pieces_kept == 0) ++report.lines_dropped;
    if (pieces_kept > 1) report.lines_split += pieces_kept - 1;
  }
}

void check_attribute_lengths(const LineSet& lines, ValidationReport& report) {
  for (const Attribute& a : lines.attributes) {
    if (a.values.size() != lines.point_count())
      report.attribute_length_mismatches.push_back(a.name);
    for (float v : a.values) report.nonfinite_attribute_values += !std::isfinite(v);
  }
  for (const Attribute& a : lines.line_attributes) {
    if (a.values.size() != lines.line_count()) report.attribute_length_mismatches.push_back(a.name);
    for (float v : a.values) report.nonfinite_attribute_values += !std::isfinite(v);
  }
}

template <typename Index>
std::vector<float> gather(const std::vector<float>& values, const std::vector<Index>& indices,
                          size_t stride) {
  std::vector<float> out(indices.size() * stride);
  for (size_t i = 0; i < indices.size(); ++i)
    for (size_t k = 0; k < stride; ++k) out[i * stride + k] = values[indices[i] * stride + k];
  return out;
}

}  // namespace

void ValidationReport::add(const ValidationReport& r) {
  invalid_points += r.invalid_points;
  repeated_points += r.repeated_points;
  short_lines += r.short_lines;
  nonfinite_attribute_values += r.nonfinite_attribute_values;
  if (first_problem.empty()) first_problem = r.first_problem;
  lines_split += r.lines_split;
  lines_dropped += r.lines_dropped;
  points_dropped += r.points_dropped;
  repaired |= r.repaired;
}

bool ValidationReport::clean() const {
  return invalid_points == 0 && repeated_points == 0 && short_lines == 0 && bad_offsets == 0 &&
         attribute_length_mismatches.empty();
}

namespace {
// Appends "n what" to a comma-separated list when n is not zero.
void append_count(std::string& list, uint64_t n, const std::string& what) {
  if (n == 0) return;
  if (!list.empty()) list += ", ";
  list += std::to_string(n) + " " + what;
}
}  // namespace

std::string ValidationReport::summary() const {
  std::string s;
  append_count(s, bad_offsets, "inconsistent line offsets");
  append_count(s, invalid_points, "invalid points (NaN/Inf or |coordinate| > 1e10)");
  append_count(s, repeated_points, "repeated consecutive points");
  append_count(s, short_lines, "lines with fewer than 2 points");
  for (const std::string& name : attribute_length_mismatches) {
    if (!s.empty()) s += ", ";
    s += "attribute '" + name + "' has the wrong length";
  }
  append_count(s, nonfinite_attribute_values, "non-finite attribute values (kept)");
  if (repaired) {
    std::string r;
    append_count(r, points_dropped, "points dropped");
    append_count(r, lines_split, "extra lines from splits");
    append_count(r, lines_dropped, "lines dropped");
    append_count(r, attributes_dropped, "attributes dropped");
    if (!r.empty()) s += "; repaired: " + r;
  }
  return s.empty() ? "no problems" : s;
}

ValidationReport inspect(const LineSet& lines, uint64_t line_base) {
  ValidationReport report;
  if (!offsets_consistent(lines)) {
    report.bad_offsets = 1;
    return report;
  }
  check_attribute_lengths(lines, report);
  walk(lines, report, nullptr, line_base);
  return report;
}

ValidationReport validate(LineSet& lines, InvalidPolicy policy, const std::string& source,
                          uint64_t line_base) {
  ValidationReport report = inspect(lines, line_base);
  if (report.clean()) return report;
  if (policy == InvalidPolicy::reject || report.bad_offsets)
    throw InputError(
        source, "",
        "invalid line set: " + report.summary() +
            (report.first_problem.empty() ? "" : "; the first: " + report.first_problem));

  // Attributes whose length does not match cannot be mapped to points: drop them.
  auto drop_mismatched = [&](std::vector<Attribute>& list, size_t expected) {
    std::erase_if(list, [&](const Attribute& a) {
      const bool bad = a.values.size() != expected;
      report.attributes_dropped += bad;
      return bad;
    });
  };
  drop_mismatched(lines.attributes, lines.point_count());
  drop_mismatched(lines.line_attributes, lines.line_count());

  ValidationReport counts;  // the walk over the data after attribute repair
  RepairPlan plan;
  walk(lines, counts, &plan, line_base);
  report.points_dropped = counts.points_dropped;
  report.lines_split = counts.lines_split;
  report.lines_dropped = counts.lines_dropped;
  report.repaired = true;

  lines.positions = gather(lines.positions, plan.kept_points, 3);
  for (Attribute& a : lines.attributes) a.values = gather(a.values, plan.kept_points, 1);
  for (Attribute& a : lines.line_attributes) a.values = gather(a.values, plan.source_line, 1);
  lines.line_offsets = std::move(plan.offsets);
  return report;
}

InvalidPolicy parse_invalid_policy(const std::string& name) {
  if (name == "reject") return InvalidPolicy::reject;
  if (name == "repair") return InvalidPolicy::repair;
  throw Error("unknown invalid-data policy '" + name + "' (expected reject or repair)");
}

}  // namespace linebake
