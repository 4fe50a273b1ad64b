// LineVis .binlines (little endian).
// Version 1: uint32 version, uint32 lines, uint32 attributes; per line uint32 n, n x float3
// positions, then attributes x n floats (attribute-major).
// Version 2 (as linebake reads and writes it): the same header, then per attribute a uint32
// byte length and that many bytes of name, then the lines as in version 1. The public LineVis
// loader reads only version 1; write version 1 for it.

#include "core/atomic_file.hpp"
#include "formats/formats.hpp"
#include "formats/io_util.hpp"

namespace linebake::formats {

namespace {

class BinlinesReader : public LineReader {
 public:
  BinlinesReader(const std::string& path, const ReadOptions& options)
      : in_(path, options.progress), memory_limit_(options.memory_limit) {
    if (in_.size() == 0) in_.fail("empty file");
    const auto version = in_.read_value<uint32_t>("version");
    if (version != 1 && version != 2)
      in_.fail_at(
          0, "unsupported .binlines version " + std::to_string(version) + " (expected 1 or 2)");
    line_count_ = in_.read_value<uint32_t>("line count");
    const auto attribute_count = in_.read_value<uint32_t>("attribute count");
    if (attribute_count > 4096)
      in_.fail_at(8, "implausible attribute count " + std::to_string(attribute_count));
    // Before anything is sized from the header: each line needs at least its 4-byte count and,
    // in version 2, each attribute its 4-byte name length.
    const uint64_t left = in_.size() - in_.offset();
    const uint64_t names = version == 2 ? 4ull * attribute_count : 0;
    if (names > left)
      in_.fail_at(8, "attribute count " + std::to_string(attribute_count) + " needs " +
                         std::to_string(names) + " bytes of names, the file has " +
                         std::to_string(left) + " left");
    if (static_cast<uint64_t>(line_count_) * 4 > left - names)
      in_.fail_at(4, "line count " + std::to_string(line_count_) + " does not fit the file size");
    header_.attributes.resize(attribute_count);
    for (uint32_t a = 0; a < attribute_count; ++a) {
      header_.attributes[a].name = "attribute" + std::to_string(a);
      if (version == 2) {
        const uint64_t at = in_.offset();
        const auto length = in_.read_value<uint32_t>("attribute name length");
        if (length > 4096)
          in_.fail_at(at, "implausible attribute name length " + std::to_string(length));
        std::string name(length, '\0');
        in_.read(name.data(), length, "attribute name");
        // Every consumer reads a name as C text (HDF5, VTK, the terminal): a NUL had cut it short.
        if (const size_t nul = name.find('\0'); nul != std::string::npos)
          in_.fail_at(at + 4 + nul, "attribute name holds a NUL byte");
        header_.attributes[a].name = name;
      }
    }
    // Each line needs at least its 4-byte count: a count beyond that is a corrupt header.
    if (static_cast<uint64_t>(line_count_) * 4 > in_.size() - in_.offset())
      in_.fail_at(4, "line count " + std::to_string(line_count_) + " does not fit the file size");
  }

  bool next(LineSet& batch, uint64_t max_points) override {
    copy_lines(header_, 0, 0, batch);
    const size_t attributes = header_.attributes.size();
    while (lines_read_ < line_count_) {
      const uint64_t at = in_.offset();
      const auto n = in_.read_value<uint32_t>("point count");
      const uint64_t needed = static_cast<uint64_t>(n) * (12 + 4ull * attributes);
      if (needed > in_.size() - in_.offset())
        in_.fail_at(at, "line " + std::to_string(lines_read_) + " claims " + std::to_string(n) +
                            " points, more than the file holds");
      if (batch.line_count() > 0 && batch.point_count() + n > max_points) {
        in_.seek(at);  // this line starts the next batch
        break;
      }
      // A line that comes alone (larger than the batch its caller sized) is checked before it
      // is read.
      if (batch.line_count() == 0)
        io::check_line_memory(in_.path(), lines_read_, n,
                              double(n) * double(12 + 4 * attributes) + 16.0,
                              "byte offset " + std::to_string(at), memory_limit_);
      const size_t first = batch.positions.size();
      batch.positions.resize(first + 3 * static_cast<size_t>(n));
      in_.read(batch.positions.data() + first, 12ull * n, "positions");
      for (Attribute& a : batch.attributes) {
        const size_t begin = a.values.size();
        a.values.resize(begin + n);
        in_.read(a.values.data() + begin, 4ull * n, "attribute values");
      }
      batch.end_line();
      ++lines_read_;
    }
    if (lines_read_ == line_count_ && !in_.at_end())
      in_.fail("unexpected " + std::to_string(in_.size() - in_.offset()) +
               " bytes after the last line");
    if constexpr (std::endian::native == std::endian::big) {
      io::byteswap_array(batch.positions.data(), batch.positions.size(), 4);
      for (Attribute& a : batch.attributes) io::byteswap_array(a.values.data(), a.values.size(), 4);
    }
    return batch.line_count() > 0;
  }

