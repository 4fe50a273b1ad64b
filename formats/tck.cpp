// MRtrix .tck: a text header starting "mrtrix tracks", `key: value` lines (datatype, file,
// count, ...), ending with END; at the `file: . OFFSET` byte offset, xyz triplets in the given
// datatype (Float32LE/BE, Float64LE/BE). A NaN triplet ends a streamline, an Inf triplet the
// file. Header keys go into the metadata as tck.<key>.

#include <cmath>

#include "formats/formats.hpp"
#include "formats/io_util.hpp"

namespace linebake::formats {

LineSet read_tck(const std::string& path, const ReadOptions& options) {
  LineSet lines;
  std::string datatype;
  uint64_t data_offset = 0;
  int64_t declared_count = -1;
  {
    io::TextReader header(path);
    std::string_view line;
    if (!header.next(line) || io::trim(line) != "mrtrix tracks")
      throw InputError(path, at_line(1), "not an MRtrix .tck file (no 'mrtrix tracks' line)");
    bool ended = false;
    while (header.next(line)) {
      line = io::trim(line);
      if (line == "END") {
        ended = true;
        break;
      }
      const size_t colon = line.find(':');
      if (colon == std::string_view::npos) header.fail("expected 'key: value'");
      const std::string key(io::trim(line.substr(0, colon)));
      const std::string value(io::trim(line.substr(colon + 1)));
      if (key == "datatype") {
        datatype = value;
      } else if (key == "file") {
        const auto parts = io::split_whitespace(value);
        if (parts.size() != 2 || parts[0] != "." || !io::parse_uint64(parts[1], data_offset))
          header.fail("expected 'file: . OFFSET' (data in the same file)");
      } else if (key == "count") {
        if (!io::parse_int64(value, declared_count)) header.fail("bad count '" + value + "'");
      }
      lines.metadata["tck." + key] = value;
      if (header.offset() > (1u << 20)) header.fail("header longer than 1 MiB without END");
    }
    if (!ended) throw InputError(path, "header", "no END line");
  }
  size_t size = 0;
  bool big = false;
  if (datatype == "Float32LE")
    size = 4;
  else if (datatype == "Float32BE")
    size = 4, big = true;
  else if (datatype == "Float64LE")
    size = 8;
  else if (datatype == "Float64BE")
    size = 8, big = true;
  else
    throw InputError(path, "header", "unsupported datatype '" + datatype + "'");
  if (data_offset == 0) throw InputError(path, "header", "no 'file: . OFFSET' entry");

  io::BinaryReader in(path, options.progress);
  in.seek(data_offset);
  const bool swap = big != (std::endian::native == std::endian::big);
  bool finished = false;
  uint64_t open_points = 0;
  while (!in.at_end()) {
    double xyz[3];
    for (double& v : xyz) {
      if (size == 4) {
        v = in.read_value<float>("point", swap);
      } else {
        v = in.read_value<double>("point", swap);
      }
    }
    if (std::isinf(xyz[0]) && std::isinf(xyz[1]) && std::isinf(xyz[2])) {
      finished = true;
      break;
    }
    if (std::isnan(xyz[0]) && std::isnan(xyz[1]) && std::isnan(xyz[2])) {
      lines.end_line();
      open_points = 0;
      continue;
    }
    lines.append_point(static_cast<float>(xyz[0]), static_cast<float>(xyz[1]),
                       static_cast<float>(xyz[2]));
    ++open_points;
  }
  if (!finished) in.fail("file ends without the Inf end-of-file triplet (truncated?)");
  if (open_points > 0) in.fail("the last streamline is not closed by a NaN triplet");
  if (declared_count >= 0 && static_cast<uint64_t>(declared_count) != lines.line_count())
    throw InputError(path, "header",
                     "count says " + std::to_string(declared_count) +
                         " streamlines, the data holds " + std::to_string(lines.line_count()));
  return lines;
}

}  // namespace linebake::formats
