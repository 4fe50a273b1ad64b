// VTK XML PolyData (.vtp). Reads DataArrays stored inline as ascii or base64, or appended as raw
// bytes or base64, with header_type UInt32/UInt64, either byte order, optionally compressed by
// vtkZLibDataCompressor in blocks. ParaView's default (appended, raw, zlib) is the writer's too.
// The XML part is parsed by pugixml; appended binary data is read from a memory map of the file,
// so it is never copied whole.

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <map>
#include <optional>
#include <pugixml.hpp>
#include <sstream>
#include <string>

#include "core/interrupt.hpp"
#include "formats/formats.hpp"
#include "formats/io_util.hpp"

namespace linebake::formats {

namespace {

class MappedFile {
 public:
  explicit MappedFile(const std::string& path) : path_(path) {
    fd_ = ::open(path.c_str(), O_RDONLY);
    if (fd_ < 0) throw InputError(path, "", std::string("cannot open: ") + std::strerror(errno));
    struct stat st {};
    ::fstat(fd_, &st);
    size_ = static_cast<size_t>(st.st_size);
    if (size_ == 0) throw InputError(path, "", "empty file");
    data_ = static_cast<const char*>(::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE, fd_, 0));
    if (data_ == MAP_FAILED) throw InputError(path, "", "cannot map the file");
  }
  ~MappedFile() {
    if (data_ && data_ != MAP_FAILED) ::munmap(const_cast<char*>(data_), size_);
    if (fd_ >= 0) ::close(fd_);
  }
  std::string_view view() const { return {data_, size_}; }

