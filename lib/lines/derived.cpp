#include "lines/derived.hpp"

#include <cmath>

#include "core/error.hpp"
#include "core/nearest.hpp"

namespace linebake {

namespace {

struct P3 {
  double x, y, z;
};
P3 point(const LineSet& lines, uint64_t i) {
  return {lines.positions[3 * i], lines.positions[3 * i + 1], lines.positions[3 * i + 2]};
}
P3 sub(P3 a, P3 b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}
double length(P3 v) {
  return std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
}
P3 cross(P3 a, P3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

// Curvature of the circle through a, b, c: 4 * area / (|ab| |bc| |ca|) = 2 |ab x bc| / (...).
double menger_curvature(P3 a, P3 b, P3 c) {
  const P3 ab = sub(b, a), bc = sub(c, b), ca = sub(a, c);
  const double denominator = length(ab) * length(bc) * length(ca);
  return denominator > 0 ? 2.0 * length(cross(ab, bc)) / denominator : 0.0;
}

template <typename PerLine>
std::vector<float> per_point(const LineSet& lines, PerLine fill) {
  std::vector<float> out(lines.point_count());
  for (size_t line = 0; line < lines.line_count(); ++line)
    fill(lines.line_offsets[line], lines.line_offsets[line + 1], out.data());
  return out;
}

}  // namespace

const std::vector<std::string>& derived_attribute_names() {
  static const std::vector<std::string> names{"segment_length", "arc_length", "curvature",
                                              "index_along_line", "line_length"};
  return names;
}

bool is_line_attribute(const std::string& derived_name) {
  return derived_name == "line_length";
}

Attribute derive_attribute(const LineSet& lines, const std::string& name) {
  Attribute a{name, {}};
  if (name == "segment_length") {
    a.values = per_point(lines, [&](uint64_t begin, uint64_t end, float* out) {
      for (uint64_t i = begin; i + 1 < end; ++i)
        out[i] = static_cast<float>(length(sub(point(lines, i + 1), point(lines, i))));
      if (end - begin >= 2) out[end - 1] = out[end - 2];
      if (end - begin == 1) out[begin] = 0;
    });
  } else if (name == "arc_length") {
    a.values = per_point(lines, [&](uint64_t begin, uint64_t end, float* out) {
      double s = 0;
      for (uint64_t i = begin; i < end; ++i) {
        if (i > begin) s += length(sub(point(lines, i), point(lines, i - 1)));
        out[i] = static_cast<float>(s);
      }
    });
  } else if (name == "curvature") {
    a.values = per_point(lines, [&](uint64_t begin, uint64_t end, float* out) {
      for (uint64_t i = begin + 1; i + 1 < end; ++i)
        out[i] = static_cast<float>(
            menger_curvature(point(lines, i - 1), point(lines, i), point(lines, i + 1)));
      if (end - begin >= 3) {
        out[begin] = out[begin + 1];
        out[end - 1] = out[end - 2];
      } else {
        for (uint64_t i = begin; i < end; ++i) out[i] = 0;
      }
    });
  } else if (name == "index_along_line") {
    a.values = per_point(lines, [&](uint64_t begin, uint64_t end, float* out) {
      for (uint64_t i = begin; i < end; ++i) out[i] = static_cast<float>(i - begin);
    });
  } else if (name == "line_length") {
    a.values.resize(lines.line_count());
    for (size_t line = 0; line < lines.line_count(); ++line) {
      double s = 0;
      for (uint64_t i = lines.line_offsets[line] + 1; i < lines.line_offsets[line + 1]; ++i)
        s += length(sub(point(lines, i), point(lines, i - 1)));
      a.values[line] = static_cast<float>(s);
    }
  } else {
    throw UsageError("unknown derived attribute '" + name +
                     "' (expected segment_length, arc_length, curvature, index_along_line or "
                     "line_length)" +
                     did_you_mean(name, derived_attribute_names()));
  }
  return a;
}

}  // namespace linebake
