// TrackVis .trk: a 1000-byte header, then per streamline int32 m, m x (3 + n_scalars) float32,
// n_properties float32. Either byte order: hdr_size (= 1000) tells which. Points stay in the
// file's voxel-mm space; voxel size, dimensions and vox_to_ras go into the metadata. Scalars
// become vertex attributes, properties line attributes (named from the header, else scalar_k /
// property_k; a name slot written as nibabel does, "name\0N", names N columns). Streamlines are
// read in batches, each one whole.

#include <algorithm>
#include <array>
#include <string>
#include <vector>

#include "formats/formats.hpp"
#include "formats/io_util.hpp"

namespace linebake::formats {

namespace {
std::string field_name(const char* raw, size_t size) {
  std::string s(raw, strnlen(raw, size));
  return s;
}

// A scalar_name or property_name slot: a name, and how many consecutive columns it covers.
// nibabel writes a multi-component one as the name, a NUL and the count in ASCII digits
// (b"colors\x003"); otherwise a slot covers one column, whatever follows its NUL.
struct NameSlot {
  std::string name;
  int columns = 1;
  bool counted = false;  // the count was written
};

NameSlot name_slot(const char* raw) {
  constexpr size_t kSize = 20;
  NameSlot slot{field_name(raw, kSize)};
  size_t i = slot.name.size() + 1;
  if (slot.name.empty() || i >= kSize) return slot;
  int count = 0;
  size_t digits = 0;
  for (; i < kSize && raw[i] >= '0' && raw[i] <= '9'; ++i, ++digits)
    count = std::min(count * 10 + (raw[i] - '0'), 100000);
  for (size_t k = i; k < kSize; ++k)
    if (raw[k] != 0) return slot;  // not a count: left as before
  if (digits == 0) return slot;
  slot.columns = count;  // 0 (nibabel skips such a slot)
  slot.counted = true;
  return slot;
}

class TrkReader : public LineReader {
 public:
  TrkReader(const std::string& path, const ReadOptions& options)
      : in_(path, options.progress), memory_limit_(options.memory_limit) {
    std::array<char, 1000> h{};
    // The magic first: a file of another format shorter than the header (a .tck renamed) is
    // named as such, not as a truncated header.
    const size_t head = size_t(std::min<uint64_t>(in_.size(), 5));
    in_.read(h.data(), head, "the 1000-byte header");
    if (head > 0 && std::memcmp(h.data(), "TRACK", head) != 0) {
      const bool tck = head >= 4 && std::memcmp(h.data(), "mrtr", 4) == 0;
      in_.fail_at(0, std::string("not a TrackVis file (no TRACK magic)") +
                         (tck ? "; it starts as an MRtrix .tck file does" : ""));
    }
    in_.seek(0);
    in_.read(h.data(), h.size(), "the 1000-byte header");
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
    header_.attributes =
        named_columns(h.data(), 38, "scalar_name", n_scalars_, 36, "n_scalars", "scalar_");
    header_.line_attributes = named_columns(h.data(), 240, "property_name", n_properties_, 238,
                                            "n_properties", "property_");
    n_count_ = i32(988);
    if (n_count_ < 0) in_.fail_at(988, "negative n_count");
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

  // The attributes of `count` columns (n_scalars at `count_at`), named by the ten 20-byte slots
  // at `names_at` in order; a column without a name is <unnamed>k. More than 10 columns only
  // where the slots' counts name them; counts that name more columns than there are are refused.
  std::vector<Attribute> named_columns(const char* h, size_t names_at, const char* names_field,
                                       int count, size_t count_at, const char* count_field,
                                       const char* unnamed) const {
    std::vector<NameSlot> slots;
    int covered = 0;
    bool counted = false;
    std::string listed;
    for (size_t s = 0; s < 10; ++s) {
      slots.push_back(name_slot(h + names_at + 20 * s));
      const NameSlot& slot = slots.back();
      counted = counted || slot.counted;
      if (slot.name.empty()) continue;
      covered += slot.columns;
      listed +=
          (listed.empty() ? "" : ", ") + ("'" + slot.name + "' " + std::to_string(slot.columns));
    }
    // Counts that name more columns than there are are no nibabel counts but bytes left in the
    // slots (a longer name overwritten by a shorter one): one column a slot, as TrackVis reads
    // them, where there are at most 10 columns.
    const bool use_counts = counted && covered <= count;
    if (count < 0 || count > std::max(10, use_counts ? covered : 0))
      in_.fail_at(count_at, std::string(count_field) + " must be 0..10, got " +
                                std::to_string(count) +
                                (counted ? " (" + std::string(names_field) + " names " +
                                               std::to_string(covered) + ": " + listed + ")"
                                         : ""));
    // A slot with a count covers as many columns (name, name_x/_y/_z for 3, name_0.._k
    // otherwise, as VTK's multi-component arrays), one without one column (TrackVis). Where
    // the header has counts, unnamed slots cover none (nibabel).
    std::vector<Attribute> columns;
    for (size_t s = 0; s < slots.size() && int(columns.size()) < count; ++s) {
      const NameSlot& slot = slots[s];
      if (!slot.name.empty())
        io::append_components(columns, slot.name, {}, use_counts ? size_t(slot.columns) : 1, 0, 0);
      else if (!use_counts)
        columns.push_back({unnamed + std::to_string(columns.size()), {}});
    }
    while (int(columns.size()) < count)
      columns.push_back({unnamed + std::to_string(columns.size()), {}});
    return columns;
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
