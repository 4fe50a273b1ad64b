// LineVis .binlines (little endian).
// Version 1: uint32 version, uint32 lines, uint32 attributes; per line uint32 n, n x float3
// positions, then attributes x n floats (attribute-major).
// Version 2 (as linebake reads and writes it): the same header, then per attribute a uint32
// byte length and that many bytes of name, then the lines as in version 1. The public LineVis
// loader reads only version 1; write version 1 for it.

#include "formats/formats.hpp"
#include "formats/io_util.hpp"

namespace linebake::formats {

LineSet read_binlines(const std::string& path, const ReadOptions& options) {
  io::BinaryReader in(path, options.progress);
  if (in.size() == 0) in.fail("empty file");
  const auto version = in.read_value<uint32_t>("version");
  if (version != 1 && version != 2)
    in.fail_at(0,
               "unsupported .binlines version " + std::to_string(version) + " (expected 1 or 2)");
  const auto line_count = in.read_value<uint32_t>("line count");
  const auto attribute_count = in.read_value<uint32_t>("attribute count");
  if (attribute_count > 4096)
    in.fail_at(8, "implausible attribute count " + std::to_string(attribute_count));

  LineSet lines;
  lines.attributes.resize(attribute_count);
  for (uint32_t a = 0; a < attribute_count; ++a) {
    lines.attributes[a].name = "attribute" + std::to_string(a);
    if (version == 2) {
      const uint64_t at = in.offset();
      const auto length = in.read_value<uint32_t>("attribute name length");
      if (length > 4096)
        in.fail_at(at, "implausible attribute name length " + std::to_string(length));
      std::string name(length, '\0');
      in.read(name.data(), length, "attribute name");
      lines.attributes[a].name = name;
    }
  }
  // Each line needs at least its 4-byte count: a count beyond that is a corrupt header.
  if (static_cast<uint64_t>(line_count) * 4 > in.size() - in.offset())
    in.fail_at(4, "line count " + std::to_string(line_count) + " does not fit the file size");
  lines.line_offsets.reserve(line_count + 1);
  for (uint32_t line = 0; line < line_count; ++line) {
    const uint64_t at = in.offset();
    const auto n = in.read_value<uint32_t>("point count");
    const uint64_t needed = static_cast<uint64_t>(n) * (12 + 4ull * attribute_count);
    if (needed > in.size() - in.offset())
      in.fail_at(at, "line " + std::to_string(line) + " claims " + std::to_string(n) +
                         " points, more than the file holds");
    const size_t first = lines.positions.size();
    lines.positions.resize(first + 3 * static_cast<size_t>(n));
    in.read(lines.positions.data() + first, 12ull * n, "positions");
    for (Attribute& a : lines.attributes) {
      const size_t begin = a.values.size();
      a.values.resize(begin + n);
      in.read(a.values.data() + begin, 4ull * n, "attribute values");
    }
    lines.end_line();
  }
  if (!in.at_end())
    in.fail("unexpected " + std::to_string(in.size() - in.offset()) + " bytes after the last line");
  if constexpr (std::endian::native == std::endian::big) {
    io::byteswap_array(lines.positions.data(), lines.positions.size(), 4);
    for (Attribute& a : lines.attributes) io::byteswap_array(a.values.data(), a.values.size(), 4);
  }
  return lines;
}

void write_binlines(const LineSet& lines, const std::string& path, const WriteOptions& options) {
  static_assert(std::endian::native == std::endian::little, "writer assumes little endian");
  if (options.binlines_version != 1 && options.binlines_version != 2)
    throw Error(".binlines version must be 1 or 2");
  if (lines.line_count() > UINT32_MAX) throw Error(".binlines holds at most 2^32-1 lines");
  io::Writer out(path);
  out.write_value<uint32_t>(options.binlines_version);
  out.write_value<uint32_t>(static_cast<uint32_t>(lines.line_count()));
  out.write_value<uint32_t>(static_cast<uint32_t>(lines.attributes.size()));
  if (options.binlines_version == 2)
    for (const Attribute& a : lines.attributes) {
      out.write_value<uint32_t>(static_cast<uint32_t>(a.name.size()));
      out.write(a.name);
    }
  for (size_t line = 0; line < lines.line_count(); ++line) {
    const uint64_t begin = lines.line_offsets[line], n = lines.line_size(line);
    if (n > UINT32_MAX) throw Error(".binlines lines hold at most 2^32-1 points");
    out.write_value<uint32_t>(static_cast<uint32_t>(n));
    out.write(lines.positions.data() + 3 * begin, 12 * n);
    for (const Attribute& a : lines.attributes) out.write(a.values.data() + begin, 4 * n);
    if (options.progress && line % 16384 == 0) options.progress(line, lines.line_count());
  }
  out.close();
}

}  // namespace linebake::formats
