// CSV, one row per point: line_id,x,y,z[,attribute...] with a header naming the columns, each
// once. Rows of one line are consecutive; a line id that comes back after another line is an
// error. Fields may be quoted (RFC 4180) and the file may start with a UTF-8 byte-order mark.
// Lines are read in batches: a line is only known to end when the next line's id appears, so
// the line being read is carried, as far as it was read, into the next batch.

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cstdint>
#include <iterator>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "formats/formats.hpp"
#include "formats/io_util.hpp"

namespace linebake::formats {

namespace {
bool is_digit(char c) {
  return c >= '0' && c <= '9';
}

// For a number from_chars found outside float's range (it rounds to 0 or to infinity there):
// whether it is that far below 1 (an underflow, read as 0), not above (an overflow). Its decimal
// order of magnitude: the place of the first non-zero digit, plus the exponent.
bool below_one(std::string_view t) {
  size_t i = 0;
  if (i < t.size() && (t[i] == '-' || t[i] == '+')) ++i;
  int64_t order = 0;  // of the first non-zero digit
  bool found = false;
  int64_t integer_digits = 0;
  for (; i < t.size() && is_digit(t[i]); ++i) {
    if (found) ++integer_digits;
    if (t[i] != '0' && !found) found = true;
  }
  if (found) {
    order = integer_digits;
  } else if (i < t.size() && t[i] == '.') {
    for (++i; i < t.size() && is_digit(t[i]); ++i) {
      --order;
      if (t[i] != '0') {
        found = true;
        break;
      }
    }
  }
  while (i < t.size() && t[i] != 'e' && t[i] != 'E') ++i;
  if (i + 1 < t.size()) {
    ++i;
    const bool negative = t[i] == '-';
    if (t[i] == '-' || t[i] == '+') ++i;
    int64_t exponent = 0;
    for (; i < t.size() && is_digit(t[i]); ++i)
      exponent = std::min<int64_t>(exponent * 10 + (t[i] - '0'), int64_t{1} << 40);
    order += negative ? -exponent : exponent;
  }
  return order < 0;
}

enum class Number { ok, bad, too_large };

// A float32 value, as io::parse_float reads it (NaN and infinity spelled out included), where a
// number too small for float32 reads as the nearest float (0, keeping its sign, as strtof gives):
// too_large for one past float32's range, which would otherwise read as infinity.
Number parse_value(std::string_view token, float& out) {
  if (io::parse_float(token, out)) return Number::ok;
  std::string_view digits = token;
  if (!digits.empty() && digits.front() == '+') digits.remove_prefix(1);
  float ignored;
  const auto r = std::from_chars(digits.data(), digits.data() + digits.size(), ignored);
  if (r.ec != std::errc::result_out_of_range || r.ptr != digits.data() + digits.size())
    return Number::bad;
  if (!below_one(digits)) return Number::too_large;
  out = digits.front() == '-' ? -0.0f : 0.0f;
  return Number::ok;
}

enum class Id { ok, bad, fraction };

// A line id: an integer, or an integral value written as a float ("3.0", "3.", "1.5e1",
// "1e+16": pandas writes the ids of a float column so). `fraction` for a value that is not an
// integer.
Id parse_line_id(std::string_view token, int64_t& id) {
  if (io::parse_int64(token, id)) return Id::ok;
  std::string_view s = token;
  const bool negative = !s.empty() && s.front() == '-';
  if (!s.empty() && (s.front() == '-' || s.front() == '+')) s.remove_prefix(1);
  std::string digits;  // of the integer part, then the fraction's
  size_t i = 0;
  for (; i < s.size() && is_digit(s[i]); ++i) digits += s[i];
  const size_t integer_digits = digits.size();
  if (i < s.size() && s[i] == '.')
    for (++i; i < s.size() && is_digit(s[i]); ++i) digits += s[i];
  if (digits.empty()) return Id::bad;
  int64_t exponent = 0;
  if (i < s.size() && (s[i] == 'e' || s[i] == 'E')) {
    std::string_view e = s.substr(i + 1);
    if (!e.empty() && e.front() == '+') e.remove_prefix(1);
    const auto r = std::from_chars(e.data(), e.data() + e.size(), exponent);
    if (e.empty() || r.ec != std::errc() || r.ptr != e.data() + e.size()) return Id::bad;
    i = s.size();
  }
  if (i != s.size()) return Id::bad;
  if (digits.find_first_not_of('0') == std::string::npos) {
    id = 0;
    return Id::ok;
  }
  if (exponent < -1000 || exponent > 1000) return exponent < 0 ? Id::fraction : Id::bad;
  // The value is digits x 10^shift.
  const int64_t shift = exponent - int64_t(digits.size() - integer_digits);
  if (shift < 0) {
    const size_t cut = size_t(std::min<int64_t>(-shift, int64_t(digits.size())));
    if (digits.find_first_not_of('0', digits.size() - cut) != std::string::npos ||
        size_t(-shift) > digits.size())
      return Id::fraction;
    digits.resize(digits.size() - cut);
  } else if (shift > 0) {
    if (shift > 40) return Id::bad;  // past int64 whatever the digits
    digits.append(size_t(shift), '0');
  }
  if (negative) digits.insert(0, 1, '-');
  return io::parse_int64(digits, id) ? Id::ok : Id::bad;
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
      : in_(path, options.progress), memory_limit_(options.memory_limit), origin_(options.origin) {
    std::string_view row;
    if (!in_.next(row)) throw InputError(path, at_line(1), "empty file (expected a header)");
    // A UTF-8 byte-order mark (Excel's "CSV UTF-8") is no part of the first name.
    if (row.starts_with("\xEF\xBB\xBF")) row.remove_prefix(3);
    split(row);
    const std::vector<std::string_view>& header = fields_;
    const char* required[] = {"line_id", "x", "y", "z"};
    if (header.size() < 4) in_.fail("header needs line_id,x,y,z");
    for (int k = 0; k < 4; ++k)
      if (header[k] != required[k])
        in_.fail("header column " + std::to_string(k + 1) + " is '" + std::string(header[k]) +
                 "', expected '" + required[k] + "'");
    // An attribute may be named as a position column (linebake writes one named x so), and
    // attributes named twice are renamed as in any format (formats/registry.cpp); an empty name
    // is most often a comma at the end of the header, said as such.
    for (size_t k = 0; k < header.size(); ++k)
      if (header[k].empty())
        in_.fail("header column " + std::to_string(k + 1) +
                 " has no name (a comma at the end of the header?)");
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
      split(row);
      const std::vector<std::string_view>& fields = fields_;
      if (fields.size() != columns_)
        in_.fail(std::to_string(fields.size()) + " columns, the header has " +
                 std::to_string(columns_));
      int64_t id;
      // A quoted number keeps its blanks as text (RFC 4180); as a number they are no part of it.
      switch (parse_line_id(io::trim(fields[0]), id)) {
        case Id::ok:
          break;
        case Id::fraction:
          in_.fail("line_id '" + std::string(fields[0]) + "' is not an integer");
        case Id::bad:
          in_.fail("bad line_id '" + std::string(fields[0]) + "'");
      }
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
      for (int k = 0; k < 3; ++k) coordinate(io::trim(fields[1 + k]), k, xyz[k]);
      open_.append_point(xyz[0], xyz[1], xyz[2]);
      for (size_t k = 4; k < fields.size(); ++k) {
        float v;
        number(io::trim(fields[k]), "value", v);
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
  // Splits `row` at its commas into fields_, each trimmed of blanks. A field in double quotes
  // (RFC 4180: R's write.csv, Python's QUOTE_ALL) is its text between them, "" standing for a
  // quote, and may hold commas; one that is not closed on its line (a line break inside quotes)
  // is refused, as is text after the closing quote. The fields stay valid until the next call.
  void split(std::string_view row) {
    fields_.clear();
    if (row.find('"') == std::string_view::npos) {
      size_t start = 0;
      for (;;) {
        const size_t comma = row.find(',', start);
        fields_.push_back(io::trim(row.substr(start, comma - start)));
        if (comma == std::string_view::npos) return;
        start = comma + 1;
      }
    }
    const auto blank = [](char c) { return c == ' ' || c == '\t' || c == '\r'; };
    unquoted_.clear();
    unquoted_.reserve(row.size());  // never outgrown: the fields' views into it stay valid
    size_t i = 0;
    for (;;) {
      const size_t start = i;
      while (i < row.size() && blank(row[i])) ++i;
      if (i < row.size() && row[i] == '"') {
        const std::string column = "column " + std::to_string(fields_.size() + 1);
        const size_t begin = unquoted_.size();
        for (++i;; ++i) {
          if (i == row.size())
            in_.fail(column +
                     ": the quoted field is not closed on its line (a line break inside quotes "
                     "is not supported)");
          if (row[i] == '"') {
            if (i + 1 < row.size() && row[i + 1] == '"') {
              ++i;
            } else {
              break;
            }
          }
          unquoted_ += row[i];
        }
        fields_.push_back(std::string_view(unquoted_).substr(begin));
        for (++i; i < row.size() && blank(row[i]);) ++i;
        if (i == row.size()) return;
        if (row[i] != ',') in_.fail(column + ": text after the closing quote");
        ++i;
      } else {
        const size_t comma = row.find(',', i);
        fields_.push_back(io::trim(row.substr(start, comma - start)));
        if (comma == std::string_view::npos) return;
        i = comma + 1;
      }
    }
  }

  // Reads `token` into `out`, or fails naming it as a bad `what` (coordinate, value).
  void number(std::string_view token, const char* what, float& out) const {
    switch (parse_value(token, out)) {
      case Number::ok:
        return;
      case Number::too_large:
        in_.fail(std::string(what) + " '" + std::string(token) +
                 "' is outside float32's range (magnitude above 3.4028235e38)");
      case Number::bad:
        in_.fail("bad " + std::string(what) + " '" + std::string(token) + "'");
    }
  }

  // A coordinate of `axis`, relative to the origin when there is one: read as a double and
  // subtracted before it is rounded to float32 (lines/origin.hpp).
  void coordinate(std::string_view token, int axis, float& out) const {
    if (!origin_) return number(token, "coordinate", out);
    double world;
    if (!io::parse_double(token, world)) {
      number(token, "coordinate", out);  // fails with the float32 reading's words
      world = out;
    }
    if (!to_local_in_range(world, (*origin_)[axis], out))
      in_.fail("coordinate '" + std::string(token) +
               "' is outside float32's range from the origin (magnitude above 3.4028235e38)");
  }

  // Moves the open line into the batch.
  void close_line(LineSet& batch) {
    open_.end_line();
    append_lines(batch, open_);
    copy_lines(header_, 0, 0, open_);
  }

  static constexpr uint64_t kCheckPoints = 65536;  // the open line's memory checked so often
  io::TextReader in_;
  std::optional<uint64_t> memory_limit_;
  std::optional<Origin> origin_;
  size_t columns_ = 0;
  IdSet finished_;
  std::optional<int64_t> open_id_;  // id of the line being read
  LineSet open_;                    // its points so far (line_offsets {0})
  bool done_ = false;
  std::vector<std::string_view> fields_;  // of the row last split
  std::string unquoted_;                  // the text of its quoted fields
};

}  // namespace

std::unique_ptr<LineReader> open_csv(const std::string& path, const ReadOptions& options) {
  return std::make_unique<CsvReader>(path, options);
}

void write_csv(const LineSet& lines, const std::string& path, const WriteOptions& options) {
  // World coordinates, in float64 text where the lines have an origin (lines/origin.hpp).
  const std::optional<Origin> origin = optional_origin(lines, path);
  io::Writer out(path);
  std::string text = "line_id,x,y,z";
  for (const Attribute& a : lines.attributes) {
    // A name the reader would split or trim is quoted (RFC 4180, "" for a quote), as it reads
    // quoted names; a line break inside quotes it does not read, so such a name is refused.
    if (a.name.find_first_of("\n\r") != std::string::npos)
      throw OutputError(path, "attribute name '" + a.name +
                                  "' holds a line break, which a CSV header cannot hold here");
    const bool blank_end =
        !a.name.empty() && (std::isspace(static_cast<unsigned char>(a.name.front())) ||
                            std::isspace(static_cast<unsigned char>(a.name.back())));
    if (a.name.find_first_of(",\"") == std::string::npos && !blank_end) {
      text += "," + a.name;
      continue;
    }
    text += ",\"";
    for (char c : a.name) text += c == '"' ? std::string("\"\"") : std::string(1, c);
    text += '"';
  }
  text += '\n';
  for (size_t line = 0; line < lines.line_count(); ++line) {
    const std::string id = std::to_string(line);
    for (uint64_t i = lines.line_offsets[line]; i < lines.line_offsets[line + 1]; ++i) {
      text += id;
      for (int k = 0; k < 3; ++k) {
        text += ',';
        if (origin)
          io::append_double(text, to_world(lines.positions[3 * i + k], (*origin)[k]));
        else
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
