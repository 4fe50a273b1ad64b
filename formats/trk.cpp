// TrackVis .trk: a 1000-byte header, then per streamline int32 m, m x (3 + n_scalars) float32,
// n_properties float32. Either byte order: hdr_size (= 1000) tells which. Points stay in the
// file's voxel-mm space; voxel size, dimensions and vox_to_ras go into the metadata. Scalars
// become vertex attributes, properties line attributes (named from the header, else scalar_k /
// property_k).

#include <array>

#include "formats/formats.hpp"
#include "formats/io_util.hpp"

namespace linebake::formats {

namespace {
std::string field_name(const char* raw, size_t size) {
  std::string s(raw, strnlen(raw, size));
  return s;
}
}  // namespace

LineSet read_trk(const std::string& path, const ReadOptions& options) {
  io::BinaryReader in(path, options.progress);
  std::array<char, 1000> h{};
  in.read(h.data(), h.size(), "the 1000-byte header");
  if (std::memcmp(h.data(), "TRACK", 5) != 0) in.fail_at(0, "not a TrackVis file (no TRACK magic)");
  int32_t hdr_size;
  std::memcpy(&hdr_size, h.data() + 996, 4);
  bool swap = false;
  if (hdr_size != 1000) {
    if (io::byteswap_value(hdr_size) != 1000)
      in.fail_at(996,
                 "hdr_size is " + std::to_string(hdr_size) + " in either byte order, not 1000");
    swap = true;
  }
  auto i16 = [&](size_t at) {
    int16_t v;
    std::memcpy(&v, h.data() + at, 2);
    return swap ? io::byteswap_value(v) : v;
  };
  auto f32 = [&](size_t at) {
    float v;
    std::memcpy(&v, h.data() + at, 4);
    return swap ? io::byteswap_value(v) : v;
  };
  auto i32 = [&](size_t at) {
    int32_t v;
    std::memcpy(&v, h.data() + at, 4);
    return swap ? io::byteswap_value(v) : v;
  };
  // Offsets: dim 6, voxel_size 12, origin 24, n_scalars 36, scalar_name 38, n_properties 238,
  // property_name 240, vox_to_ras 440, reserved 504, voxel_order 948, pad2 952,
  // image_orientation_patient 956, pad1 980, invert/swap 982..987, n_count 988, version 992.
  const int n_scalars = i16(36), n_properties = i16(238);
  if (n_scalars < 0 || n_scalars > 10)
    in.fail_at(36, "n_scalars must be 0..10, got " + std::to_string(n_scalars));
  if (n_properties < 0 || n_properties > 10)
    in.fail_at(238, "n_properties must be 0..10, got " + std::to_string(n_properties));
  const int32_t n_count = i32(988);
  if (n_count < 0) in.fail_at(988, "negative n_count");

  LineSet lines;
  for (int s = 0; s < n_scalars; ++s) {
    std::string name = field_name(h.data() + 38 + 20 * s, 20);
    lines.attributes.push_back({name.empty() ? "scalar_" + std::to_string(s) : name, {}});
  }
  for (int p = 0; p < n_properties; ++p) {
    std::string name = field_name(h.data() + 240 + 20 * p, 20);
    lines.line_attributes.push_back({name.empty() ? "property_" + std::to_string(p) : name, {}});
  }
  lines.metadata["trk.space"] = "voxmm";
  lines.metadata["trk.dim"] =
      std::to_string(i16(6)) + " " + std::to_string(i16(8)) + " " + std::to_string(i16(10));
  lines.metadata["trk.voxel_size"] =
      std::to_string(f32(12)) + " " + std::to_string(f32(16)) + " " + std::to_string(f32(20));
  std::string ras;
  for (int i = 0; i < 16; ++i) ras += (i ? " " : "") + std::to_string(f32(440 + 4 * i));
  lines.metadata["trk.vox_to_ras"] = ras;
  lines.metadata["trk.voxel_order"] = field_name(h.data() + 948, 4);

  const size_t stride = 3 + static_cast<size_t>(n_scalars);
  std::vector<float> record;
  for (int64_t line = 0; n_count == 0 ? !in.at_end() : line < n_count; ++line) {
    const uint64_t at = in.offset();
    const auto m = in.read_value<int32_t>("streamline point count", swap);
    if (m < 0) in.fail_at(at, "negative point count in streamline " + std::to_string(line));
    const uint64_t bytes =
        (static_cast<uint64_t>(m) * stride + static_cast<uint64_t>(n_properties)) * 4;
    if (bytes > in.size() - in.offset())
      in.fail_at(at, "streamline " + std::to_string(line) + " claims " + std::to_string(m) +
                         " points, more than the file holds");
    record.resize(static_cast<size_t>(m) * stride);
    in.read(record.data(), record.size() * 4, "streamline points");
    if (swap) io::byteswap_array(record.data(), record.size(), 4);
    for (int32_t i = 0; i < m; ++i) {
      const float* r = &record[static_cast<size_t>(i) * stride];
      lines.append_point(r[0], r[1], r[2]);
      for (int s = 0; s < n_scalars; ++s) lines.attributes[s].values.push_back(r[3 + s]);
    }
    for (int p = 0; p < n_properties; ++p)
      lines.line_attributes[p].values.push_back(in.read_value<float>("streamline property", swap));
    lines.end_line();
  }
  if (!in.at_end())
    in.fail("unexpected " + std::to_string(in.size() - in.offset()) + " bytes after " +
            std::to_string(n_count) + " streamlines (n_count)");
  return lines;
}

}  // namespace linebake::formats
