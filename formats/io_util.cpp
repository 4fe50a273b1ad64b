#include "formats/io_util.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>

#include "core/interrupt.hpp"
#include "core/memory_budget.hpp"

namespace linebake::io {

File::File(const std::string& path, const char* mode) : path_(path) {
  f_ = std::fopen(path.c_str(), mode);
  if (!f_) throw InputError(path, "", std::string("cannot open: ") + std::strerror(errno));
  if (std::fseek(f_, 0, SEEK_END) == 0) {
    const long end = std::ftell(f_);
    size_ = end > 0 ? static_cast<uint64_t>(end) : 0;
    std::fseek(f_, 0, SEEK_SET);
  }
}

File::~File() {
  if (f_) std::fclose(f_);
}

TextReader::TextReader(const std::string& path, ProgressFn progress)
    : file_(path),
      progress_(std::move(progress)),
      // 1 MiB, or the file and a byte (at least 4 KiB) for a small one: a small file read often
      // (a fuzzer's input, a sidecar) should not pay for zeroing a megabyte. refill() grows it
      // for longer lines.
      buffer_(size_t(std::clamp<uint64_t>(file_.size() + 1, 4096, 1 << 20))) {}

bool TextReader::refill() {
  if (eof_) return false;
  if (begin_ > 0) {
    std::memmove(buffer_.data(), buffer_.data() + begin_, end_ - begin_);
    end_ -= begin_;
    begin_ = 0;
  }
  if (end_ == buffer_.size()) {
    // Growing holds the old buffer and the new one at once.
    if (before_growing_) before_growing_(3 * buffer_.size());
    buffer_.resize(buffer_.size() * 2);
  }
  const size_t got = std::fread(buffer_.data() + end_, 1, buffer_.size() - end_, file_.get());
  if (got == 0) eof_ = true;
  end_ += got;
  if (progress_) progress_(consumed_, file_.size());
  return got > 0;
}

bool TextReader::next(std::string_view& line) {
  for (;;) {
    const char* start = buffer_.data() + begin_;
    const void* nl = std::memchr(start, '\n', end_ - begin_);
    if (nl || (eof_ && begin_ < end_)) {
      const char* stop = nl ? static_cast<const char*>(nl) : buffer_.data() + end_;
      size_t length = static_cast<size_t>(stop - start);
      const size_t advance = length + (nl ? 1 : 0);
      if (length > 0 && start[length - 1] == '\r') --length;
      line = std::string_view(start, length);
      begin_ += advance;
      consumed_ += advance;
      ++line_number_;
      return true;
    }
    if (eof_) return false;
    refill();
  }
}

void TextReader::fail(const std::string& message) const {
  throw InputError(file_.path(), at_line(line_number_), message);
}

BinaryReader::BinaryReader(const std::string& path, ProgressFn progress)
    : file_(path), progress_(std::move(progress)) {}

void BinaryReader::read(void* out, size_t bytes, const char* what) {
  if (bytes == 0) return;
  if (offset_ + bytes > file_.size() || std::fread(out, 1, bytes, file_.get()) != bytes) {
    fail(std::string("file truncated while reading ") + what + " (needs " + std::to_string(bytes) +
         " bytes, " + std::to_string(file_.size() > offset_ ? file_.size() - offset_ : 0) +
         " left)");
  }
  offset_ += bytes;
  if (progress_ && offset_ - last_report_ > (8u << 20)) {
    last_report_ = offset_;
    progress_(offset_, file_.size());
  }
}

void BinaryReader::seek(uint64_t offset) {
  if (offset > file_.size() || std::fseek(file_.get(), static_cast<long>(offset), SEEK_SET) != 0)
    fail("cannot seek to byte offset " + std::to_string(offset) + " (file has " +
         std::to_string(file_.size()) + " bytes)");
  offset_ = offset;
}

void BinaryReader::fail(const std::string& message) const {
  fail_at(offset_, message);
}

void BinaryReader::fail_at(uint64_t offset, const std::string& message) const {
  throw InputError(file_.path(), at_byte(offset), message);
}

size_t scalar_size(Scalar type) {
  switch (type) {
    case Scalar::int8:
    case Scalar::uint8:
      return 1;
    case Scalar::int16:
    case Scalar::uint16:
      return 2;
    case Scalar::int32:
    case Scalar::uint32:
    case Scalar::float32:
      return 4;
    default:
      return 8;
  }
}

void byteswap_array(void* data, size_t count, size_t element_size) {
  auto* b = static_cast<unsigned char*>(data);
  for (size_t i = 0; i < count; ++i, b += element_size)
    for (size_t k = 0; k < element_size / 2; ++k) std::swap(b[k], b[element_size - 1 - k]);
}

std::string_view trim(std::string_view s) {
  const auto space = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; };
  while (!s.empty() && space(s.front())) s.remove_prefix(1);
  while (!s.empty() && space(s.back())) s.remove_suffix(1);
  return s;
}

