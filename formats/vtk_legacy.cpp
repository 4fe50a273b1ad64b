// VTK legacy PolyData (.vtk), ASCII and BINARY (big endian). Lines in the classic layout
// (`LINES cells size`, count then indices per cell) or the 5.1 layout (`LINES offsets conn`,
// `OFFSETS type`, `CONNECTIVITY type`). POINT_DATA becomes vertex attributes and the CELL_DATA of
// the line cells becomes line attributes: SCALARS (any component count), VECTORS, NORMALS,
// TEXTURE_COORDINATES, TENSORS and FIELD arrays; multi-component arrays are split into
// name_x/_y/_z (3 components) or name_0.._k, or name_<component> where a METADATA block's
// COMPONENT_NAMES names every component.

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <optional>
#include <string>
#include <utility>

#include "formats/formats.hpp"
#include "formats/io_util.hpp"

namespace linebake::formats {

namespace {

// Keywords and type names in any case, as VTK's own reader takes them (it lowers each first).
std::string upper(std::string text) {
  for (char& c : text) c = char(std::toupper(static_cast<unsigned char>(c)));
  return text;
}

// Legacy type names; "long" is 8 bytes as written on LP64 systems.
std::optional<io::Scalar> legacy_type(const std::string& type_name) {
  using io::Scalar;
  std::string type = type_name;
  for (char& c : type) c = char(std::tolower(static_cast<unsigned char>(c)));
  if (type == "vtkidtype") return Scalar::int64;
  if (type == "char") return Scalar::int8;
  if (type == "unsigned_char") return Scalar::uint8;
  if (type == "short") return Scalar::int16;
  if (type == "unsigned_short") return Scalar::uint16;
  if (type == "int") return Scalar::int32;
  if (type == "unsigned_int") return Scalar::uint32;
  if (type == "long" || type == "vtktypeint64") return Scalar::int64;
  if (type == "unsigned_long" || type == "vtktypeuint64") return Scalar::uint64;
  if (type == "float") return Scalar::float32;
  if (type == "double") return Scalar::float64;
  return std::nullopt;
}

// Token-and-bytes reader: ASCII parts are read as whitespace-separated tokens, binary blocks
// as raw bytes starting after the line that announced them.
class LegacyStream {
 public:
  LegacyStream(const std::string& path, ProgressFn progress)
      : file_(path),
        progress_(std::move(progress)),
        // As io::TextReader: no more than the file (a small file should not zero a megabyte).
        buffer_(size_t(std::clamp<uint64_t>(file_.size(), 4096, 1 << 20))) {}

  bool fill() {
    if (pos_ < end_) return true;
    if (progress_) progress_(offset(), file_.size());
    base_ += end_;
    pos_ = 0;
    end_ = std::fread(buffer_.data(), 1, buffer_.size(), file_.get());
    return end_ > 0;
  }
  uint64_t offset() const { return base_ + pos_; }
  uint64_t remaining() const { return file_.size() - std::min<uint64_t>(offset(), file_.size()); }
  bool at_end() { return !fill(); }

  std::string line() {
    std::string s;
    while (fill()) {
      const char c = buffer_[pos_++];
      if (c == '\n') break;
      s += c;
    }
    if (!s.empty() && s.back() == '\r') s.pop_back();
    ++line_;
    return s;
  }

  // Next whitespace-separated token, or empty at end of file.
  std::string token() {
    if (!unread_.empty()) return std::exchange(unread_, std::string());
    std::string t;
    while (fill()) {
      const char c = buffer_[pos_];
      if (c == '\n') ++line_;
      if (!std::isspace(static_cast<unsigned char>(c))) break;
      ++pos_;
    }
    while (fill()) {
      const char c = buffer_[pos_];
      if (std::isspace(static_cast<unsigned char>(c))) break;
      t += c;
      ++pos_;
    }
    return t;
  }

  // The next token() returns `t` again (a look ahead that found no METADATA).
  void unread(std::string t) { unread_ = std::move(t); }

  // Whether the rest of the current line holds only blanks, looked at without reading it.
  bool rest_of_line_blank() {
    for (;;) {
      for (size_t i = pos_; i < end_; ++i) {
        if (buffer_[i] == '\n') return true;
        if (!std::isspace(static_cast<unsigned char>(buffer_[i]))) return false;
      }
      // The line goes on past the buffer: keep what is left of it and read more behind it.
      if (end_ - pos_ == buffer_.size()) return true;  // a buffer of blanks
      std::memmove(buffer_.data(), buffer_.data() + pos_, end_ - pos_);
      base_ += pos_;
      end_ -= pos_;
      pos_ = 0;
      const size_t more = std::fread(buffer_.data() + end_, 1, buffer_.size() - end_, file_.get());
      if (more == 0) return true;  // the file ends on this line
      end_ += more;
    }
  }