 private:
  std::string path_;
  int fd_ = -1;
  const char* data_ = nullptr;
  size_t size_ = 0;
};

int base64_value(char c) {
  if (c >= 'A' && c <= 'Z') return c - 'A';
  if (c >= 'a' && c <= 'z') return c - 'a' + 26;
  if (c >= '0' && c <= '9') return c - '0' + 52;
  if (c == '+') return 62;
  if (c == '/') return 63;
  return -1;
}

const char kBase64[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

std::string base64_encode(const unsigned char* data, size_t n) {
  std::string out;
  out.reserve((n + 2) / 3 * 4);
  for (size_t i = 0; i < n; i += 3) {
    const uint32_t b0 = data[i], b1 = i + 1 < n ? data[i + 1] : 0, b2 = i + 2 < n ? data[i + 2] : 0;
    const uint32_t v = b0 << 16 | b1 << 8 | b2;
    out += kBase64[v >> 18 & 63];
    out += kBase64[v >> 12 & 63];
    out += i + 1 < n ? kBase64[v >> 6 & 63] : '=';
    out += i + 2 < n ? kBase64[v & 63] : '=';
  }
  return out;
}

size_t base64_chars(size_t bytes) {
  return (bytes + 2) / 3 * 4;
}

struct Context {
  std::string path;
  bool swap = false;       // file byte order differs from ours
  size_t header_size = 4;  // UInt32 or UInt64
  bool compressed = false;
  std::string_view appended;  // bytes after the '_' of <AppendedData>
  bool appended_base64 = false;
  uint64_t file_bytes = 0;

  [[noreturn]] void fail(const std::string& where, const std::string& message) const {
    throw InputError(path, where, message);
  }
};

std::vector<unsigned char> base64_decode(const Context& ctx, const std::string& where,
                                         std::string_view text) {
  std::vector<unsigned char> out;
  out.reserve(text.size() / 4 * 3);
  uint32_t acc = 0;
  int bits = 0;
  for (char c : text) {
    if (c == '=' || c == ' ' || c == '\n' || c == '\r' || c == '\t') continue;
    const int v = base64_value(c);
    if (v < 0) ctx.fail(where, "invalid base64 character");
    acc = acc << 6 | static_cast<uint32_t>(v);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out.push_back(static_cast<unsigned char>(acc >> bits & 0xFF));
    }
  }
  return out;
}

uint64_t header_word(const Context& ctx, const unsigned char* p) {
  if (ctx.header_size == 4) {
    uint32_t v;
    std::memcpy(&v, p, 4);
    return ctx.swap ? io::byteswap_value(v) : v;
  }
  uint64_t v;
  std::memcpy(&v, p, 8);
  return ctx.swap ? io::byteswap_value(v) : v;
}

constexpr uint64_t kMaxDeflateRatio = 1032;

std::vector<unsigned char> inflate_blocks(const Context& ctx, const std::string& where,
                                          const std::vector<uint64_t>& header,
                                          const unsigned char* data, size_t available) {
  const uint64_t blocks = header[0], block_size = header[1], last_size = header[2];
  uint64_t total = 0;
  uint64_t compressed_total = 0;
  for (uint64_t b = 0; b < blocks; ++b) {
    const uint64_t size = (b + 1 == blocks && last_size != 0) ? last_size : block_size;
    // The compressed sizes first (so that nothing below overflows), then the sizes they claim:
    // deflate expands at most 1032:1 (zlib's technical notes), a larger claim is a lie, refused
    // before it is allocated.
    if (header[3 + b] > available || (compressed_total += header[3 + b]) > available)
      ctx.fail(where, "compressed block past the end of data");
    if (size > kMaxDeflateRatio * header[3 + b] + 64)
      ctx.fail(where, "zlib block " + std::to_string(b) + " claims " + std::to_string(size) +
                          " bytes from " + std::to_string(header[3 + b]) + " compressed");
    total += size;
  }
  std::vector<unsigned char> out(total);
  size_t in_at = 0, out_at = 0;
  for (uint64_t b = 0; b < blocks; ++b) {
    const uint64_t compressed = header[3 + b];
    const uint64_t expected = (b + 1 == blocks && last_size != 0) ? last_size : block_size;
    if (in_at + compressed > available) ctx.fail(where, "compressed block past the end of data");
    uLongf got = static_cast<uLongf>(expected);
    if (uncompress(out.data() + out_at, &got, data + in_at, static_cast<uLong>(compressed)) !=
            Z_OK ||
        got != expected)
      ctx.fail(where, "zlib block " + std::to_string(b) + " does not decompress");
    in_at += compressed;
    out_at += expected;
  }
  return out;
}

// Raw (decoded) bytes of a binary data array: header words then data.
std::vector<unsigned char> decode_binary(const Context& ctx, const std::string& where,
                                         std::string_view stored, bool base64) {
  const size_t hs = ctx.header_size;
  if (!base64) {
    const auto* p = reinterpret_cast<const unsigned char*>(stored.data());
    if (stored.size() < hs) ctx.fail(where, "data header truncated");
    if (!ctx.compressed) {
      const uint64_t n = header_word(ctx, p);
      if (n > stored.size() - hs)
        ctx.fail(where, "data size " + std::to_string(n) + " past the end of the file");
      return {p + hs, p + hs + n};
    }
    if (stored.size() < 3 * hs) ctx.fail(where, "compression header truncated");
    const uint64_t blocks = header_word(ctx, p);
    if (blocks > stored.size() / hs) ctx.fail(where, "implausible block count");
    std::vector<uint64_t> header(3 + blocks);
    if ((3 + blocks) * hs > stored.size()) ctx.fail(where, "compression header truncated");
    for (size_t i = 0; i < header.size(); ++i) header[i] = header_word(ctx, p + i * hs);
    const size_t used = (3 + blocks) * hs;
    return inflate_blocks(ctx, where, header, p + used, stored.size() - used);
  }
  // base64: the header tells how many characters the array takes, so only those are decoded
  // (appended data holds every array back to back).
  const std::string_view text = io::trim(stored);
  auto decode = [&](size_t from, size_t chars) {
    if (from + chars > text.size()) ctx.fail(where, "base64 data shorter than its header says");
    return base64_decode(ctx, where, text.substr(from, chars));
  };
  const std::vector<unsigned char> first = decode(0, base64_chars(hs));
  if (!ctx.compressed) {
    // Header and data are one base64 stream.
    const uint64_t n = header_word(ctx, first.data());
    if (n > text.size())
      ctx.fail(where, "data size " + std::to_string(n) + " past the end of the file");
    std::vector<unsigned char> all = decode(0, base64_chars(hs + n));
    return {all.begin() + static_cast<ptrdiff_t>(hs), all.begin() + static_cast<ptrdiff_t>(hs + n)};
  }
  // The compression header is encoded on its own, then the blocks as one stream.
  const uint64_t blocks = header_word(ctx, first.data());
  if (blocks > text.size()) ctx.fail(where, "implausible block count");
  const size_t header_chars = base64_chars((3 + blocks) * hs);
  const std::vector<unsigned char> head = decode(0, header_chars);
  std::vector<uint64_t> header(3 + blocks);
  uint64_t compressed_bytes = 0;
  for (size_t i = 0; i < header.size(); ++i) {
    header[i] = header_word(ctx, head.data() + i * hs);
    if (i >= 3) compressed_bytes += header[i];
  }
  if (compressed_bytes > text.size()) ctx.fail(where, "compressed sizes past the end of the file");
  const std::vector<unsigned char> data = decode(header_chars, base64_chars(compressed_bytes));
  return inflate_blocks(ctx, where, header, data.data(), data.size());
}

std::optional<io::Scalar> xml_type(const std::string& type) {
  using io::Scalar;
  static const std::pair<const char*, Scalar> names[] = {
      {"Int8", Scalar::int8},      {"UInt8", Scalar::uint8},   {"Int16", Scalar::int16},
      {"UInt16", Scalar::uint16},  {"Int32", Scalar::int32},   {"UInt32", Scalar::uint32},
      {"Int64", Scalar::int64},    {"UInt64", Scalar::uint64}, {"Float32", Scalar::float32},
      {"Float64", Scalar::float64}};
  for (const auto& [name, scalar] : names)
    if (type == name) return scalar;
  return std::nullopt;
}

// The most values a DataArray can hold in this file: an ASCII value takes at least two
// characters, a binary one its size over deflate's best ratio.
uint64_t most_values(const Context& ctx, const pugi::xml_node& node) {
  const std::optional<io::Scalar> type = xml_type(node.attribute("type").as_string());
  const uint64_t size = type ? io::scalar_size(*type) : 1;
  return std::string(node.attribute("format").as_string("ascii")) == "ascii"
             ? ctx.file_bytes / 2 + 1
             : ctx.file_bytes * kMaxDeflateRatio / size + 1;
}

// A count from the file's attributes, checked against the file before anything is allocated for
// it: past what the file can hold, the file's error.
void check_value_count(const Context& ctx, const pugi::xml_node& node, uint64_t count) {
  if (count > most_values(ctx, node))
    ctx.fail("DataArray '" + std::string(node.attribute("Name").as_string()) + "'",
             std::to_string(count) + " values cannot be in a file of " +
                 std::to_string(ctx.file_bytes) + " bytes");
}

// What reading `values` of a DataArray holds besides them, its count checked first: a token per
// value (16 bytes) when it is ASCII, else its decoded bytes.
double bytes_reading(const Context& ctx, const pugi::xml_node& node, uint64_t values) {
  check_value_count(ctx, node, values);
  const std::optional<io::Scalar> type = xml_type(node.attribute("type").as_string());
  const bool ascii = std::string(node.attribute("format").as_string("ascii")) == "ascii";
  return double(values) * (ascii ? 16.0 : double(type ? io::scalar_size(*type) : 8));
}

// Reads a DataArray into `count` values of Out, checking its size.
template <typename Out>
std::vector<Out> read_array(const Context& ctx, const pugi::xml_node& node, size_t count) {
  const std::string name = node.attribute("Name").as_string();
  const std::string where = "DataArray '" + name + "'";
  const std::string type_name = node.attribute("type").as_string();
  const std::optional<io::Scalar> type = xml_type(type_name);
  if (!type) ctx.fail(where, "unsupported type '" + type_name + "'");
  const size_t size = io::scalar_size(*type);
  const std::string format = node.attribute("format").as_string("ascii");
  check_value_count(ctx, node, count);
  std::vector<Out> out(count);
  if (format == "ascii") {
    const auto tokens = io::split_whitespace(node.child_value());
    if (tokens.size() != count)
      ctx.fail(where, std::to_string(tokens.size()) + " values, expected " + std::to_string(count));
    for (size_t i = 0; i < count; ++i) {
      double v;
      if (!io::parse_double(tokens[i], v))
        ctx.fail(where, "bad number '" + std::string(tokens[i]) + "'");
      if (!io::convert_scalar(v, out[i]))
        ctx.fail(where, "value " + std::string(tokens[i]) + " is outside the array's range");
    }
    return out;
  }
  std::vector<unsigned char> bytes;
  if (format == "binary") {
    bytes = decode_binary(ctx, where, node.child_value(), true);
  } else if (format == "appended") {
    const uint64_t offset = node.attribute("offset").as_ullong(UINT64_MAX);
    if (offset >= ctx.appended.size()) ctx.fail(where, "appended offset out of range");
    bytes = decode_binary(ctx, where, ctx.appended.substr(offset), ctx.appended_base64);
  } else {
    ctx.fail(where, "unknown format '" + format + "'");
  }
  if (bytes.size() != count * size)
    ctx.fail(where,
             std::to_string(bytes.size()) + " bytes, expected " + std::to_string(count * size));
  if (!io::decode_scalars(*type, bytes.data(), count, ctx.swap, out.data()))
    ctx.fail(where, "a " + type_name + " value outside the range of the array it is read into");
  return out;
}

void read_attributes(const Context& ctx, const pugi::xml_node& data, size_t tuples, size_t first,
                     size_t count, std::vector<Attribute>& target) {
  for (pugi::xml_node a : data.children("DataArray")) {
    const std::string name = a.attribute("Name").as_string("unnamed");
    const size_t components = a.attribute("NumberOfComponents").as_ullong(1);
    if (components == 0 || components > 16)
      ctx.fail("DataArray '" + name + "'", "bad NumberOfComponents");
    const std::vector<float> values = read_array<float>(ctx, a, tuples * components);
    std::vector<std::string> component_names;  // ComponentName0.., as VTK writes them
    for (size_t c = 0; c < components; ++c)
      component_names.push_back(
          a.attribute(("ComponentName" + std::to_string(c)).c_str()).as_string());
    if (!io::append_components(target, name, values, components, first, count, component_names))
      ctx.fail("DataArray '" + name + "'", "fewer tuples than its points or cells");
  }
}

}  // namespace

