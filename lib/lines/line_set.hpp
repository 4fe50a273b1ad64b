#pragma once
// The line set: every stage of linebake takes one in. Structure of arrays, so a renderer or a
// writer can hand each array to its consumer without reshuffling.

#include <array>
#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <vector>

namespace linebake {

// A named float32 array with one value per point (vertex attribute) or per line.
struct Attribute {
  std::string name;
  std::vector<float> values;
};

struct Bounds {
  std::array<float, 3> min{0, 0, 0};
  std::array<float, 3> max{0, 0, 0};
  bool empty = true;
  float diagonal() const;
};

struct LineSet {
  std::vector<float> positions;                 // x0 y0 z0 x1 y1 z1 ...: 3 floats per point
  std::vector<uint64_t> line_offsets{0};        // line i spans points [offsets[i], offsets[i+1])
  std::vector<Attribute> attributes;            // one value per point
  std::vector<Attribute> line_attributes;       // one value per line
  std::map<std::string, std::string> metadata;  // provenance, units, source notes

  size_t point_count() const { return positions.size() / 3; }
  size_t line_count() const { return line_offsets.empty() ? 0 : line_offsets.size() - 1; }
  // Segments: consecutive point pairs within a line.
  uint64_t segment_count() const;
  uint64_t line_size(size_t line) const { return line_offsets[line + 1] - line_offsets[line]; }

  void append_point(float x, float y, float z) { positions.insert(positions.end(), {x, y, z}); }
  // Closes the current line at the current point count.
  void end_line() { line_offsets.push_back(point_count()); }

  const Attribute* find_attribute(const std::string& name) const;
  const Attribute* find_line_attribute(const std::string& name) const;

  // Exact equality of every array and name, and of the origin (lines/origin.hpp: the same world
  // positions); the rest of the metadata excluded. Used by round-trip tests.
  bool same_data(const LineSet& other) const;
};

// Points with a NaN/Inf coordinate, or any |coordinate| above this, are invalid (the public
// LineVis viewer drops such points too): validation counts them, repair drops them, and bounds
// leave them out.
inline constexpr float kMaxCoordinate = 1e10f;
// Whether the point x y z at `p` is valid (above).
bool valid_point(const float* p);

// Bounds of the valid points (valid_point).
Bounds compute_bounds(const LineSet& lines);
// Grows `bounds` by points given as x y z triples; invalid points are skipped, so that the bounds
// `info` prints are those of the points a bake keeps.
void include_points(Bounds& bounds, std::span<const float> xyz);

// An option names an attribute the lines do not have: a UsageError (exit 1) naming the option,
// the attributes there are (vertex ones, and line ones unless `vertex_only`) and the nearest.
[[noreturn]] void throw_unknown_attribute(const LineSet& lines, const std::string& option,
                                          const std::string& name, bool vertex_only);

struct ValueRange {
  float min = 0;  // 0 when no value is finite
  float max = 0;
  uint64_t nonfinite = 0;  // NaN or Inf values, excluded from min/max
  uint64_t finite = 0;
};
ValueRange compute_range(std::span<const float> values);
// The range of the values of both.
ValueRange merge(const ValueRange& a, const ValueRange& b);

// Sizes and counts: the "LS" (segments) and "LM" (line model bytes) columns of the paper's
// Table 1.
struct LineSetStats {
  uint64_t lines = 0;
  uint64_t points = 0;
  uint64_t segments = 0;
  Bounds bounds;
  std::vector<std::pair<std::string, ValueRange>> attribute_ranges;
  std::vector<std::pair<std::string, ValueRange>> line_attribute_ranges;
  uint64_t position_bytes = 0;
  uint64_t offset_bytes = 0;
  uint64_t attribute_bytes = 0;  // vertex and line attributes
  uint64_t largest_line = 0;     // points of the longest line
  uint64_t total_bytes() const { return position_bytes + offset_bytes + attribute_bytes; }
  const ValueRange* attribute_range(const std::string& name) const;
  const ValueRange* line_attribute_range(const std::string& name) const;
};
LineSetStats compute_stats(const LineSet& lines);
// The figures of two consecutive parts of one line set (the ranks of an MPI bake): counts and
// bytes add up, bounds and ranges merge. The attributes must be the same, in the same order.
LineSetStats merge(const LineSetStats& first, const LineSetStats& second);

// The same figures over a line set given batch by batch (lines/line_reader.hpp), whatever the
// batches: counts add up, bounds and ranges merge.
class LineStatsBuilder {
 public:
  explicit LineStatsBuilder(const LineSet& header);  // names of the attributes, in order
  void add(const LineSet& batch);
  const LineSetStats& stats() const { return stats_; }

 private:
  LineSetStats stats_;
};

}  // namespace linebake
