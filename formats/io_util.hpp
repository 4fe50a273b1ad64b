#pragma once
// Small I/O pieces the readers and writers share: buffered line reading with line numbers,
// checked binary reads with byte offsets, byte order, and exact float formatting.

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "core/error.hpp"
#include "core/progress.hpp"
#include "lines/line_set.hpp"

namespace linebake::io {

// A read-only file with its size; closes on destruction. Throws InputError when it cannot open.
class File {
 public:
  File(const std::string& path, const char* mode = "rb");
  ~File();
  File(const File&) = delete;
  File& operator=(const File&) = delete;
  std::FILE* get() const { return f_; }
  uint64_t size() const { return size_; }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  std::FILE* f_ = nullptr;
  uint64_t size_ = 0;
};

// Streams a text file line by line (LF or CRLF) without holding it whole.
class TextReader {
 public:
  explicit TextReader(const std::string& path, ProgressFn progress = {});
  // Next line without its terminator; false at end of file.
  bool next(std::string_view& line);
  uint64_t line_number() const { return line_number_; }
  uint64_t offset() const { return consumed_; }  // bytes before the next unread line
  const std::string& path() const { return file_.path(); }
  [[noreturn]] void fail(const std::string& message) const;
  // Called with the bytes the buffer will hold while it grows, before it grows to take a line
  // longer than it (a reader's memory check, which may throw).
  void before_growing(std::function<void(uint64_t bytes)> check) {
    before_growing_ = std::move(check);
  }

 private:
  bool refill();
  File file_;
  ProgressFn progress_;
  std::function<void(uint64_t)> before_growing_;
  std::vector<char> buffer_;
  size_t begin_ = 0, end_ = 0;
  bool eof_ = false;
  uint64_t line_number_ = 0;
  uint64_t consumed_ = 0;
  std::string long_line_;
};

// Checked binary reads that report the byte offset of a truncation.
class BinaryReader {
 public:
  explicit BinaryReader(const std::string& path, ProgressFn progress = {});
  void read(void* out, size_t bytes, const char* what);
  template <typename T>
  T read_value(const char* what, bool swap = false);
  void seek(uint64_t offset);
  bool at_end() const { return offset_ >= file_.size(); }
  uint64_t offset() const { return offset_; }
  uint64_t size() const { return file_.size(); }
  const std::string& path() const { return file_.path(); }
  [[noreturn]] void fail(const std::string& message) const;
  [[noreturn]] void fail_at(uint64_t offset, const std::string& message) const;