// The data set's FieldData string arrays of one value: the line set's metadata, as VTK writes a
// vtkStringArray (ascii: the bytes as numbers, each string ending in 0; binary or appended: the
// same bytes behind the size header, base64 or raw, compressed or not). Other field arrays are
// not line-set data.
std::map<std::string, std::string> read_field_strings(const Context& ctx,
                                                      const pugi::xml_node& field_data) {
  std::map<std::string, std::string> metadata;
  for (const pugi::xml_node& array : field_data.children()) {
    if (std::string(array.attribute("type").as_string()) != "String" ||
        array.attribute("NumberOfTuples").as_ullong(0) != 1)
      continue;
    const std::string name = array.attribute("Name").as_string();
    const std::string format = array.attribute("format").as_string("ascii");
    const std::string where = "FieldData array " + name;
    std::string bytes;
    if (format == "ascii") {
      std::istringstream in(array.child_value());
      for (int code; in >> code;) {
        if (code < 0 || code > 255) ctx.fail(where, "character code out of range");
        bytes += static_cast<char>(code);
      }
    } else if (format == "binary") {
      const std::vector<unsigned char> raw = decode_binary(ctx, where, array.child_value(), true);
      bytes.assign(raw.begin(), raw.end());
    } else if (format == "appended") {  // VTK's writer's default
      const uint64_t offset = array.attribute("offset").as_ullong(UINT64_MAX);
      if (offset >= ctx.appended.size()) ctx.fail(where, "appended offset out of range");
      const std::vector<unsigned char> raw =
          decode_binary(ctx, where, ctx.appended.substr(offset), ctx.appended_base64);
      bytes.assign(raw.begin(), raw.end());
    } else {
      ctx.fail(where, "unknown format '" + format + "'");
    }
    metadata[name] = bytes.substr(0, bytes.find('\0'));
  }
  return metadata;
}