namespace {
bool is_space(char c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\n';
}
}  // namespace

size_t count_tokens(std::string_view line) {
  size_t count = 0;
  for (size_t i = 0; i < line.size(); ++i)
    count += !is_space(line[i]) && (i == 0 || is_space(line[i - 1]));
  return count;
}

std::vector<std::string_view> split_whitespace(std::string_view line) {
  // Counted first: a vector grown by doubling holds up to three times its tokens while it grows
  // (a million-value line of an OBJ or an ASCII VTP array), which the readers' memory checks
  // count once.
  std::vector<std::string_view> tokens;
  tokens.reserve(count_tokens(line));
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && is_space(line[i])) ++i;
    const size_t start = i;
    while (i < line.size() && !is_space(line[i])) ++i;
    if (i > start) tokens.push_back(line.substr(start, i - start));
  }
  return tokens;
}

namespace {
template <typename T>
bool parse_number(std::string_view token, T& out) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  const char* end = token.data() + token.size();
  auto r = std::from_chars(token.data(), end, out);
  return r.ec == std::errc() && r.ptr == end;
}
// from_chars rejects "nan"/"inf" spellings some writers use; accept them explicitly.
template <typename T>
bool parse_real(std::string_view token, T& out) {
  if (parse_number(token, out)) return true;
  std::string lower(token);
  for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (lower == "nan" || lower == "-nan" || lower == "+nan") {
    out = std::numeric_limits<T>::quiet_NaN();
    return true;
  }
  if (lower == "inf" || lower == "+inf" || lower == "infinity") {
    out = std::numeric_limits<T>::infinity();
    return true;
  }
  if (lower == "-inf" || lower == "-infinity") {
    out = -std::numeric_limits<T>::infinity();
    return true;
  }
  return false;
}
}  // namespace

bool parse_float(std::string_view token, float& out) {
  return parse_real(token, out);
}
bool parse_double(std::string_view token, double& out) {
  return parse_real(token, out);
}
bool parse_int64(std::string_view token, int64_t& out) {
  return parse_number(token, out);
}
bool parse_uint64(std::string_view token, uint64_t& out) {
  return parse_number(token, out);
}

std::string encode_name(const std::string& name) {
  std::string out;
  for (unsigned char c : name) {
    // '#' too: an OBJ comment starts there, wherever it is on the line.
    if (c <= ' ' || c == '%' || c == '#' || c >= 127) {
      char hex[4];
      std::snprintf(hex, sizeof(hex), "%%%02X", c);
      out += hex;
    } else {
      out += static_cast<char>(c);
    }
  }
  return out.empty() ? "unnamed" : out;
}

std::string decode_name(std::string_view s) {
  auto hex = [](char c) { return std::isxdigit(static_cast<unsigned char>(c)) != 0; };
  std::string out;
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '%' && i + 2 < s.size() && hex(s[i + 1]) && hex(s[i + 2])) {
      out += static_cast<char>(std::stoi(std::string(s.substr(i + 1, 2)), nullptr, 16));
      i += 2;
    } else {
      out += s[i];
    }
  }
  return out;
}

std::string component_name(const std::string& name, size_t c, size_t components,
                           const std::vector<std::string>& component_names) {
  const bool named = components > 1 && component_names.size() == components &&
                     std::none_of(component_names.begin(), component_names.end(),
                                  [](const std::string& n) { return n.empty(); });
  return named             ? name + "_" + component_names[c]
         : components == 1 ? name
         : components == 3 ? name + "_" + "xyz"[c]
                           : name + "_" + std::to_string(c);
}

