// Wavefront OBJ polylines: v (positions), vt (one per v: the vertex attributes), l (polylines,
// 1-based or negative relative indices), an optional `a name0 name1 ...` line naming the
// attributes (spaces in names as %20). Faces, normals, groups and materials are ignored. A
// vertex colour (`v x y z r g b`, MeshLab's and others' extension) becomes the attributes
// color_r, color_g and color_b, after the vt ones; a `w` (`v x y z w`) is ignored. A line ending
// in a backslash continues on the next.

#include <algorithm>
#include <limits>
#include <numeric>
#include <optional>

#include "formats/formats.hpp"
#include "formats/io_util.hpp"

namespace linebake::formats {

LineSet read_obj(const std::string& path, const ReadOptions& options) {
  io::TextReader in(path, options.progress);
  std::vector<float> positions;
  std::vector<float> vt;  // row-major: point x attribute
  // r, g, b of each vertex once one has them; NaN for a vertex without (no value, as a NetCDF
  // fill value reads).
  std::vector<float> colors;
  bool colored = false;
  size_t vt_rows = 0;
  size_t attribute_count = SIZE_MAX;
  std::vector<std::string> names;
  std::vector<uint64_t> indices;
  std::vector<uint64_t> offsets{0};
  // What reading it holds (ReadOptions::memory_limit), checked at every `l` line and every 65,536
  // lines: the arrays (resident as far as they are filled), the largest of them once more while
  // they grow (a vector copies itself as it grows), and the line set to be gathered along the
  // indices so far.
  // `line`: the line it is at (0: the last one read).
  const auto check_memory = [&](bool growing, double line_bytes = 0, uint64_t line = 0) {
    const double attribute_floats =
        (attribute_count == SIZE_MAX ? 0 : double(attribute_count)) + (colored ? 3 : 0);
    const double arrays[] = {4.0 * double(positions.size()), 4.0 * double(vt.size()),
                             4.0 * double(colors.size()), 8.0 * double(indices.size()),
                             8.0 * double(offsets.size())};
    double held = 0, largest = 0;
    for (const double bytes : arrays) held += bytes, largest = std::max(largest, bytes);
    io::check_read_memory(path, "obj",
                          held + (growing ? largest : 0) + line_bytes +
                              (12 + 4 * attribute_floats) * double(indices.size()),
                          at_line(line ? line : in.line_number()), options.memory_limit);
  };
  // The buffer grows while the next line is read.
  in.before_growing(
      [&](uint64_t bytes) { check_memory(true, double(bytes), in.line_number() + 1); });
  std::string_view line;
  // A statement continued over lines ending in a backslash (OBJ's rule; long `l` lines), joined.
  std::string joined;
  bool continued = false;
  while (in.next(line)) {
    if (in.line_number() % 65536 == 0) check_memory(true);
    if (!continued) joined.clear();
    // A comment runs to the end of its line, whatever it ends in (a path's backslash); not in
    // linebake's own `a` lines, whose names older versions wrote with '#' as it was.
    if (!io::trim(line).starts_with("a ")) line = line.substr(0, line.find('#'));
    if (const std::string_view t = io::trim(line); !t.empty() && t.back() == '\\') {
      joined.append(t.substr(0, t.size() - 1)).push_back(' ');
      if (joined.size() > 65536) check_memory(true, 2.0 * double(joined.size()));
      continued = true;
      continue;
    }
    if (continued) {
      joined.append(line);
      line = joined;
      continued = false;
    }
    // A long line (an `l` of millions of indices) before it is split: the line, a token per
    // value (counted) and what each index will add.
    if (line.size() > 65536) {
      const double values = double(io::count_tokens(line));
      const double attributes = attribute_count == SIZE_MAX ? 0 : double(attribute_count);
      check_memory(true, double(line.size()) + values * (16 + 8 + 12 + 4 * attributes));
    }
    line = io::trim(line);
    if (line.empty()) continue;
    const auto tokens = io::split_whitespace(line);
    const std::string_view key = tokens[0];
    if (key == "v") {
      if (tokens.size() < 4) in.fail("vertex needs 3 coordinates");
      for (int k = 1; k <= 3; ++k) {
        float value = 0;
        double world = 0;  // with an origin, subtracted before rounding (lines/origin.hpp)
        if (options.origin ? !io::parse_double(tokens[k], world)
                           : !io::parse_float(tokens[k], value))
          in.fail("bad coordinate '" + std::string(tokens[k]) + "'");
        if (options.origin && !to_local_in_range(world, (*options.origin)[k - 1], value))
          in.fail("coordinate '" + std::string(tokens[k]) +
                  "' is outside float32's range from the origin");
        positions.push_back(value);
      }
      // A colour follows the coordinates (`v x y z r g b`), or the weight w, which lines leave
      // unused (`v x y z w r g b`).
      const size_t color_at = tokens.size() == 7 ? 4 : tokens.size() == 8 ? 5 : 0;
      const bool has_color = color_at != 0;
      if (has_color && !colored) {
        colored = true;
        colors.assign(positions.size() - 3, std::numeric_limits<float>::quiet_NaN());
      }
      for (size_t c = 0; colored && c < 3; ++c) {
        float value = std::numeric_limits<float>::quiet_NaN();
        if (has_color && !io::parse_float(tokens[color_at + c], value))
          in.fail("bad colour value '" + std::string(tokens[color_at + c]) + "'");
        colors.push_back(value);
      }
    } else if (key == "vt") {
      const size_t n = tokens.size() - 1;
      if (attribute_count == SIZE_MAX) attribute_count = n;
      if (n != attribute_count)
        in.fail("vt has " + std::to_string(n) + " values, earlier vt lines had " +
                std::to_string(attribute_count));
      for (size_t k = 1; k < tokens.size(); ++k) {
        float value;
        if (!io::parse_float(tokens[k], value))
          in.fail("bad attribute value '" + std::string(tokens[k]) + "'");
        vt.push_back(value);
      }
      ++vt_rows;
    } else if (key == "l") {
      if (tokens.size() < 2) in.fail("polyline without indices");
      const int64_t count = static_cast<int64_t>(positions.size() / 3);
      for (size_t k = 1; k < tokens.size(); ++k) {
        // "l 1/1 2/2" (vertex/texture) is legal OBJ: the vertex index comes first.
        std::string_view token = tokens[k].substr(0, tokens[k].find('/'));
        int64_t index;
        if (!io::parse_int64(token, index) || index == 0)
          in.fail("bad vertex index '" + std::string(tokens[k]) + "'");
        const int64_t zero_based = index > 0 ? index - 1 : count + index;
        if (zero_based < 0 || zero_based >= count)
          in.fail("vertex index " + std::to_string(index) + " out of range (" +
                  std::to_string(count) + " vertices so far)");
        indices.push_back(static_cast<uint64_t>(zero_based));
      }
      offsets.push_back(indices.size());
      check_memory(true);
    } else if (key == "a") {
      names.clear();
      for (size_t k = 1; k < tokens.size(); ++k) names.push_back(io::decode_name(tokens[k]));
    }
  }
  if (continued) in.fail("the file ends in a statement continued with '\\'");
  const size_t point_count = positions.size() / 3;
  // No vertices, no vt lines: the `a` line alone says which attributes an empty set has.
  if (attribute_count == SIZE_MAX) attribute_count = point_count == 0 ? names.size() : 0;
  if (vt_rows != 0 && vt_rows != point_count)
    throw InputError(path, "",
                     std::to_string(vt_rows) + " vt lines for " + std::to_string(point_count) +
                         " vertices (need one per v)");
  if (!names.empty() && names.size() != attribute_count)
    throw InputError(path, "",
                     "the `a` line names " + std::to_string(names.size()) +
                         " attributes, vt lines have " + std::to_string(attribute_count));

  check_memory(false);
  LineSet lines;
  lines.line_offsets = std::move(offsets);
  // Lines that walk the vertices in file order (what most writers produce) keep the arrays
  // as they are; anything else is gathered.
  bool identity = indices.size() == point_count;
  for (size_t i = 0; identity && i < indices.size(); ++i) identity = indices[i] == i;
  if (identity) {
    lines.positions = std::move(positions);
  } else {
    lines.positions.resize(indices.size() * 3);
    for (size_t i = 0; i < indices.size(); ++i)
      for (int k = 0; k < 3; ++k) lines.positions[3 * i + k] = positions[3 * indices[i] + k];
  }
  for (size_t a = 0; a < attribute_count; ++a) {
    Attribute attribute{names.empty() ? "attribute" + std::to_string(a) : names[a], {}};
    attribute.values.resize(indices.size());
    for (size_t i = 0; i < indices.size(); ++i)
      attribute.values[i] = vt[indices[i] * attribute_count + a];
    lines.attributes.push_back(std::move(attribute));
  }
  for (int c = 0; c < 3 && !colors.empty(); ++c) {
    Attribute attribute{std::string("color_") + "rgb" [c], {}};
    attribute.values.resize(indices.size());
    for (size_t i = 0; i < indices.size(); ++i) attribute.values[i] = colors[3 * indices[i] + c];
    lines.attributes.push_back(std::move(attribute));
  }
  return lines;
}

void write_obj(const LineSet& lines, const std::string& path, const WriteOptions& options) {
  // World coordinates, in float64 text where the lines have an origin (lines/origin.hpp).
  const std::optional<Origin> origin = optional_origin(lines, path);
  io::Writer out(path);
  std::string text;
  text.reserve(1 << 20);
  auto flush = [&] {
    out.write(text);
    text.clear();
  };
  text += "# linebake " LINEBAKE_VERSION " polylines\n";
  if (!lines.attributes.empty()) {
    text += "a";
    for (const Attribute& a : lines.attributes) text += " " + io::encode_name(a.name);
    text += "\n";
  }
  for (size_t i = 0; i < lines.point_count(); ++i) {
    text += "v";
    for (int k = 0; k < 3; ++k) {
      text += ' ';
      if (origin)
        io::append_double(text, to_world(lines.positions[3 * i + k], (*origin)[k]));
      else
        io::append_float(text, lines.positions[3 * i + k]);
    }
    text += '\n';
    if (!lines.attributes.empty()) {
      text += "vt";
      for (const Attribute& a : lines.attributes) {
        text += ' ';
        io::append_float(text, a.values[i]);
      }
      text += '\n';
    }
    if (text.size() > (1 << 20) - 256) flush();
  }
  for (size_t line = 0; line < lines.line_count(); ++line) {
    // A line without points has no `l` (it needs a vertex): left out, as lost_in_format says.
    if (lines.line_size(line) == 0) continue;
    text += "l";
    for (uint64_t i = lines.line_offsets[line]; i < lines.line_offsets[line + 1]; ++i)
      text += " " + std::to_string(i + 1);
    text += '\n';
    if (text.size() > (1 << 20) - 256) flush();
    if (options.progress && line % 4096 == 0) options.progress(line, lines.line_count());
  }
  flush();
  out.close();
}

}  // namespace linebake::formats
