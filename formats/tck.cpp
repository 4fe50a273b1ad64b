// MRtrix .tck: a text header starting "mrtrix tracks", `key: value` lines (datatype, file,
// count, ...), ending with END; at the `file: . OFFSET` byte offset, xyz triplets in the given
// datatype (Float32LE/BE, Float64LE/BE). A NaN triplet ends a streamline, an Inf triplet the
// file. Header keys go into the metadata as tck.<key>. Streamlines are read in batches: a
// streamline's end is only known at its NaN triplet, so one that does not fit the batch it
// started in is carried, as far as it was read, into the next.

#include <cmath>

#include "formats/formats.hpp"
#include "formats/io_util.hpp"

namespace linebake::formats {

namespace {

class TckReader : public LineReader {
 public:
  TckReader(const std::string& path, const ReadOptions& options)
      : in_(path, options.progress),
        memory_limit_(options.memory_limit),
        origin_(options.origin.value_or(Origin{0, 0, 0})) {
    std::string datatype;
    uint64_t data_offset = 0, header_end = 0;
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
          if (!io::parse_int64(value, declared_count_)) header.fail("bad count '" + value + "'");
        }
        // A key given again (command_history, roi) keeps every value, one a line, as MRtrix's
        // own header reader does.
        const auto [kept, fresh] = header_.metadata.try_emplace("tck." + key, value);
        if (!fresh) kept->second += "\n" + value;
        if (header.offset() > (1u << 20)) header.fail("header longer than 1 MiB without END");
      }
      if (!ended) throw InputError(path, "header", "no END line");
      header_end = header.offset();
    }
    bool big = false;
    if (datatype == "Float32LE")
      size_ = 4;
    else if (datatype == "Float32BE")
      size_ = 4, big = true;
    else if (datatype == "Float64LE")
      size_ = 8;
    else if (datatype == "Float64BE")
      size_ = 8, big = true;
    else
      throw InputError(path, "header", "unsupported datatype '" + datatype + "'");
    if (data_offset == 0) throw InputError(path, "header", "no 'file: . OFFSET' entry");
    if (data_offset < header_end)
      throw InputError(path, "header",
                       "'file: . " + std::to_string(data_offset) +
                           "' points inside the header, which ends at byte " +
                           std::to_string(header_end));
    if (data_offset > in_.size())
      throw InputError(path, "header",
                       "'file: . " + std::to_string(data_offset) + "' points past the end of the " +
                           std::to_string(in_.size()) + "-byte file (truncated?)");
    in_.seek(data_offset);
    swap_ = big != (std::endian::native == std::endian::big);
  }

  bool next(LineSet& batch, uint64_t max_points) override {
    copy_lines(header_, 0, 0, batch);
    while (!finished_) {
      // The open streamline no longer fits beside the batch's: it goes on in the next batch.
      if (batch.line_count() > 0 && batch.point_count() + open_.size() / 3 > max_points) break;
      if (in_.at_end()) in_.fail("file ends without the Inf end-of-file triplet (truncated?)");
      double xyz[3];
      for (double& v : xyz) {
        if (size_ == 4) {
          v = in_.read_value<float>("point", swap_);
        } else {
          v = in_.read_value<double>("point", swap_);
        }
      }
      if (std::isinf(xyz[0]) && std::isinf(xyz[1]) && std::isinf(xyz[2])) {
        finished_ = true;
        if (!open_.empty()) in_.fail("the last streamline is not closed by a NaN triplet");
        const uint64_t total = lines_read_ + batch.line_count();
        if (declared_count_ >= 0 && static_cast<uint64_t>(declared_count_) != total)
          throw InputError(in_.path(), "header",
                           "count says " + std::to_string(declared_count_) +
                               " streamlines, the data holds " + std::to_string(total));
        break;
      }
      if (std::isnan(xyz[0]) && std::isnan(xyz[1]) && std::isnan(xyz[2])) {
        batch.positions.insert(batch.positions.end(), open_.begin(), open_.end());
        batch.end_line();
        open_.clear();
        if (batch.point_count() >= max_points) break;
        continue;
      }
      // Relative to the origin asked for, subtracted before Float64 data is rounded
      // (lines/origin.hpp); Float32 data comes out as a shift of its float32 values would.
      open_.insert(open_.end(), {to_local(xyz[0], origin_[0]), to_local(xyz[1], origin_[1]),
                                 to_local(xyz[2], origin_[2])});
      // A streamline's length is known only at its NaN: what it holds is checked as it grows
      // (its buffer and the batch's copy, both growing by doubling).
      const uint64_t open_points = open_.size() / 3;
      if (batch.line_count() == 0 && open_points % kCheckPoints == 0)
        io::check_line_memory(
            in_.path(), lines_read_, open_points, 36.0 * double(open_points),
            "its point at byte offset " + std::to_string(in_.offset() - 3 * size_), memory_limit_);
    }
    lines_read_ += batch.line_count();
    return batch.line_count() > 0;
  }

 private:
  static constexpr uint64_t kCheckPoints = 65536;  // the open streamline's memory checked so often
  io::BinaryReader in_;
  std::optional<uint64_t> memory_limit_;
  Origin origin_;  // asked for; none is 0, 0, 0 (subtracting 0 changes no value)
  int64_t declared_count_ = -1;
  size_t size_ = 0;
  bool swap_ = false;
  bool finished_ = false;
  std::vector<float> open_;  // xyz of the streamline read so far, not yet closed by NaN
};

}  // namespace

std::unique_ptr<LineReader> open_tck(const std::string& path, const ReadOptions& options) {
  return std::make_unique<TckReader>(path, options);
}

}  // namespace linebake::formats
