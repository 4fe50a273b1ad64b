// CSV, one row per point: line_id,x,y,z[,attribute...] with a header naming the columns.
// Rows of one line are consecutive; a line id that comes back after another line is an error.
// Lines are read in batches: a line is only known to end when the next line's id appears, so
// the line being read is carried, as far as it was read, into the next batch.

#include <cstdint>
#include <iterator>
#include <map>
#include <optional>

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

// The ids of the lines already read, as runs of consecutive ids: ids that count up (or down)
// take one entry in all, whatever the number of lines.
class IdSet {
 public:
  bool contains(int64_t id) const {
    auto it = runs_.upper_bound(id);
    if (it == runs_.begin()) return false;
    return id <= std::prev(it)->second;
  }
  // `id` must not be in the set yet.
  void insert(int64_t id) {
    auto after = runs_.upper_bound(id);
    const bool joins_before =
        after != runs_.begin() && id != INT64_MIN && std::prev(after)->second == id - 1;
    const bool joins_after = after != runs_.end() && id != INT64_MAX && after->first == id + 1;
    if (joins_before) {
      auto before = std::prev(after);
      if (joins_after) {
        before->second = after->second;
        runs_.erase(after);
      } else {
        before->second = id;
      }
    } else if (joins_after) {
      const int64_t last = after->second;
      runs_.erase(after);
      runs_.emplace(id, last);
    } else {
      runs_.emplace(id, id);
    }
  }

 private:
  std::map<int64_t, int64_t> runs_;  // first id -> last id of each run
};

class CsvReader : public LineReader {
 public:
  CsvReader(const std::string& path, const ReadOptions& options)
      : in_(path, options.progress), memory_limit_(options.memory_limit) {
    std::string_view row;
    if (!in_.next(row)) throw InputError(path, at_line(1), "empty file (expected a header)");
    const auto header = split_commas(row);
    const char* required[] = {"line_id", "x", "y", "z"};
    if (header.size() < 4) in_.fail("header needs line_id,x,y,z");
    for (int k = 0; k < 4; ++k)
      if (header[k] != required[k])
        in_.fail("header column " + std::to_string(k + 1) + " is '" + std::string(header[k]) +
                 "', expected '" + required[k] + "'");
    columns_ = header.size();
    for (size_t k = 4; k < header.size(); ++k)
      header_.attributes.push_back({std::string(header[k]), {}});
    open_ = header_of(header_);
  }

  bool next(LineSet& batch, uint64_t max_points) override {
    copy_lines(header_, 0, 0, batch);
    std::string_view row;
    while (!done_) {
      // The open line no longer fits beside the batch's: it goes on in the next batch.
      if (batch.line_count() > 0 && batch.point_count() + open_.point_count() > max_points) break;
      if (!in_.next(row)) {
        if (open_id_) close_line(batch);
        done_ = true;
        break;
      }
      if (io::trim(row).empty()) continue;
      const auto fields = split_commas(row);
      if (fields.size() != columns_)
        in_.fail(std::to_string(fields.size()) + " columns, the header has " +
                 std::to_string(columns_));
      int64_t id;
      if (!io::parse_int64(fields[0], id)) in_.fail("bad line_id '" + std::string(fields[0]) + "'");
      if (!open_id_ || id != *open_id_) {
        if (open_id_) {
          finished_.insert(*open_id_);
          close_line(batch);
        }
        if (finished_.contains(id))
          in_.fail("rows of line " + std::to_string(id) + " are not consecutive");
        open_id_ = id;
      }
      float xyz[3];
      for (int k = 0; k < 3; ++k)
        if (!io::parse_float(fields[1 + k], xyz[k]))
          in_.fail("bad coordinate '" + std::string(fields[1 + k]) + "'");
      open_.append_point(xyz[0], xyz[1], xyz[2]);
      for (size_t k = 4; k < fields.size(); ++k) {
        float v;
        if (!io::parse_float(fields[k], v)) in_.fail("bad value '" + std::string(fields[k]) + "'");
        open_.attributes[k - 4].values.push_back(v);
      }
      // A line's length is known only at its last row: what it holds is checked as it grows
      // (its arrays and the batch's copy, both growing by doubling).
      const uint64_t open_points = open_.positions.size() / 3;
      if (batch.line_count() == 0 && open_points % kCheckPoints == 0)
        io::check_line_memory(in_.path(), lines_read_, open_points,
                              3.0 * double(open_points) * double(12 + 4 * (columns_ - 4)),
                              "text line " + std::to_string(in_.line_number()), memory_limit_);
    }
    lines_read_ += batch.line_count();
    return batch.line_count() > 0;
  }

 private:
  // Moves the open line into the batch.
  void close_line(LineSet& batch) {
    open_.end_line();
    append_lines(batch, open_);
    copy_lines(header_, 0, 0, open_);
  }

  static constexpr uint64_t kCheckPoints = 65536;  // the open line's memory checked so often
  io::TextReader in_;
  std::optional<uint64_t> memory_limit_;
  size_t columns_ = 0;
  IdSet finished_;
  std::optional<int64_t> open_id_;  // id of the line being read
  LineSet open_;                    // its points so far (line_offsets {0})
  bool done_ = false;
};

}  // namespace

std::unique_ptr<LineReader> open_csv(const std::string& path, const ReadOptions& options) {
  return std::make_unique<CsvReader>(path, options);
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