LineSet read_vtp(const std::string& path, const ReadOptions& options) {
  MappedFile file(path);
  const std::string_view content = file.view();
  Context ctx;
  ctx.path = path;
  ctx.file_bytes = content.size();

  // The appended section is raw bytes, not XML: parse the part before it, closed by hand.
  std::string xml;
  const size_t appended_tag = content.find("<AppendedData");
  // The XML (all of the file but appended data) is held twice while it is parsed: mapped, and
  // copied here, parsed in place (the parser keeps no copy of its own), with its nodes (about
  // 64 bytes an element, 40 an attribute, counted by their '<' and '=').
  const size_t xml_bytes = std::min(appended_tag, content.size());
  double markup = 0;
  for (const char c : content.substr(0, xml_bytes)) markup += c == '<' ? 64 : c == '=' ? 40 : 0;
  const double xml_held = 2.0 * double(xml_bytes) + markup;
  io::check_read_memory(path, "vtp", xml_held, "its XML (" + std::to_string(xml_bytes) + " bytes)",
                        options.memory_limit);
  if (appended_tag != std::string_view::npos) {
    const size_t close = content.find('>', appended_tag);
    const size_t underscore = close == std::string_view::npos ? close : content.find('_', close);
    if (underscore == std::string_view::npos)
      throw InputError(path, at_byte(appended_tag), "AppendedData without its '_' marker");
    ctx.appended = content.substr(underscore + 1);
    const std::string tag(content.substr(appended_tag, close - appended_tag));
    ctx.appended_base64 = tag.find("\"base64\"") != std::string::npos;
    xml.assign(content.substr(0, appended_tag));
    xml += "</VTKFile>";
  } else {
    xml.assign(content);
  }
  pugi::xml_document doc;
  const pugi::xml_parse_result parsed = doc.load_buffer_inplace(xml.data(), xml.size());
  if (!parsed)
    throw InputError(path, at_byte(static_cast<uint64_t>(parsed.offset)),
                     std::string("XML error: ") + parsed.description());
  const pugi::xml_node root = doc.child("VTKFile");
  if (!root || std::string(root.attribute("type").as_string()) != "PolyData")
    throw InputError(path, "VTKFile", "not a VTK XML PolyData file");
  const std::string byte_order = root.attribute("byte_order").as_string("LittleEndian");
  ctx.swap = (byte_order == "BigEndian") != (std::endian::native == std::endian::big);
  const std::string header_type = root.attribute("header_type").as_string("UInt32");
  if (header_type != "UInt32" && header_type != "UInt64")
    throw InputError(path, "VTKFile", "unsupported header_type " + header_type);
  ctx.header_size = header_type == "UInt64" ? 8 : 4;
  const std::string compressor = root.attribute("compressor").as_string("");
  if (!compressor.empty() && compressor != "vtkZLibDataCompressor")
    throw InputError(path, "VTKFile", "unsupported compressor " + compressor + " (zlib only)");
  ctx.compressed = !compressor.empty();

  const pugi::xml_node piece = root.child("PolyData").child("Piece");
  if (!piece) throw InputError(path, "PolyData", "no Piece");
  if (piece.next_sibling("Piece"))
    throw InputError(path, "PolyData", "several Pieces are not supported");
  const uint64_t point_count = piece.attribute("NumberOfPoints").as_ullong(0);
  const uint64_t line_count = piece.attribute("NumberOfLines").as_ullong(0);
  const uint64_t vert_count = piece.attribute("NumberOfVerts").as_ullong(0);
  const uint64_t poly_count = piece.attribute("NumberOfPolys").as_ullong(0);
  const uint64_t strip_count = piece.attribute("NumberOfStrips").as_ullong(0);
  if (options.progress) options.progress(0, 3);
  // Counts past what any file holds (and whose products would wrap) are refused here.
  for (const auto& [name, count] : {std::pair<const char*, uint64_t>{"NumberOfPoints", point_count},
                                    {"NumberOfLines", line_count},
                                    {"NumberOfVerts", vert_count},
                                    {"NumberOfPolys", poly_count},
                                    {"NumberOfStrips", strip_count}})
    if (count > ctx.file_bytes * kMaxDeflateRatio)
      throw InputError(path, "Piece",
                       std::string(name) + " " + std::to_string(count) +
                           " cannot be in a file of " + std::to_string(ctx.file_bytes) + " bytes");
  // Surfaces without lines are no line set: said, not read as an empty one (as the legacy
  // reader's "no LINES").
  if (line_count == 0 && poly_count + strip_count > 0)
    throw InputError(path, "Piece",
                     "no Lines cells, only surfaces (" + std::to_string(poly_count) + " Polys, " +
                         std::to_string(strip_count) +
                         " Strips): linebake reads the Lines of a PolyData file");

  // What reading it holds (ReadOptions::memory_limit): the mapped file, the XML and its copy in
  // the parser, the arrays (int64 offsets and connectivity, float points and attributes), and
  // the line set gathered from them once the connectivity is known.
  const auto components_of = [](const pugi::xml_node& data) {
    double sum = 0;
    for (pugi::xml_node a : data.children("DataArray"))
      sum += double(std::min<uint64_t>(a.attribute("NumberOfComponents").as_ullong(1), 16));
    return sum;
  };
  // While an array is read it holds more than its values (bytes_reading), its count checked
  // against the file first.
  const uint64_t cells = vert_count + line_count + poly_count + strip_count;
  double largest_read = 0;
  const auto reading = [&](const pugi::xml_node& data, uint64_t tuples, bool times_components) {
    for (pugi::xml_node a : data.children("DataArray")) {
      const uint64_t components =
          times_components ? std::min<uint64_t>(a.attribute("NumberOfComponents").as_ullong(1), 16)
                           : 1;
      // tuples is bounded by the file's size, components by 16: no wrap
      largest_read = std::max(largest_read, bytes_reading(ctx, a, tuples * components));
    }
  };
  reading(piece.child("Points"), 3 * point_count, false);
  // With an origin, the points are read as doubles first (below).
  if (options.origin) largest_read += 24 * double(point_count);
  reading(piece.child("PointData"), point_count, true);
  reading(piece.child("CellData"), cells, true);
  for (pugi::xml_node a : piece.child("Lines").children("DataArray"))
    if (std::string(a.attribute("Name").as_string()) == "offsets")
      largest_read = std::max(largest_read, bytes_reading(ctx, a, line_count));
  const double point_floats = 3 + components_of(piece.child("PointData"));
  const double held = double(ctx.file_bytes) + xml_held - double(xml_bytes) +
                      4 * point_floats * double(point_count) + 16 * double(line_count) +
                      4 * components_of(piece.child("CellData")) * double(cells);
  io::check_read_memory(path, "vtp", held + 8 * double(point_count) + largest_read,
                        "Piece (" + std::to_string(point_count) + " points, " +
                            std::to_string(line_count) + " lines)",
                        options.memory_limit);

  LineSet lines;
  const pugi::xml_node points = piece.child("Points").child("DataArray");
  if (!points && point_count > 0) throw InputError(path, "Points", "no DataArray");
  if (points) {
    if (points.attribute("NumberOfComponents").as_ullong(1) != 3)
      throw InputError(path, "Points", "points need 3 components");
    if (options.origin) {  // subtracted in double, then rounded (lines/origin.hpp)
      const std::vector<double> world = read_array<double>(ctx, points, 3 * point_count);
      lines.positions.resize(world.size());
      for (size_t i = 0; i < world.size(); ++i)
        if (!to_local_in_range(world[i], (*options.origin)[i % 3], lines.positions[i]))
          throw InputError(path, "Points",
                           "point " + std::to_string(i / 3) +
                               ": a coordinate outside float32's range from the origin");
    } else {
      lines.positions = read_array<float>(ctx, points, 3 * point_count);
    }
  }
  std::vector<int64_t> connectivity, offsets;
  for (pugi::xml_node a : piece.child("Lines").children("DataArray")) {
    const std::string name = a.attribute("Name").as_string();
    if (name == "offsets") offsets = read_array<int64_t>(ctx, a, line_count);
  }
  // The last offset is the connectivity's length: one its array cannot hold in this file is the
  // file's fault.
  if (!offsets.empty() && offsets.back() < 0)
    throw InputError(path, "Lines",
                     "the last offset " + std::to_string(offsets.back()) + " is negative");
  const uint64_t connectivity_size = offsets.empty() ? 0 : static_cast<uint64_t>(offsets.back());
  // The connectivity as it is read, and the points and attributes gathered along it (unless it
  // walks the points in order, which leaves them as they are).
  double connectivity_read = 0;
  bool has_connectivity = false;
  for (pugi::xml_node a : piece.child("Lines").children("DataArray"))
    if (std::string(a.attribute("Name").as_string()) == "connectivity") {
      has_connectivity = true;
      connectivity_read = bytes_reading(ctx, a, connectivity_size);
    }
  if (connectivity_size > 0 && !has_connectivity)
    throw InputError(path, "Lines", "missing connectivity array");
  io::check_read_memory(
      path, "vtp", held + (8 + 4 * point_floats) * double(connectivity_size) + connectivity_read,
      "Lines (" + std::to_string(connectivity_size) + " point indices)", options.memory_limit);
  for (pugi::xml_node a : piece.child("Lines").children("DataArray")) {
    if (std::string(a.attribute("Name").as_string()) == "connectivity")
      connectivity = read_array<int64_t>(ctx, a, connectivity_size);
  }
  if (offsets.size() != line_count) throw InputError(path, "Lines", "missing offsets array");
  if (connectivity.size() != connectivity_size)
    throw InputError(path, "Lines", "missing connectivity array");
  int64_t previous = 0;
  for (int64_t o : offsets) {
    if (o < previous) throw InputError(path, "Lines", "offsets decrease");
    previous = o;
  }
  for (int64_t i : connectivity)
    if (i < 0 || static_cast<uint64_t>(i) >= point_count)
      throw InputError(path, "Lines", "point index " + std::to_string(i) + " out of range");
  if (options.progress) options.progress(1, 3);

  std::vector<Attribute> point_attributes;
  read_attributes(ctx, piece.child("PointData"), point_count, 0, point_count, point_attributes);
  read_attributes(ctx, piece.child("CellData"), cells, vert_count, line_count,
                  lines.line_attributes);

  lines.line_offsets.assign(1, 0);
  for (int64_t o : offsets) lines.line_offsets.push_back(static_cast<uint64_t>(o));
  bool identity = connectivity.size() == point_count;
  for (size_t i = 0; identity && i < connectivity.size(); ++i)
    identity = connectivity[i] == static_cast<int64_t>(i);
  if (identity) {
    lines.attributes = std::move(point_attributes);
  } else {
    std::vector<float> gathered(3 * connectivity.size());
    for (size_t i = 0; i < connectivity.size(); ++i)
      for (int k = 0; k < 3; ++k) gathered[3 * i + k] = lines.positions[3 * connectivity[i] + k];
    lines.positions = std::move(gathered);
    for (Attribute& a : point_attributes) {
      Attribute g{a.name, std::vector<float>(connectivity.size())};
      for (size_t i = 0; i < connectivity.size(); ++i) g.values[i] = a.values[connectivity[i]];
      lines.attributes.push_back(std::move(g));
    }
  }
  lines.metadata =
      read_field_strings(ctx, doc.child("VTKFile").child("PolyData").child("FieldData"));
  if (options.progress) options.progress(3, 3);
  return lines;
}

