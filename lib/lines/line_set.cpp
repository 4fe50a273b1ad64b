#include "lines/line_set.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace linebake {

float Bounds::diagonal() const {
  if (empty) return 0;
  const float dx = max[0] - min[0], dy = max[1] - min[1], dz = max[2] - min[2];
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

uint64_t LineSet::segment_count() const {
  uint64_t segments = 0;
  for (size_t i = 0; i < line_count(); ++i) {
    const uint64_t n = line_size(i);
    segments += n > 0 ? n - 1 : 0;
  }
  return segments;
}

namespace {
const Attribute* find_named(const std::vector<Attribute>& list, const std::string& name) {
  for (const Attribute& a : list)
    if (a.name == name) return &a;
  return nullptr;
}

template <typename T>
bool same_bits(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

bool same_attributes(const std::vector<Attribute>& a, const std::vector<Attribute>& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i)
    if (a[i].name != b[i].name || !same_bits(a[i].values, b[i].values)) return false;
  return true;
}
}  // namespace

const Attribute* LineSet::find_attribute(const std::string& name) const {
  return find_named(attributes, name);
}
const Attribute* LineSet::find_line_attribute(const std::string& name) const {
  return find_named(line_attributes, name);
}

bool LineSet::same_data(const LineSet& other) const {
  return same_bits(positions, other.positions) && line_offsets == other.line_offsets &&
         same_attributes(attributes, other.attributes) &&
         same_attributes(line_attributes, other.line_attributes);
}

void include_points(Bounds& b, std::span<const float> xyz) {
  for (size_t i = 0; i + 2 < xyz.size(); i += 3) {
    const float* p = &xyz[i];
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) continue;
    for (int k = 0; k < 3; ++k) {
      if (b.empty || p[k] < b.min[k]) b.min[k] = p[k];
      if (b.empty || p[k] > b.max[k]) b.max[k] = p[k];
    }
    if (b.empty) b.min = b.max = {p[0], p[1], p[2]};
    b.empty = false;
  }
}

Bounds compute_bounds(const LineSet& lines) {
  Bounds b;
  include_points(b, std::span<const float>(lines.positions.data(), 3 * lines.point_count()));
  return b;
}

ValueRange compute_range(std::span<const float> values) {
  ValueRange r;
  bool first = true;
  for (float v : values) {
    if (!std::isfinite(v)) {
      ++r.nonfinite;
      continue;
    }
    if (first || v < r.min) r.min = v;
    if (first || v > r.max) r.max = v;
    first = false;
  }
  return r;
}

LineSetStats compute_stats(const LineSet& lines) {
  LineSetStats s;
  s.lines = lines.line_count();
  s.points = lines.point_count();
  s.segments = lines.segment_count();
  s.bounds = compute_bounds(lines);
  s.position_bytes = lines.positions.size() * sizeof(float);
  s.offset_bytes = lines.line_offsets.size() * sizeof(uint64_t);
  for (const Attribute& a : lines.attributes) {
    s.attribute_ranges.emplace_back(a.name, compute_range(a.values));
    s.attribute_bytes += a.values.size() * sizeof(float);
  }
  for (const Attribute& a : lines.line_attributes) {
    s.line_attribute_ranges.emplace_back(a.name, compute_range(a.values));
    s.attribute_bytes += a.values.size() * sizeof(float);
  }
  return s;
}

}  // namespace linebake
