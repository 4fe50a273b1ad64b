#include "lines/line_set.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "core/error.hpp"
#include "core/nearest.hpp"
#include "lines/origin.hpp"

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
  // The same local positions at another origin are other world positions (none: 0, 0, 0).
  const auto frame = [](const LineSet& lines) -> std::optional<Origin> {
    const auto it = lines.metadata.find(kOriginKey);
    return it == lines.metadata.end() ? Origin{0, 0, 0} : parse_origin(it->second);
  };
  return same_bits(positions, other.positions) && line_offsets == other.line_offsets &&
         same_attributes(attributes, other.attributes) &&
         same_attributes(line_attributes, other.line_attributes) && frame(*this) == frame(other);
}

bool valid_point(const float* p) {
  for (int k = 0; k < 3; ++k)
    if (!std::isfinite(p[k]) || std::fabs(p[k]) > kMaxCoordinate) return false;
  return true;
}

void include_points(Bounds& b, std::span<const float> xyz) {
  for (size_t i = 0; i + 2 < xyz.size(); i += 3) {
    const float* p = &xyz[i];
    if (!valid_point(p)) continue;
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
  for (float v : values) {
    if (!std::isfinite(v)) {
      ++r.nonfinite;
      continue;
    }
    if (r.finite == 0 || v < r.min) r.min = v;
    if (r.finite == 0 || v > r.max) r.max = v;
    ++r.finite;
  }
  return r;
}

ValueRange merge(const ValueRange& a, const ValueRange& b) {
  if (a.finite == 0) return {b.min, b.max, a.nonfinite + b.nonfinite, b.finite};
  if (b.finite == 0) return {a.min, a.max, a.nonfinite + b.nonfinite, a.finite};
  return {std::min(a.min, b.min), std::max(a.max, b.max), a.nonfinite + b.nonfinite,
          a.finite + b.finite};
}

namespace {
const ValueRange* find_range(const std::vector<std::pair<std::string, ValueRange>>& list,
                             const std::string& name) {
  for (const auto& [n, r] : list)
    if (n == name) return &r;
  return nullptr;
}
}  // namespace

const ValueRange* LineSetStats::attribute_range(const std::string& name) const {
  return find_range(attribute_ranges, name);
}
const ValueRange* LineSetStats::line_attribute_range(const std::string& name) const {
  return find_range(line_attribute_ranges, name);
}

LineStatsBuilder::LineStatsBuilder(const LineSet& header) {
  for (const Attribute& a : header.attributes)
    stats_.attribute_ranges.emplace_back(a.name, ValueRange{});
  for (const Attribute& a : header.line_attributes)
    stats_.line_attribute_ranges.emplace_back(a.name, ValueRange{});
  stats_.offset_bytes = sizeof(uint64_t);  // the leading 0
}

void LineStatsBuilder::add(const LineSet& batch) {
  LineSetStats& s = stats_;
  s.lines += batch.line_count();
  s.points += batch.point_count();
  s.segments += batch.segment_count();
  for (size_t l = 0; l < batch.line_count(); ++l)
    s.largest_line = std::max(s.largest_line, batch.line_size(l));
  include_points(s.bounds, std::span<const float>(batch.positions.data(), 3 * batch.point_count()));
  s.position_bytes += batch.positions.size() * sizeof(float);
  s.offset_bytes += batch.line_count() * sizeof(uint64_t);
  for (size_t a = 0; a < batch.attributes.size(); ++a) {
    s.attribute_ranges[a].second =
        merge(s.attribute_ranges[a].second, compute_range(batch.attributes[a].values));
    s.attribute_bytes += batch.attributes[a].values.size() * sizeof(float);
  }
  for (size_t a = 0; a < batch.line_attributes.size(); ++a) {
    s.line_attribute_ranges[a].second =
        merge(s.line_attribute_ranges[a].second, compute_range(batch.line_attributes[a].values));
    s.attribute_bytes += batch.line_attributes[a].values.size() * sizeof(float);
  }
}

LineSetStats merge(const LineSetStats& a, const LineSetStats& b) {
  if (a.attribute_ranges.size() != b.attribute_ranges.size() ||
      a.line_attribute_ranges.size() != b.line_attribute_ranges.size())
    throw Error("line set statistics with different attributes cannot merge");
  LineSetStats s = a;
  s.lines += b.lines;
  s.points += b.points;
  s.segments += b.segments;
  s.position_bytes += b.position_bytes;
  // Each set's offsets start with a 0 that the merged set holds once.
  s.offset_bytes += b.offset_bytes - std::min({a.offset_bytes, b.offset_bytes, uint64_t{8}});
  s.attribute_bytes += b.attribute_bytes;
  s.largest_line = std::max(a.largest_line, b.largest_line);
  if (s.bounds.empty) {
    s.bounds = b.bounds;
  } else if (!b.bounds.empty) {
    for (int k = 0; k < 3; ++k) {
      s.bounds.min[k] = std::min(s.bounds.min[k], b.bounds.min[k]);
      s.bounds.max[k] = std::max(s.bounds.max[k], b.bounds.max[k]);
    }
  }
  for (size_t i = 0; i < s.attribute_ranges.size(); ++i)
    s.attribute_ranges[i].second =
        merge(a.attribute_ranges[i].second, b.attribute_ranges[i].second);
  for (size_t i = 0; i < s.line_attribute_ranges.size(); ++i)
    s.line_attribute_ranges[i].second =
        merge(a.line_attribute_ranges[i].second, b.line_attribute_ranges[i].second);
  return s;
}

LineSetStats compute_stats(const LineSet& lines) {
  LineStatsBuilder builder(lines);
  builder.add(lines);
  LineSetStats s = builder.stats();
  s.offset_bytes = lines.line_offsets.size() * sizeof(uint64_t);
  return s;
}

void throw_unknown_attribute(const LineSet& lines, const std::string& option,
                             const std::string& name, bool vertex_only) {
  std::vector<std::string> names;
  for (const Attribute& a : lines.attributes) names.push_back(a.name);
  if (!vertex_only)
    for (const Attribute& a : lines.line_attributes) names.push_back(a.name);
  const std::string list = name_list(names);
  throw UsageError(option + ": no " + (vertex_only ? "vertex " : "") + "attribute named '" + name +
                   "' in these lines (" + (list.empty() ? std::string("they have none") : list) +
                   ")" + did_you_mean(name, names));
}

}  // namespace linebake
