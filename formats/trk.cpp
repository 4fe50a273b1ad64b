// TrackVis .trk: a 1000-byte header, then per streamline int32 m, m x (3 + n_scalars) float32,
// n_properties float32. Either byte order: hdr_size (= 1000) tells which. Points stay in the
// file's voxel-mm space; voxel size, dimensions and vox_to_ras go into the metadata. Scalars
// become vertex attributes, properties line attributes (named from the header, else scalar_k /
// property_k). Streamlines are read in batches, each one whole.

#include <array>

#include "formats/formats.hpp"
#include "formats/io_util.hpp"

namespace linebake::formats {

namespace {
std::string field_name(const char* raw, size_t size) {
  std::string s(raw, strnlen(raw, size));
  return s;
}

class TrkReader : public LineReader {
 public:
  TrkReader(const std::string& path, const ReadOptions& options)
      : in_(path, options.progress), memory_limit_(options.memory_limit) {
    std::array<char, 1000> h{};
    in_.read(h.data(), h.size(), "the 1000-byte header");
    if (std::memcmp(h.data(), "TRACK", 5) != 0)
      in_.fail_at(0, "not a TrackVis file (no TRACK magic)");
    int32_t hdr_size;
    std::memcpy(&hdr_size, h.data() + 996, 4);
    if (hdr_size != 1000) {
      if (io::byteswap_value(hdr_size) != 1000)
        in_.fail_at(996,
                    "hdr_size is " + std::to_string(hdr_size) + " in either byte order, not 1000");
      swap_ = true;
    }
    auto i16 = [&](size_t at) {
      int16_t v;
      std::memcpy(&v, h.data() + at, 2);
      return swap_ ? io::byteswap_value(v) : v;
    };
    auto f32 = [&](size_t at) {
      float v;
      std::memcpy(&v, h.data() + at, 4);
      return swap_ ? io::byteswap_value(v) : v;
    };
    auto i32 = [&](size_t at) {
      int32_t v;
      std::memcpy(&v, h.data() + at, 4);
      return swap_ ? io::byteswap_value(v) : v;
    };
    // Offsets: dim 6, voxel_size 12, origin 24, n_scalars 36, scalar_name 38, n_properties 238,
    // property_name 240, vox_to_ras 440, reserved 504, voxel_order 948, pad2 952,
    // image_orientation_patient 956, pad1 980, invert/swap 982..987, n_count 988, version 992.
    n_scalars_ = i16(36);
    n_properties_ = i16(238);
    if (n_scalars_ < 0 || n_scalars_ > 10)
      in_.fail_at(36, "n_scalars must be 0..10, got " + std::to_string(n_scalars_));
    if (n_properties_ < 0 || n_properties_ > 10)
      in_.fail_at(238, "n_properties must be 0..10, got " + std::to_string(n_properties_));
    n_count_ = i32(988);
    if (n_count_ < 0) in_.fail_at(988, "negative n_count");

    for (int s = 0; s < n_scalars_; ++s) {
      std::string name = field_name(h.data() + 38 + 20 * s, 20);
      header_.attributes.push_back({name.empty() ? "scalar_" + std::to_string(s) : name, {}});
    }
    for (int p = 0; p < n_properties_; ++p) {
      std::string name = field_name(h.data() + 240 + 20 * p, 20);
      header_.line_attributes.push_back(
          {name.empty() ? "property_" + std::to_string(p) : name, {}});
    }
    header_.metadata["trk.space"] = "voxmm";
    header_.metadata["trk.dim"] =
        std::to_string(i16(6)) + " " + std::to_string(i16(8)) + " " + std::to_string(i16(10));
    header_.metadata["trk.voxel_size"] =
        std::to_string(f32(12)) + " " + std::to_string(f32(16)) + " " + std::to_string(f32(20));
    std::string ras;
    for (int i = 0; i < 16; ++i) ras += (i ? " " : "") + std::to_string(f32(440 + 4 * i));
    header_.metadata["trk.vox_to_ras"] = ras;
    header_.metadata["trk.voxel_order"] = field_name(h.data() + 948, 4);
  }

  bool next(LineSet& batch, uint64_t max_points) override {
    copy_lines(header_, 0, 0, batch);
    if (done_) return false;
    const size_t stride = 3 + static_cast<size_t>(n_scalars_);
    bool full = false;
    while (n_count_ == 0 ? !in_.at_end() : lines_read_ < static_cast<uint64_t>(n_count_)) {
      const uint64_t at = in_.offset();
      const auto m = in_.read_value<int32_t>("streamline point count", swap_);
      if (m < 0)
        in_.fail_at(at, "negative point count in streamline " + std::to_string(lines_read_));
      const uint64_t bytes =
          (static_cast<uint64_t>(m) * stride + static_cast<uint64_t>(n_properties_)) * 4;
      if (bytes > in_.size() - in_.offset())
        in_.fail_at(at, "streamline " + std::to_string(lines_read_) + " claims " +
                            std::to_string(m) + " points, more than the file holds");
      if (batch.line_count() > 0 && batch.point_count() + static_cast<uint64_t>(m) > max_points) {
        in_.seek(at);  // this streamline starts the next batch
        full = true;
        break;
      }
      // A streamline that comes alone: its record buffer beside the batch's arrays, which grow
      // by doubling.
      if (batch.line_count() == 0)
        io::check_line_memory(
            in_.path(), lines_read_, uint64_t(m),
            double(m) * double(stride) * 4.0 + 2.0 * double(m) * double(12 + 4 * n_scalars_),
            "byte offset " + std::to_string(at), memory_limit_);
      record_.resize(static_cast<size_t>(m) * stride);
      in_.read(record_.data(), record_.size() * 4, "streamline points");
      if (swap_) io::byteswap_array(record_.data(), record_.size(), 4);
      for (int32_t i = 0; i < m; ++i) {
        const float* r = &record_[static_cast<size_t>(i) * stride];
        batch.append_point(r[0], r[1], r[2]);
        for (int s = 0; s < n_scalars_; ++s) batch.attributes[s].values.push_back(r[3 + s]);
      }
      for (int p = 0; p < n_properties_; ++p)
        batch.line_attributes[p].values.push_back(
            in_.read_value<float>("streamline property", swap_));
      batch.end_line();
      ++lines_read_;
    }
    if (!full) {
      done_ = true;
      if (!in_.at_end())
        in_.fail("unexpected " + std::to_string(in_.size() - in_.offset()) + " bytes after " +
                 std::to_string(n_count_) + " streamlines (n_count)");
    }
    return batch.line_count() > 0;
  }

 private:
  io::BinaryReader in_;
  std::optional<uint64_t> memory_limit_;
  bool swap_ = false;
  int n_scalars_ = 0, n_properties_ = 0;
  int32_t n_count_ = 0;
  bool done_ = false;
  std::vector<float> record_;  // one streamline's points, as stored
};

}  // namespace

std::unique_ptr<LineReader> open_trk(const std::string& path, const ReadOptions& options) {
  return std::make_unique<TrkReader>(path, options);
}

}  // namespace linebake::formats