namespace {

class VtpWriter {
 public:
  VtpWriter(const WriteOptions& o) : options_(o) {
    if (o.vtp_encoding != "appended" && o.vtp_encoding != "appended-base64" &&
        o.vtp_encoding != "base64" && o.vtp_encoding != "ascii")
      throw Error("vtp encoding must be appended, appended-base64, base64 or ascii");
  }

  // Returns the <DataArray .../> element text, adding appended bytes where needed.
  template <typename T>
  std::string array(const std::string& name, const char* type, size_t components, const T* values,
                    size_t count) {
    std::string head = "<DataArray type=\"" + std::string(type) + "\" Name=\"" + escape(name) +
                       "\" NumberOfComponents=\"" + std::to_string(components) + "\"";
    if (options_.vtp_encoding == "ascii") {
      std::string text = head + " format=\"ascii\">\n";
      for (size_t i = 0; i < count; ++i) {
        if constexpr (std::is_same_v<T, double>)
          io::append_double(text, values[i]);
        else if constexpr (std::is_floating_point_v<T>)
          io::append_float(text, static_cast<float>(values[i]));
        else
          text += std::to_string(values[i]);
        text += (i + 1) % 9 == 0 || i + 1 == count ? '\n' : ' ';
      }
      return text + "</DataArray>\n";
    }
    const auto* bytes = reinterpret_cast<const unsigned char*>(values);
    const size_t n = count * sizeof(T);
    const bool base64 = options_.vtp_encoding != "appended";
    std::string encoded = encode(bytes, n, base64);
    if (options_.vtp_encoding == "base64")
      return head + " format=\"binary\">\n" + encoded + "\n</DataArray>\n";
    const size_t offset = appended_.size();
    appended_ += encoded;
    return head + " format=\"appended\" offset=\"" + std::to_string(offset) + "\"/>\n";
  }