 private:
  File file_;
  ProgressFn progress_;
  uint64_t offset_ = 0;
  uint64_t last_report_ = 0;
};

template <typename T>
T byteswap_value(T v) {
  unsigned char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  for (size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
  std::memcpy(&v, b, sizeof(T));
  return v;
}

// Swaps every element of an array of `element_size`-byte values in place.
void byteswap_array(void* data, size_t count, size_t element_size);

template <typename T>
T BinaryReader::read_value(const char* what, bool swap) {
  T v;
  read(&v, sizeof(T), what);
  return swap ? byteswap_value(v) : v;
}

// Binary scalar types of the formats we read, decoded with one dispatch per array.
enum class Scalar { int8, uint8, int16, uint16, int32, uint32, int64, uint64, float32, float64 };
size_t scalar_size(Scalar type);

// `v` as Out. Where Out is an integer type, a floating-point `v` must be finite and inside Out's
// range, since the cast is undefined behaviour otherwise: false (and `out` untouched) where not.
// A finite double past float's range is refused too (float32 would hold infinity: the value is
// lost, not invalid; CSV's reader refuses it so as well); infinity and NaN are read as they are.
template <typename Out, typename T>
[[nodiscard]] bool convert_scalar(T v, Out& out) {
  if constexpr (std::is_integral_v<Out> && std::is_floating_point_v<T>) {
    const double lowest = double(std::numeric_limits<Out>::lowest());
    const double past_max = std::ldexp(1.0, std::numeric_limits<Out>::digits);  // max + 1
    if (!(double(v) >= lowest && double(v) < past_max)) return false;
  }
  if constexpr (std::is_same_v<Out, float> && std::is_same_v<T, double>) {
    if (std::isfinite(v) && std::isinf(static_cast<float>(v))) return false;
  }
  out = static_cast<Out>(v);
  return true;
}

// Converts `count` packed values of `type` at `src` (byte-swapped when `swap`) to Out: false
// when a value does not fit Out (convert_scalar), e.g. a float array read as indices.
template <typename Out>
[[nodiscard]] bool decode_scalars(Scalar type, const unsigned char* src, size_t count, bool swap,
                                  Out* out) {
  bool fits = true;
  auto run = [&]<typename T>(T) {
    for (size_t i = 0; i < count; ++i) {
      T v;
      std::memcpy(&v, src + i * sizeof(T), sizeof(T));
      fits = convert_scalar(swap ? byteswap_value(v) : v, out[i]) && fits;
    }
    return fits;
  };
  switch (type) {
    case Scalar::int8:
      return run(int8_t{});
    case Scalar::uint8:
      return run(uint8_t{});
    case Scalar::int16:
      return run(int16_t{});
    case Scalar::uint16:
      return run(uint16_t{});
    case Scalar::int32:
      return run(int32_t{});
    case Scalar::uint32:
      return run(uint32_t{});
    case Scalar::int64:
      return run(int64_t{});
    case Scalar::uint64:
      return run(uint64_t{});
    case Scalar::float32:
      return run(float{});
    case Scalar::float64:
      return run(double{});
  }
  return fits;
}

// Whitespace tokenizer over one line.
std::vector<std::string_view> split_whitespace(std::string_view line);
// How many tokens split_whitespace would make of `line`.
size_t count_tokens(std::string_view line);
std::string_view trim(std::string_view s);

// Parse helpers: throw nothing; return false on failure (the caller names the place).
bool parse_float(std::string_view token, float& out);
bool parse_double(std::string_view token, double& out);
bool parse_int64(std::string_view token, int64_t& out);
bool parse_uint64(std::string_view token, uint64_t& out);

// Attribute names in whitespace-separated formats (VTK legacy, OBJ `a` lines): spaces and
// other special bytes as %xx, as VTK writes them ('#' too, which starts an OBJ comment).
std::string encode_name(const std::string& name);
std::string decode_name(std::string_view encoded);

// Splits an array of `components`-tuples into one attribute per component (name, or name_x/_y/_z
// for 3 components, name_0.._k otherwise, or name_<its name> where the file names every
// component: VTK's component names), taking tuples [first, first + count). False when the
// array holds fewer tuples.
bool append_components(std::vector<Attribute>& target, const std::string& name,
                       const std::vector<float>& values, size_t components, size_t first,
                       size_t count, const std::vector<std::string>& component_names = {});
// The name of component `c` of `components` of array `name`, as append_components gives it.
std::string component_name(const std::string& name, size_t c, size_t components,
                           const std::vector<std::string>& component_names = {});

// Shortest text that parses back to exactly `v` ("nan", "inf", "-inf" for non-finite).
void append_float(std::string& out, float v);
void append_double(std::string& out, double v);

// Buffered binary/text writer over an AtomicFile's temporary path, on POSIX write(2): a write
// error (a full disk, a quota) is an OutputError with the system's reason, and a pending
// interruption (core/interrupt.hpp) stops the writer at its next 1 MiB.
class Writer {
 public:
  explicit Writer(const std::string& path);
  ~Writer();
  Writer(const Writer&) = delete;
  Writer& operator=(const Writer&) = delete;
  void write(const void* data, size_t bytes);
  void write(std::string_view text) { write(text.data(), text.size()); }
  template <typename T>
  void write_value(T v, bool swap = false) {
    if (swap) v = byteswap_value(v);
    write(&v, sizeof(T));
  }
  // Overwrites `bytes` at `offset` (a header field known only at the end), then goes on
  // appending.
  void patch(uint64_t offset, const void* data, size_t bytes);
  void close();  // flushes; throws OutputError on failure

 private:
  void flush();
  std::string path_;
  int fd_ = -1;
  std::vector<char> buffer_;
  uint64_t offset_ = 0;  // where the buffer starts in the file
};

// What a reader of a format read whole will hold at `place` (its arrays and the line set
// gathered from them), checked against ReadOptions::memory_limit (none: no limit) before it
// allocates:
// past it, BudgetExceeded naming the file, the place and the figures. In double: the counts come
// from the file, and their products must not wrap.
void check_read_memory(const std::string& path, const char* format, double bytes,
                       const std::string& place, std::optional<uint64_t> limit);

// A line that comes alone in a streaming reader's batch (LineReader::next: one larger than the
// batch its caller asked for), checked against ReadOptions::memory_limit before the reader
// allocates for it: refused at its place (BudgetExceeded naming the file, the line, `place` and
// the figures) instead of read into memory whole. `points`: the line's; `bytes`: what holding it
// takes, the reader's buffers and the arrays' growth included.
void check_line_memory(const std::string& path, uint64_t line, uint64_t points, double bytes,
                       const std::string& place, std::optional<uint64_t> limit);

}  // namespace linebake::io