bool append_components(std::vector<Attribute>& target, const std::string& name,
                       const std::vector<float>& values, size_t components, size_t first,
                       size_t count, const std::vector<std::string>& component_names) {
  if (values.size() < (first + count) * components) return false;
  for (size_t c = 0; c < components; ++c) {
    Attribute a;
    a.name = component_name(name, c, components, component_names);
    a.values.resize(count);
    for (size_t i = 0; i < count; ++i) a.values[i] = values[(first + i) * components + c];
    target.push_back(std::move(a));
  }
  return true;
}

void append_float(std::string& out, float v) {
  if (std::isnan(v)) {
    out += "nan";
    return;
  }
  char buffer[32];
  auto r = std::to_chars(buffer, buffer + sizeof(buffer), v);
  out.append(buffer, r.ptr);
}

void append_double(std::string& out, double v) {
  if (std::isnan(v)) {
    out += "nan";
    return;
  }
  char buffer[32];
  auto r = std::to_chars(buffer, buffer + sizeof(buffer), v);
  out.append(buffer, r.ptr);
}

Writer::Writer(const std::string& path) : path_(path) {
  fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd_ < 0) throw OutputError(path, std::string("cannot create: ") + std::strerror(errno));
  buffer_.reserve(1 << 20);
}

Writer::~Writer() {
  if (fd_ >= 0) ::close(fd_);
}

void Writer::flush() {
  const char* p = buffer_.data();
  size_t left = buffer_.size();
  while (left > 0) {
    const ssize_t n = ::pwrite(fd_, p, left, off_t(offset_));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0)
      throw OutputError(path_,
                        std::string("write failed: ") + std::strerror(n < 0 ? errno : ENOSPC));
    p += n;
    left -= size_t(n);
    offset_ += uint64_t(n);
  }
  buffer_.clear();
  throw_if_interrupted();
}

void Writer::write(const void* data, size_t bytes) {
  const char* p = static_cast<const char*>(data);
  while (bytes > 0) {
    const size_t room = buffer_.capacity() - buffer_.size();
    const size_t n = std::min(room, bytes);
    buffer_.insert(buffer_.end(), p, p + n);
    p += n;
    bytes -= n;
    if (buffer_.size() == buffer_.capacity()) flush();
  }
}

void Writer::patch(uint64_t offset, const void* data, size_t bytes) {
  flush();
  if (::pwrite(fd_, data, bytes, off_t(offset)) != ssize_t(bytes))
    throw OutputError(path_, std::string("write failed: ") + std::strerror(errno));
}

void Writer::close() {
  flush();
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0)
    throw OutputError(path_, std::string("write failed: ") + std::strerror(errno));
}

void check_read_memory(const std::string& path, const char* format, double bytes,
                       const std::string& place, std::optional<uint64_t> limit) {
  if (!limit || bytes <= double(*limit)) return;
  throw BudgetExceeded(
      path + ": " + format + " is read whole: at " + place + " it holds about " +
      (bytes < 1e19 ? format_bytes(uint64_t(bytes)) : std::string("16 EiB")) + ", more than the " +
      format_bytes(*limit) +
      " the memory budget leaves for reading it; raise the budget (--memory-budget; "
      "memory_budget= in Python; .binlines and .h5 inputs are read piece by piece)");
}

void check_line_memory(const std::string& path, uint64_t line, uint64_t points, double bytes,
                       const std::string& place, std::optional<uint64_t> limit) {
  if (!limit || bytes <= double(*limit)) return;
  throw BudgetExceeded(path + ": line " + std::to_string(line) + " (" + place + ") has " +
                       std::to_string(points) + " points, read whole: about " +
                       (bytes < 1e19 ? format_bytes(uint64_t(bytes)) : std::string("16 EiB")) +
                       " in memory, more than the " + format_bytes(*limit) +
                       " the memory budget leaves for reading; raise the budget "
                       "(--memory-budget; memory_budget= in Python)");
}

}  // namespace linebake::io