  std::string header_attributes() const {
    std::string s = " header_type=\"";
    s += options_.vtp_header_uint64 ? "UInt64\"" : "UInt32\"";
    if (options_.vtp_compress && options_.vtp_encoding != "ascii")
      s += " compressor=\"vtkZLibDataCompressor\"";
    return s;
  }
  const std::string& appended() const { return appended_; }

  static std::string escape(const std::string& s) {
    std::string out;
    for (char c : s) {
      if (c == '&')
        out += "&amp;";
      else if (c == '<')
        out += "&lt;";
      else if (c == '>')
        out += "&gt;";
      else if (c == '"')
        out += "&quot;";
      else if (c == '\t' || c == '\n' || c == '\r')  // kept: a parser turns raw ones into spaces
        out += "&#" + std::to_string(int(c)) + ";";
      else if (static_cast<unsigned char>(c) < 0x20)  // not allowed in XML 1.0, even escaped
        out += "\xEF\xBF\xBD";                        // U+FFFD REPLACEMENT CHARACTER
      else
        out += c;
    }
    return out;
  }

 private:
  void put_word(std::string& out, uint64_t v) const {
    if (options_.vtp_header_uint64) {
      out.append(reinterpret_cast<const char*>(&v), 8);
    } else {
      if (v > UINT32_MAX) throw Error("vtp: array too large for a UInt32 header; use UInt64");
      const auto w = static_cast<uint32_t>(v);
      out.append(reinterpret_cast<const char*>(&w), 4);
    }
  }