  // Skips the rest of the current line (binary data follows the newline).
  void skip_line() {
    while (fill()) {
      if (buffer_[pos_++] == '\n') {
        ++line_;
        return;
      }
    }
  }

  void bytes(void* out, size_t n) {
    auto* dst = static_cast<char*>(out);
    while (n > 0) {
      if (!fill()) fail("file truncated inside binary data");
      const size_t take = std::min(n, end_ - pos_);
      std::memcpy(dst, buffer_.data() + pos_, take);
      pos_ += take;
      dst += take;
      n -= take;
    }
  }

  [[noreturn]] void fail(const std::string& message) const {
    throw InputError(file_.path(), at_line(line_) + " (" + at_byte(offset()) + ")", message);
  }
  const std::string& path() const { return file_.path(); }

 private:
  io::File file_;
  ProgressFn progress_;
  std::vector<char> buffer_;
  size_t pos_ = 0, end_ = 0;
  uint64_t base_ = 0;
  uint64_t line_ = 1;
  std::string unread_;
};

// VTK 9 writes an array's component names and information keys (a component's range, once
// asked for, as ParaView always does) after it as a METADATA block, which ends at an empty line:
// the component names (COMPONENT_NAMES, then one a line) are returned, the rest skipped.
// VTK writes a line for each of the array's `components` after COMPONENT_NAMES, an empty one for a
// component without a name: that many are names, up to an INFORMATION line (0: the array is not
// known, names run to INFORMATION or the block's end). Names of fewer components than the array
// has are not used.
std::vector<std::string> read_metadata(LegacyStream& in, size_t components) {
  in.skip_line();
  std::vector<std::string> names;
  for (std::string l = in.line(); !io::trim(l).empty(); l = in.line()) {
    if (std::string(io::trim(l)) != "COMPONENT_NAMES") continue;
    for (size_t c = 0; components == 0 || c < components; ++c) {
      if (in.at_end()) in.fail("file ends inside COMPONENT_NAMES");
      const std::string text(io::trim(in.line()));
      // Fewer names than components (not as VTK writes them): "INFORMATION <count>" follows.
      const std::string_view rest =
          std::string_view(text).substr(std::min<size_t>(text.size(), 12));
      if (text.rfind("INFORMATION ", 0) == 0 && !rest.empty() &&
          rest.find_first_not_of("0123456789") == std::string_view::npos)
        break;
      if (components == 0 && text.empty()) return names;  // the block's end
      names.push_back(io::decode_name(text));
    }
  }
  return names;
}

// `count` values into `out`; `before` and `total` place them in a larger array read in parts, for
// the message of a file that ends early.
template <typename Out>
void read_values(LegacyStream& in, bool binary, const std::string& type_name, size_t count,
                 Out* out, size_t before = 0, size_t total = 0) {
  const std::optional<io::Scalar> type = legacy_type(type_name);
  if (!type) in.fail("unsupported data type '" + type_name + "'");
  if (!binary) {
    for (size_t i = 0; i < count; ++i) {
      const std::string t = in.token();
      double v;
      if (t.empty())
        in.fail("file ends after " + std::to_string(before + i) + " of " +
                std::to_string(total ? total : count) + " values");
      if (!io::parse_double(t, v)) in.fail("bad number '" + t + "'");
      if (!io::convert_scalar(v, out[i])) in.fail("value " + t + " is outside the array's range");
    }
    return;
  }
  // Legacy binary is big endian; decode in chunks so a large array is not held twice.
  const bool swap = std::endian::native == std::endian::little;
  const size_t size = io::scalar_size(*type);
  constexpr size_t kChunk = 1 << 16;
  std::vector<unsigned char> raw(std::min(count, kChunk) * size);
  for (size_t done = 0; done < count; done += kChunk) {
    const size_t n = std::min(kChunk, count - done);
    in.bytes(raw.data(), n * size);
    if (!io::decode_scalars(*type, raw.data(), n, swap, out + done))
      in.fail("a " + type_name + " value outside the range of the array it is read into");
  }
}

// Points relative to `origin` (lines/origin.hpp): read as doubles a block at a time, the origin
// subtracted, then rounded to float32.
void read_local_points(LegacyStream& in, bool binary, const std::string& type_name, size_t count,
                       float* out, const Origin& origin) {
  constexpr size_t kBlock = 3 * 21845;  // whole points
  std::vector<double> world(std::min(count, kBlock));
  for (size_t done = 0; done < count; done += kBlock) {
    const size_t n = std::min(kBlock, count - done);
    read_values(in, binary, type_name, n, world.data(), done, count);
    for (size_t i = 0; i < n; ++i)
      if (!to_local_in_range(world[i], origin[(done + i) % 3], out[done + i]))
        in.fail("point " + std::to_string((done + i) / 3) +
                ": a coordinate outside float32's range from the origin");
  }
}

struct Cells {
  std::vector<int64_t> offsets{0};  // n + 1
  std::vector<int64_t> connectivity;
  size_t count() const { return offsets.size() - 1; }
};

// Splits the classic layout, a count followed by that many indices per cell, into cells.
Cells split_classic(LegacyStream& in, const std::vector<int64_t>& list, uint64_t cell_count) {
  Cells cells;
  size_t at = 0;
  for (uint64_t c = 0; c < cell_count; ++c) {
    if (at >= list.size())
      in.fail("cell list size too small for its " + std::to_string(cell_count) + " cells");
    const int64_t n = list[at++];
    if (n < 0 || static_cast<uint64_t>(n) > list.size() - at)
      in.fail("bad cell size " + std::to_string(n));
    cells.connectivity.insert(cells.connectivity.end(), list.begin() + static_cast<ptrdiff_t>(at),
                              list.begin() + static_cast<ptrdiff_t>(at + static_cast<size_t>(n)));
    at += static_cast<size_t>(n);
    cells.offsets.push_back(static_cast<int64_t>(cells.connectivity.size()));
  }
  if (at != list.size())
    in.fail("cell list size " + std::to_string(list.size()) + " does not match its cells (" +
            std::to_string(at) + ")");
  return cells;
}

// A count from the file, checked before anything is sized from it: each of its `values_each`
// values takes at least one byte of what is left of the file (an int8, or one ASCII digit).
uint64_t checked_count(LegacyStream& in, uint64_t count, uint64_t values_each,
                       const std::string& what) {
  if (count > in.remaining() / values_each)
    in.fail(what + " " + std::to_string(count) + " cannot be in the " +
            std::to_string(in.remaining()) + " bytes left of the file");
  return count;
}

Cells read_cells(LegacyStream& in, bool binary, uint64_t a, uint64_t b) {
  if (a == 0 && b == 0) return {};
  checked_count(in, a, 1, "cell count");
  checked_count(in, b, 1, "cell list size");
  // The 5.1 layout announces OFFSETS next; the classic one starts with the first cell's count.
  std::vector<int64_t> classic(b);
  if (binary) {
    // Binary classic data starts on the next line with raw integers, 5.1 with "OFFSETS".
    in.skip_line();
    char head[7];
    if (b * 4 < 7) {
      read_values(in, true, "int", b, classic.data());
      return split_classic(in, classic, a);
    }
    in.bytes(head, 7);
    if (std::string(head, 7) != "OFFSETS") {
      std::vector<unsigned char> raw(b * 4);
      std::memcpy(raw.data(), head, 7);
      in.bytes(raw.data() + 7, raw.size() - 7);
      (void)io::decode_scalars(io::Scalar::int32, raw.data(), b,  // int32 always fits int64
                               std::endian::native == std::endian::little, classic.data());
      return split_classic(in, classic, a);
    }
  } else {
    std::string t = in.token();
    if (t != "OFFSETS") {
      // Cell by cell, so a wrong size is reported as such rather than as a bad next keyword.
      classic.clear();
      for (uint64_t c = 0; c < a; ++c) {
        if (c > 0) t = in.token();
        int64_t n;
        if (!io::parse_int64(t, n) || n < 0) in.fail("bad cell size '" + t + "'");
        checked_count(in, static_cast<uint64_t>(n), 1, "cell size");
        classic.push_back(n);
        const size_t at = classic.size();
        classic.resize(at + static_cast<size_t>(n));
        read_values(in, false, "int", static_cast<size_t>(n), classic.data() + at);
      }
      if (classic.size() != b)
        in.fail("cell list size " + std::to_string(b) + " does not match its cells (" +
                std::to_string(classic.size()) + ")");
      return split_classic(in, classic, a);
    }
  }
  // 5.1 layout: OFFSETS then CONNECTIVITY arrays.
  Cells cells;
  const std::string offset_type = in.token();
  if (binary) in.skip_line();
  cells.offsets.resize(a);
  if (a == 0) in.fail("OFFSETS needs at least one value");
  read_values(in, binary, offset_type, a, cells.offsets.data());
  if (in.token() != "CONNECTIVITY") in.fail("expected CONNECTIVITY after OFFSETS");
  const std::string conn_type = in.token();
  if (binary) in.skip_line();
  cells.connectivity.resize(b);
  read_values(in, binary, conn_type, b, cells.connectivity.data());
  for (size_t i = 1; i < cells.offsets.size(); ++i)
    if (cells.offsets[i] < cells.offsets[i - 1] || cells.offsets[i] > static_cast<int64_t>(b))
      in.fail("OFFSETS not increasing or past the connectivity");
  if (cells.offsets.front() != 0 || cells.offsets.back() != static_cast<int64_t>(b))
    in.fail("OFFSETS must start at 0 and end at the connectivity size");
  return cells;
}

// Adds the attributes of one array, or fails naming the section.
void add_components(LegacyStream& in, std::vector<Attribute>& target, const std::string& name,
                    const std::vector<float>& values, size_t components, size_t first,
                    size_t count) {
  if (!io::append_components(target, name, values, components, first, count))
    in.fail("array '" + name + "' has fewer tuples than its points or line cells");
}

// A string value of a BINARY file as vtkDataWriter writes it: its length in 1, 2, 4 or 8
// big-endian bytes whose top two bits say which (11, 10, 01, 00), then the bytes.
std::string vtk_binary_string(const std::string& value) {
  const uint64_t n = value.size();
  std::string out;
  const auto put = [&](uint64_t word, int bytes) {
    for (int b = bytes - 1; b >= 0; --b) out += static_cast<char>((word >> (8 * b)) & 0xFF);
  };
  if (n < (uint64_t{1} << 6))
    put(n | 0xC0, 1);
  else if (n < (uint64_t{1} << 14))
    put(n | 0x8000, 2);
  else if (n < (uint64_t{1} << 30))
    put(n | 0x40000000, 4);
  else
    put(n, 8);
  return out + value;
}

std::string read_binary_string(LegacyStream& in) {
  unsigned char first = 0;
  in.bytes(&first, 1);
  const int bytes = (first >> 6) == 3 ? 1 : (first >> 6) == 2 ? 2 : (first >> 6) == 1 ? 4 : 8;
  uint64_t n = first & (bytes == 8 ? 0xFF : 0x3F);
  for (int b = 1; b < bytes; ++b) {
    unsigned char next = 0;
    in.bytes(&next, 1);
    n = (n << 8) | next;
  }
  if (n > in.remaining())
    in.fail("string length " + std::to_string(n) + " past the end of the file");
  std::string value(n, '\0');
  in.bytes(value.data(), n);
  return value;
}

// An ASCII string value: bytes outside printable ASCII, space, '%' and '"' as %XX (VTK's own
// escaping, so an empty or multi-word value stays one line).
std::string encode_string(const std::string& value) {
  std::string out;
  for (unsigned char c : value) {
    if (c <= ' ' || c == '%' || c == '"' || c >= 127) {
      char hex[4];
      std::snprintf(hex, sizeof hex, "%%%02X", c);
      out += hex;
    } else {
      out += static_cast<char>(c);
    }
  }
  return out;
}

}  // namespace

LineSet read_vtk_legacy(const std::string& path, const ReadOptions& options) {
  LegacyStream in(path, options.progress);
  const std::string header = in.line();
  if (header.rfind("# vtk DataFile Version", 0) != 0)
    throw InputError(path, at_line(1),
                     "not a VTK legacy file (header '" + header.substr(0, 40) + "')");
  in.line();  // title
  const std::string encoding = io::trim(in.line()).data();
  const bool binary = upper(encoding).rfind("BINARY", 0) == 0;
  if (!binary && upper(encoding).rfind("ASCII", 0) != 0)
    throw InputError(path, at_line(3), "expected ASCII or BINARY, got '" + encoding + "'");
  if (upper(in.token()) != "DATASET" || upper(in.token()) != "POLYDATA")
    in.fail("expected DATASET POLYDATA (only PolyData holds lines)");

  std::vector<float> points;
  Cells lines_cells;
  bool have_lines = false;
  uint64_t vertex_cells = 0;
  enum class Target { none, point, cell } target = Target::none;
  size_t target_tuples = 0;
  std::vector<Attribute> point_attributes, cell_attributes;
  std::map<std::string, std::string> metadata;

  // What reading it holds (ReadOptions::memory_limit), checked before each array is allocated:
  // the arrays so far, and the new one with its copy while it is split into attributes.
  double held = 0;
  const auto hold = [&](double bytes, double transient, const std::string& place) {
    io::check_read_memory(path, "vtk", held + bytes + transient, place, options.memory_limit);
    held += bytes;
  };
  double point_floats = 3;  // per point: position and point attributes

  // The array read last, whose components a METADATA block after it may name.
  std::vector<Attribute>* last_target = nullptr;
  size_t last_first = 0, last_components = 0;
  std::string last_name;
  const auto added = [&](std::vector<Attribute>& list, size_t before, const std::string& name,
                         size_t components) {
    last_target = list.size() > before ? &list : nullptr;
    last_first = before, last_components = components, last_name = name;  // named if kept
  };
  const auto metadata_block = [&] {
    const std::vector<std::string> names = read_metadata(in, last_components);
    if (last_target && names.size() == last_components)
      for (size_t c = 0; c < last_components; ++c)
        (*last_target)[last_first + c].name =
            io::component_name(last_name, c, last_components, names);
    last_target = nullptr, last_components = 0;
  };
  // After a FIELD array the next token is either its METADATA, alone on its line, or the next
  // array's name, which may be METADATA too (its counts and type follow on the line).
  const auto array_metadata = [&] {
    std::string next = in.token();
    if (upper(next) == "METADATA" && in.rest_of_line_blank())
      metadata_block();
    else
      in.unread(std::move(next));
  };

  // `scale`: COLOR_SCALARS in binary files are bytes for 0..1, as floats in ASCII ones.
  auto read_array = [&](const std::string& name, size_t components, const std::string& type,
                        float scale = 1) {
    if (target == Target::none) in.fail("attribute data before POINT_DATA or CELL_DATA");
    if (binary) in.skip_line();
    checked_count(in, target_tuples, components,
                  "array " + name + " (POINT_DATA or CELL_DATA count)");
    const double bytes = 4.0 * double(components) * double(target_tuples);
    hold(bytes, bytes, "array " + name + " (" + std::to_string(target_tuples) + " tuples)");
    if (target == Target::point) point_floats += double(components);
    std::vector<float> values(components * target_tuples);
    read_values(in, binary, type, values.size(), values.data());
    if (scale != 1)
      for (float& v : values) v *= scale;
    std::vector<Attribute>& list = target == Target::point ? point_attributes : cell_attributes;
    const size_t before = list.size();
    if (target == Target::point)
      add_components(in, point_attributes, name, values, components, 0, target_tuples);
    else if (have_lines)
      add_components(in, cell_attributes, name, values, components, vertex_cells,
                     lines_cells.count());
    added(list, before, name, components);
  };

  for (std::string word = in.token(); !word.empty(); word = in.token()) {
    const std::string key = upper(word);
    if (key == "POINTS") {
      uint64_t n;
      if (!io::parse_uint64(in.token(), n)) in.fail("bad POINTS count");
      checked_count(in, n, 3, "POINTS count");
      const std::string type = in.token();
      if (binary) in.skip_line();
      hold(12.0 * double(n), 0, "POINTS (" + std::to_string(n) + " points)");
      points.resize(3 * n);
      if (options.origin)
        read_local_points(in, binary, type, 3 * n, points.data(), *options.origin);
      else
        read_values(in, binary, type, 3 * n, points.data());
    } else if (key == "LINES" || key == "VERTICES" || key == "POLYGONS" ||
               key == "TRIANGLE_STRIPS") {
      uint64_t a, b;
      if (!io::parse_uint64(in.token(), a) || !io::parse_uint64(in.token(), b))
        in.fail("bad " + key + " header");
      // The cell list as read (int64), then split into offsets and connectivity; counts the
      // file cannot hold are its own fault first.
      checked_count(in, a, 1, "cell count");
      checked_count(in, b, 1, "cell list size");
      hold(8.0 * (double(a) + double(b)), 12.0 * double(b),
           key + " (" + std::to_string(a) + " cells, " + std::to_string(b) + " values)");
      Cells cells = read_cells(in, binary, a, b);
      if (key == "LINES") {
        lines_cells = std::move(cells);
        have_lines = true;
      } else if (key == "VERTICES") {
        vertex_cells = cells.count();
      }
    } else if (key == "POINT_DATA" || key == "CELL_DATA") {
      uint64_t n;
      if (!io::parse_uint64(in.token(), n)) in.fail("bad " + key + " count");
      target = key == "POINT_DATA" ? Target::point : Target::cell;
      target_tuples = n;
    } else if (key == "SCALARS") {
      const std::string name = io::decode_name(in.token());
      const std::string type = in.token();
      // Optional component count, then LOOKUP_TABLE on the next line.
      std::string t = in.token();
      size_t components = 1;
      int64_t parsed;
      if (io::parse_int64(t, parsed)) {
        if (parsed < 1 || parsed > 4) in.fail("SCALARS component count must be 1..4");
        components = static_cast<size_t>(parsed);
        t = in.token();
      }
      if (upper(t) != "LOOKUP_TABLE") in.fail("expected LOOKUP_TABLE after SCALARS " + name);
      in.token();  // table name
      read_array(name, components, type);
    } else if (key == "COLOR_SCALARS") {
      const std::string name = io::decode_name(in.token());
      int64_t components;
      if (!io::parse_int64(in.token(), components) || components < 1 || components > 4)
        in.fail("COLOR_SCALARS component count must be 1..4");
      read_array(name, size_t(components), binary ? "unsigned_char" : "float",
                 binary ? 1.0f / 255.0f : 1.0f);
    } else if (key == "VECTORS" || key == "NORMALS") {
      const std::string name = io::decode_name(in.token());
      read_array(name, 3, in.token());
    } else if (key == "TENSORS") {
      const std::string name = io::decode_name(in.token());
      read_array(name, 9, in.token());
    } else if (key == "TEXTURE_COORDINATES") {
      const std::string name = io::decode_name(in.token());
      int64_t dim;
      if (!io::parse_int64(in.token(), dim) || dim < 1 || dim > 3) in.fail("bad texture dimension");
      read_array(name, static_cast<size_t>(dim), in.token());
    } else if (key == "FIELD") {
      in.token();  // field name
      int64_t arrays;
      if (!io::parse_int64(in.token(), arrays) || arrays < 0) in.fail("bad FIELD array count");
      for (int64_t k = 0; k < arrays; ++k) {
        const std::string name = io::decode_name(in.token());
        if (name == "NULL_ARRAY") continue;
        int64_t components, tuples;
        if (!io::parse_int64(in.token(), components) || !io::parse_int64(in.token(), tuples) ||
            components < 1 || tuples < 0)
          in.fail("bad FIELD array header for " + name);
        const std::string type = in.token();
        if (upper(type) == "STRING" || upper(type) == "UTF8_STRING") {
          // One value before any POINT_DATA/CELL_DATA: the line set's metadata; other string
          // arrays are read past.
          if (components > 64 || tuples > (int64_t{1} << 40))
            in.fail("implausible string array " + name);
          const int64_t values = components * tuples;
          in.skip_line();
          for (int64_t v = 0; v < values; ++v) {
            if (in.at_end()) in.fail("file ends inside string array " + name);
            const std::string value = binary ? read_binary_string(in) : io::decode_name(in.line());
            if (target == Target::none && values == 1) metadata[name] = value;
          }
          // Binary strings follow each other; one newline ends the array.
          if (binary) in.skip_line();
          last_target = nullptr, last_components = size_t(components);
          array_metadata();
          continue;
        }
        if (binary) in.skip_line();
        checked_count(in, static_cast<uint64_t>(tuples), static_cast<uint64_t>(components),
                      "array " + name + " tuple count");
        const double bytes = 4.0 * double(components) * double(tuples);
        hold(bytes, bytes, "FIELD array " + name + " (" + std::to_string(tuples) + " tuples)");
        if (static_cast<size_t>(tuples) == target_tuples && target == Target::point)
          point_floats += double(components);
        std::vector<float> values(static_cast<size_t>(components * tuples));
        read_values(in, binary, type, values.size(), values.data());
        std::vector<Attribute>& list = target == Target::point ? point_attributes : cell_attributes;
        const size_t before = list.size();
        if (static_cast<size_t>(tuples) == target_tuples && target == Target::point)
          add_components(in, point_attributes, name, values, static_cast<size_t>(components), 0,
                         target_tuples);
        else if (static_cast<size_t>(tuples) == target_tuples && target == Target::cell &&
                 have_lines)
          add_components(in, cell_attributes, name, values, static_cast<size_t>(components),
                         vertex_cells, lines_cells.count());
        added(list, before, name, static_cast<size_t>(components));
        array_metadata();
      }
    } else if (key == "LOOKUP_TABLE") {
      in.token();
      int64_t size;
      if (!io::parse_int64(in.token(), size) || size < 0) in.fail("bad LOOKUP_TABLE size");
      if (binary) in.skip_line();
      checked_count(in, static_cast<uint64_t>(size), 4, "LOOKUP_TABLE size");
      std::vector<float> table(static_cast<size_t>(4 * size));
      read_values(in, binary, binary ? "unsigned_char" : "float", table.size(), table.data());
    } else if (key == "METADATA") {
      metadata_block();
    } else {
      in.fail("unexpected keyword '" + word + "'");
    }
  }

  const size_t point_count = points.size() / 3;
  if (!have_lines) throw InputError(path, "", "no LINES in the file");
  for (int64_t index : lines_cells.connectivity)
    if (index < 0 || static_cast<size_t>(index) >= point_count)
      throw InputError(path, "LINES",
                       "point index " + std::to_string(index) + " out of range (" +
                           std::to_string(point_count) + " points)");
  for (const Attribute& a : point_attributes)
    if (a.values.size() != point_count)
      throw InputError(path, "POINT_DATA",
                       "array '" + a.name + "' has " + std::to_string(a.values.size()) +
                           " values for " + std::to_string(point_count) + " points");

  LineSet lines;
  lines.line_offsets.assign(lines_cells.offsets.begin(), lines_cells.offsets.end());
  const auto& conn = lines_cells.connectivity;
  bool identity = conn.size() == point_count;
  for (size_t i = 0; identity && i < conn.size(); ++i)
    identity = conn[i] == static_cast<int64_t>(i);
  if (identity) {
    lines.positions = std::move(points);
    lines.attributes = std::move(point_attributes);
  } else {
    // The points and point attributes gathered along the connectivity.
    hold(4.0 * point_floats * double(conn.size()), 0,
         "LINES (" + std::to_string(conn.size()) + " point indices, gathered)");
    lines.positions.resize(3 * conn.size());
    for (size_t i = 0; i < conn.size(); ++i)
      for (int k = 0; k < 3; ++k) lines.positions[3 * i + k] = points[3 * conn[i] + k];
    for (Attribute& a : point_attributes) {
      Attribute g{a.name, std::vector<float>(conn.size())};
      for (size_t i = 0; i < conn.size(); ++i) g.values[i] = a.values[conn[i]];
      lines.attributes.push_back(std::move(g));
    }
  }
  lines.line_attributes = std::move(cell_attributes);
  lines.metadata = std::move(metadata);
  return lines;
}

void write_vtk_legacy(const LineSet& lines, const std::string& path, const WriteOptions& options) {
  io::Writer out(path);
  const bool binary = !options.ascii;
  const uint64_t n = lines.point_count(), l = lines.line_count();
  // The classic layout stores 32-bit indices; larger sets use the 5.1 offsets layout.
  const bool modern = n + l > static_cast<uint64_t>(INT32_MAX);
  std::string text = modern ? "# vtk DataFile Version 5.1\n" : "# vtk DataFile Version 3.0\n";
  text += "linebake " LINEBAKE_VERSION " line set\n";
  text += binary ? "BINARY\n" : "ASCII\n";
  text += "DATASET POLYDATA\n";
  // World coordinates, float64 where the lines have an origin (lines/origin.hpp), which is then
  // no part of the metadata.
  const std::optional<Origin> origin = optional_origin(lines, path);
  const std::map<std::string, std::string> metadata = metadata_without_origin(lines);
  // Metadata as a data-set FIELD of one-value string arrays, as VTK writes a vtkStringArray.
  if (!metadata.empty()) {
    text += "FIELD FieldData " + std::to_string(metadata.size()) + "\n";
    for (const auto& [key, value] : metadata) {
      text += io::encode_name(key) + " 1 1 string\n";
      text += binary ? vtk_binary_string(value) : encode_string(value);
      text += "\n";
    }
  }
  text += "POINTS " + std::to_string(n) + (origin ? " double\n" : " float\n");
  out.write(text);

  // `count` values value(0), value(1), ...: floats or doubles.
  auto write_values = [&](size_t count, size_t per_row, const auto& value) {
    std::string chunk;
    for (size_t i = 0; i < count; ++i) {
      const auto v = value(i);
      if (binary) {
        const auto swapped = io::byteswap_value(v);
        chunk.append(reinterpret_cast<const char*>(&swapped), sizeof swapped);
      } else {
        if constexpr (std::is_same_v<decltype(v), const double>)
          io::append_double(chunk, v);
        else
          io::append_float(chunk, v);
        chunk += (i + 1) % per_row == 0 ? '\n' : ' ';
      }
      if (chunk.size() > (1 << 20)) {
        out.write(chunk);
        chunk.clear();
      }
    }
    if (!binary && count % per_row != 0) chunk += '\n';
    if (binary) chunk += '\n';
    out.write(chunk);
  };
  auto write_floats = [&](const float* values, size_t count, size_t per_row) {
    write_values(count, per_row, [&](size_t i) { return values[i]; });
  };
  auto write_ints = [&](const std::vector<int64_t>& values, bool wide, size_t per_row) {
    std::string chunk;
    for (size_t i = 0; i < values.size(); ++i) {
      if (binary && wide) {
        const int64_t v = io::byteswap_value(values[i]);
        chunk.append(reinterpret_cast<const char*>(&v), 8);
      } else if (binary) {
        const int32_t v = io::byteswap_value(static_cast<int32_t>(values[i]));
        chunk.append(reinterpret_cast<const char*>(&v), 4);
      } else {
        chunk += std::to_string(values[i]);
        chunk += (i + 1) % per_row == 0 ? '\n' : ' ';
      }
      if (chunk.size() > (1 << 20)) {
        out.write(chunk);
        chunk.clear();
      }
    }
    if (!binary && values.size() % per_row != 0) chunk += '\n';
    if (binary) chunk += '\n';
    out.write(chunk);
  };

  if (origin)
    write_values(lines.positions.size(), 3,
                 [&](size_t i) { return to_world(lines.positions[i], (*origin)[i % 3]); });
  else
    write_floats(lines.positions.data(), lines.positions.size(), 3);
  if (options.progress) options.progress(1, 3);
  if (modern) {
    out.write("LINES " + std::to_string(l + 1) + " " + std::to_string(n) + "\n");
    out.write("OFFSETS vtktypeint64\n");
    std::vector<int64_t> offsets(lines.line_offsets.begin(), lines.line_offsets.end());
    write_ints(offsets, true, 9);
    out.write("CONNECTIVITY vtktypeint64\n");
    std::vector<int64_t> conn(n);
    for (uint64_t i = 0; i < n; ++i) conn[i] = static_cast<int64_t>(i);
    write_ints(conn, true, 9);
  } else {
    out.write("LINES " + std::to_string(l) + " " + std::to_string(n + l) + "\n");
    std::vector<int64_t> cells;
    cells.reserve(n + l);
    for (uint64_t line = 0; line < l; ++line) {
      cells.push_back(static_cast<int64_t>(lines.line_size(line)));
      for (uint64_t i = lines.line_offsets[line]; i < lines.line_offsets[line + 1]; ++i)
        cells.push_back(static_cast<int64_t>(i));
    }
    write_ints(cells, false, SIZE_MAX);
  }
  if (options.progress) options.progress(2, 3);
  auto write_attributes = [&](const std::vector<Attribute>& list, const char* section,
                              uint64_t count) {
    if (list.empty()) return;
    out.write(std::string(section) + " " + std::to_string(count) + "\n");
    // The first as the active SCALARS, the others as a FIELD block, as VTK's own writer does:
    // its readers keep only the first SCALARS section unless told to read them all (every
    // attribute as SCALARS had lost all but the first in ParaView and VTK's default readers).
    const Attribute& first = list.front();
    out.write("SCALARS " + io::encode_name(first.name) + " float 1\nLOOKUP_TABLE default\n");
    write_floats(first.values.data(), first.values.size(), 9);
    if (list.size() == 1) return;
    out.write("FIELD FieldData " + std::to_string(list.size() - 1) + "\n");
    for (size_t i = 1; i < list.size(); ++i) {
      const Attribute& a = list[i];
      out.write(io::encode_name(a.name) + " 1 " + std::to_string(count) + " float\n");
      write_floats(a.values.data(), a.values.size(), 9);
    }
  };
  write_attributes(lines.attributes, "POINT_DATA", n);
  write_attributes(lines.line_attributes, "CELL_DATA", l);
  out.close();
}

}  // namespace linebake::formats
