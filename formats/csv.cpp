// CSV, one row per point: line_id,x,y,z[,attribute...] with a header naming the columns.
// Rows of one line are consecutive; a line id that comes back after another line is an error.

#include <unordered_set>

#include "formats/formats.hpp"
#include "formats/io_util.hpp"

namespace linebake::formats {

namespace {
std::vector<std::string_view> split_commas(std::string_view line) {
  std::vector<std::string_view> fields;
  size_t start = 0;
  for (;;) {
    const size_t comma = line.find(',', start);
    fields.push_back(io::trim(line.substr(start, comma - start)));
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  return fields;
}
}  // namespace

LineSet read_csv(const std::string& path, const ReadOptions& options) {
  io::TextReader in(path, options.progress);
  std::string_view row;
  if (!in.next(row)) throw InputError(path, at_line(1), "empty file (expected a header)");
  const auto header = split_commas(row);
  const char* required[] = {"line_id", "x", "y", "z"};
  if (header.size() < 4) in.fail("header needs line_id,x,y,z");
  for (int k = 0; k < 4; ++k)
    if (header[k] != required[k])
      in.fail("header column " + std::to_string(k + 1) + " is '" + std::string(header[k]) +
              "', expected '" + required[k] + "'");
  LineSet lines;
  for (size_t k = 4; k < header.size(); ++k)
    lines.attributes.push_back({std::string(header[k]), {}});

  std::unordered_set<int64_t> finished;
  int64_t current = 0;
  bool open = false;
  while (in.next(row)) {
    if (io::trim(row).empty()) continue;
    const auto fields = split_commas(row);
    if (fields.size() != header.size())
      in.fail(std::to_string(fields.size()) + " columns, the header has " +
              std::to_string(header.size()));
    int64_t id;
    if (!io::parse_int64(fields[0], id)) in.fail("bad line_id '" + std::string(fields[0]) + "'");
    if (!open || id != current) {
      if (open) {
        lines.end_line();
        finished.insert(current);
      }
      if (finished.count(id))
        in.fail("rows of line " + std::to_string(id) + " are not consecutive");
      current = id;
      open = true;
    }
    float xyz[3];
    for (int k = 0; k < 3; ++k)
      if (!io::parse_float(fields[1 + k], xyz[k]))
        in.fail("bad coordinate '" + std::string(fields[1 + k]) + "'");
    lines.append_point(xyz[0], xyz[1], xyz[2]);
    for (size_t k = 4; k < fields.size(); ++k) {
      float v;
      if (!io::parse_float(fields[k], v)) in.fail("bad value '" + std::string(fields[k]) + "'");
      lines.attributes[k - 4].values.push_back(v);
    }
  }
  if (open) lines.end_line();
  return lines;
}

void write_csv(const LineSet& lines, const std::string& path, const WriteOptions& options) {
  io::Writer out(path);
  std::string text = "line_id,x,y,z";
  for (const Attribute& a : lines.attributes) {
    if (a.name.find_first_of(",\n\r\"") != std::string::npos)
      throw Error("CSV: attribute name '" + a.name + "' contains a comma, quote or newline");
    text += "," + a.name;
  }
  text += '\n';
  for (size_t line = 0; line < lines.line_count(); ++line) {
    const std::string id = std::to_string(line);
    for (uint64_t i = lines.line_offsets[line]; i < lines.line_offsets[line + 1]; ++i) {
      text += id;
      for (int k = 0; k < 3; ++k) {
        text += ',';
        io::append_float(text, lines.positions[3 * i + k]);
      }
      for (const Attribute& a : lines.attributes) {
        text += ',';
        io::append_float(text, a.values[i]);
      }
      text += '\n';
    }
    if (text.size() > (1 << 20)) {
      out.write(text);
      text.clear();
    }
    if (options.progress && line % 4096 == 0) options.progress(line, lines.line_count());
  }
  out.write(text);
  out.close();
}

}  // namespace linebake::formats