  std::string encode(const unsigned char* bytes, size_t n, bool base64) const {
    auto to_text = [&](const std::string& raw) {
      return base64 ? base64_encode(reinterpret_cast<const unsigned char*>(raw.data()), raw.size())
                    : raw;
    };
    if (!options_.vtp_compress) {
      std::string raw;
      put_word(raw, n);
      raw.append(reinterpret_cast<const char*>(bytes), n);
      return to_text(raw);
    }
    constexpr size_t kBlock = 1 << 15;
    const size_t blocks = (n + kBlock - 1) / kBlock;
    std::string header, data;
    put_word(header, blocks);
    put_word(header, kBlock);
    put_word(header, n % kBlock);
    for (size_t b = 0; b < blocks; ++b) {
      const size_t size = std::min(kBlock, n - b * kBlock);
      uLongf bound = compressBound(static_cast<uLong>(size));
      std::string block(bound, '\0');
      if (compress2(reinterpret_cast<Bytef*>(block.data()), &bound, bytes + b * kBlock,
                    static_cast<uLong>(size), Z_DEFAULT_COMPRESSION) != Z_OK)
        throw Error("zlib compression failed");
      block.resize(bound);
      put_word(header, bound);
      data += block;
      if (b % 64 == 63) throw_if_interrupted();  // Ctrl-C every 2 MiB compressed
    }
    // The compression header is encoded separately from the blocks, as VTK does.
    return to_text(header) + to_text(data);
  }