  std::optional<uint64_t> line_count_hint() const override { return line_count_; }

 private:
  io::BinaryReader in_;
  std::optional<uint64_t> memory_limit_;
  uint32_t line_count_ = 0;
};

}  // namespace

std::unique_ptr<LineReader> open_binlines(const std::string& path, const ReadOptions& options) {
  return std::make_unique<BinlinesReader>(path, options);
}

namespace {

// `n` points from `xyz` as world coordinates: the format holds float32 only, so a line set with
// an origin (lines/origin.hpp) is written with it added and rounded to float32 (convert says what
// that loses: formats/registry.hpp, lost_in_format).
template <typename Out>
void write_positions(Out& out, const float* xyz, uint64_t n, const std::optional<Origin>& origin) {
  if (!origin) return out.write(xyz, 12 * n);
  std::vector<float> world(3 * n);
  for (size_t i = 0; i < world.size(); ++i)
    world[i] = static_cast<float>(to_world(xyz[i], (*origin)[i % 3]));
  out.write(world.data(), 12 * n);
}

class BinlinesWriter : public LineWriter {
 public:
  BinlinesWriter(const std::string& path, const LineSet& header, const WriteOptions& options)
      : file_(path), options_(options), origin_(optional_origin(header, path)) {
    if (options.binlines_version != 1 && options.binlines_version != 2)
      throw Error(".binlines version must be 1 or 2");
    attributes_ = header.attributes.size();
    // Made and written within write_with, so that an error names the output, not its
    // temporary (a file system out of inodes had said "x.binlines.tmp-...: cannot create").
    file_.write_with([&] {
      io::Writer& out = out_.emplace(file_.temp_path());
      out.write_value<uint32_t>(options.binlines_version);
      out.write_value<uint32_t>(0);  // the line count, filled in by close()
      out.write_value<uint32_t>(static_cast<uint32_t>(attributes_));
      if (options.binlines_version == 2)
        for (const Attribute& a : header.attributes) {
          out.write_value<uint32_t>(static_cast<uint32_t>(a.name.size()));
          out.write(a.name);
        }
    });
  }

  void write(const LineSet& batch) override {
    file_.write_with([&] { write_lines(batch); });
  }

  void write_lines(const LineSet& batch) {
    if (batch.attributes.size() != attributes_)
      throw Error("binlines: a batch with " + std::to_string(batch.attributes.size()) +
                  " attributes, the header has " + std::to_string(attributes_));
    for (size_t line = 0; line < batch.line_count(); ++line) {
      const uint64_t begin = batch.line_offsets[line], n = batch.line_size(line);
      if (n > UINT32_MAX) throw Error(".binlines lines hold at most 2^32-1 points");
      if (lines_ == UINT32_MAX) throw Error(".binlines holds at most 2^32-1 lines");
      out_->write_value<uint32_t>(static_cast<uint32_t>(n));
      write_positions(*out_, batch.positions.data() + 3 * begin, n, origin_);
      for (const Attribute& a : batch.attributes) out_->write(a.values.data() + begin, 4 * n);
      ++lines_;
    }
  }

  void close() override {
    file_.write_with([&] {
      const uint32_t count = static_cast<uint32_t>(lines_);
      out_->patch(4, &count, sizeof count);
      out_->close();
    });
    file_.commit();
  }
  bool streams() const override { return true; }

 private:
  AtomicFile file_;
  std::optional<io::Writer> out_;
  WriteOptions options_;
  std::optional<Origin> origin_;
  size_t attributes_ = 0;
  uint64_t lines_ = 0;
};

}  // namespace

std::unique_ptr<LineWriter> open_binlines_writer(const std::string& path, const LineSet& header,
                                                 const WriteOptions& options) {
  static_assert(std::endian::native == std::endian::little, "writer assumes little endian");
  return std::make_unique<BinlinesWriter>(path, header, options);
}

void write_binlines(const LineSet& lines, const std::string& path, const WriteOptions& options) {
  static_assert(std::endian::native == std::endian::little, "writer assumes little endian");
  if (options.binlines_version != 1 && options.binlines_version != 2)
    throw Error(".binlines version must be 1 or 2");
  if (lines.line_count() > UINT32_MAX) throw Error(".binlines holds at most 2^32-1 lines");
  const std::optional<Origin> origin = optional_origin(lines, path);
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
    write_positions(out, lines.positions.data() + 3 * begin, n, origin);
    for (const Attribute& a : lines.attributes) out.write(a.values.data() + begin, 4 * n);
    if (options.progress && line % 16384 == 0) options.progress(line, lines.line_count());
  }
  out.close();
}

}  // namespace linebake::formats