  const WriteOptions& options_;
  std::string appended_;
};

// The first attribute as the active scalars (Scalars="NAME"), as VTK's legacy reader makes the
// first SCALARS section active: without it ParaView draws the .vtp in a plain colour while the
// .vtk of the same lines is colour-mapped.
std::string active_scalars(const std::vector<Attribute>& attributes) {
  if (attributes.empty()) return "";
  return " Scalars=\"" + VtpWriter::escape(attributes.front().name) + "\"";
}

}  // namespace

void write_vtp(const LineSet& lines, const std::string& path, const WriteOptions& options) {
  static_assert(std::endian::native == std::endian::little, "writer assumes little endian");
  VtpWriter w(options);
  const uint64_t n = lines.point_count(), l = lines.line_count();
  std::string body =
      "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"1.0\" "
      "byte_order=\"LittleEndian\"" +
      w.header_attributes() + ">\n<PolyData>\n";
  // World coordinates, Float64 where the lines have an origin (lines/origin.hpp), which is then
  // no part of the metadata.
  const std::optional<Origin> origin = optional_origin(lines, path);
  const std::map<std::string, std::string> metadata = metadata_without_origin(lines);
  // Metadata as FieldData string arrays (what VTK writes for a vtkStringArray; ParaView shows
  // them in its Information panel).
  if (!metadata.empty()) {
    body += "<FieldData>\n";
    for (const auto& [key, value] : metadata) {
      body += "<Array type=\"String\" Name=\"" + VtpWriter::escape(key) +
              "\" NumberOfTuples=\"1\" format=\"ascii\">\n";
      for (unsigned char c : value) body += std::to_string(c) + " ";
      body += "0\n</Array>\n";
    }
    body += "</FieldData>\n";
  }
  body += "<Piece NumberOfPoints=\"" + std::to_string(n) +
          "\" NumberOfVerts=\"0\" NumberOfLines=\"" + std::to_string(l) +
          "\" NumberOfStrips=\"0\" NumberOfPolys=\"0\">\n";
  if (origin) {
    std::vector<double> world(3 * n);
    for (size_t i = 0; i < world.size(); ++i)
      world[i] = to_world(lines.positions[i], (*origin)[i % 3]);
    body += "<Points>\n" + w.array("Points", "Float64", 3, world.data(), 3 * n) + "</Points>\n";
  } else {
    body += "<Points>\n" + w.array("Points", "Float32", 3, lines.positions.data(), 3 * n) +
            "</Points>\n";
  }
  std::vector<int64_t> connectivity(n), offsets(l);
  for (uint64_t i = 0; i < n; ++i) connectivity[i] = static_cast<int64_t>(i);
  for (uint64_t i = 0; i < l; ++i) offsets[i] = static_cast<int64_t>(lines.line_offsets[i + 1]);
  body += "<Lines>\n" + w.array("connectivity", "Int64", 1, connectivity.data(), n) +
          w.array("offsets", "Int64", 1, offsets.data(), l) + "</Lines>\n";
  if (options.progress) options.progress(1, 3);
  body += "<PointData" + active_scalars(lines.attributes) + ">\n";
  for (const Attribute& a : lines.attributes)
    body += w.array(a.name, "Float32", 1, a.values.data(), a.values.size());
  body += "</PointData>\n<CellData" + active_scalars(lines.line_attributes) + ">\n";
  for (const Attribute& a : lines.line_attributes)
    body += w.array(a.name, "Float32", 1, a.values.data(), a.values.size());
  body += "</CellData>\n</Piece>\n</PolyData>\n";
  io::Writer out(path);
  out.write(body);
  if (options.vtp_encoding == "appended" || options.vtp_encoding == "appended-base64") {
    out.write(options.vtp_encoding == "appended" ? "<AppendedData encoding=\"raw\">\n_"
                                                 : "<AppendedData encoding=\"base64\">\n_");
    out.write(w.appended());
    out.write("\n</AppendedData>\n");
  }
  out.write("</VTKFile>\n");
  out.close();
  if (options.progress) options.progress(3, 3);
}

}  // namespace linebake::formats
