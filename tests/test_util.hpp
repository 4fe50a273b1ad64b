#pragma once
// Helpers shared by the tests: temporary directories and a line set with awkward values.

#include <gtest/gtest.h>
#include <hdf5.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>

#include "core/error.hpp"
#include "formats/registry.hpp"
#include "lines/line_set.hpp"
#include "pipeline/bake.hpp"
#include "render/vulkan/context.hpp"

namespace linebake::test {

// A Vulkan context whose validation layer fails the test on any error.
inline vk::ContextOptions validated() {
  vk::ContextOptions o;
  o.validation = true;
  return o;
}

// A fresh directory per test, removed afterwards.
class TempDir {
 public:
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = std::filesystem::temp_directory_path() /
            ("linebake-" + std::string(info->test_suite_name()) + "-" + info->name() + "-" +
             std::to_string(::getpid()));
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() { std::filesystem::remove_all(path_); }
  std::string file(const std::string& name) const { return (path_ / name).string(); }
  // Names of everything in the directory (to check that nothing is left behind).
  std::vector<std::string> entries() const {
    std::vector<std::string> names;
    for (const auto& e : std::filesystem::directory_iterator(path_))
      names.push_back(e.path().filename().string());
    return names;
  }

 private:
  std::filesystem::path path_;
};

// Bake options for `input` (a file or a synth: source) into `cache` in `dir`, without progress:
// the tests set what they need beside these and call bake().
inline BakeOptions quiet_bake(const TempDir& dir, const std::string& input,
                              const std::string& cache) {
  BakeOptions o;
  o.input = input;
  o.cache = dir.file(cache);
  o.progress = false;
  return o;
}

inline std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}
inline void write_text(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}
inline void write_bytes(const std::string& path, const std::vector<unsigned char>& bytes) {
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()),
             static_cast<std::streamsize>(bytes.size()));
}

// Appends values in the requested byte order (for binary test files).
class Bytes {
 public:
  explicit Bytes(bool big_endian) : big_(big_endian) {}
  template <typename T>
  Bytes& put(T v) {
    unsigned char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    if (big_ != (std::endian::native == std::endian::big)) std::reverse(b, b + sizeof(T));
    data.insert(data.end(), b, b + sizeof(T));
    return *this;
  }
  Bytes& text(const std::string& s, size_t width) {
    std::vector<unsigned char> field(width, 0);
    std::memcpy(field.data(), s.data(), std::min(width, s.size()));
    data.insert(data.end(), field.begin(), field.end());
    return *this;
  }
  std::vector<unsigned char> data;

 private:
  bool big_;
};

// Three lines with values that text formats get wrong when they round: 1/3, 0.1, denormals,
// large and negative values, and an attribute name with a space.
inline LineSet awkward_lines(bool with_line_attributes) {
  LineSet lines;
  const float values[] = {1.0f / 3.0f, 0.1f, -2.5e-38f, 1.0e-42f, 3.4e37f,  -7.0f,
                          123456.789f, 0.0f, -0.0f,     1e-7f,    65504.0f, 2.0f / 3.0f};
  size_t v = 0;
  const size_t sizes[] = {2, 5, 3};
  for (size_t line = 0; line < 3; ++line) {
    for (size_t i = 0; i < sizes[line]; ++i, ++v)
      lines.append_point(values[v % 12] + static_cast<float>(i), values[(v + 1) % 12],
                         values[(v + 5) % 12] * static_cast<float>(line + 1));
    lines.end_line();
  }
  Attribute a{"vorticity", {}}, b{"second attr", {}};
  for (size_t i = 0; i < lines.point_count(); ++i) {
    a.values.push_back(values[(i + 3) % 12]);
    b.values.push_back(static_cast<float>(i) / 7.0f);
  }
  lines.attributes = {a, b};
  if (with_line_attributes) lines.line_attributes = {{"line_id", {10.0f, 11.5f, 1.0f / 9.0f}}};
  return lines;
}

// File offset of a dataset's first stored byte (its first chunk where chunked).
inline uint64_t data_offset(const std::string& path, const std::string& dataset) {
  const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  const hid_t d = H5Dopen2(f, dataset.c_str(), H5P_DEFAULT);
  haddr_t offset = H5Dget_offset(d);
  if (offset == HADDR_UNDEF) {
    hsize_t coords[2];
    unsigned mask;
    hsize_t size = 0;
    const hid_t space = H5Dget_space(d);
    H5Dget_chunk_info(d, space, 0, coords, &mask, &offset, &size);
    H5Sclose(space);
    offset += size / 2;  // inside the compressed bytes
  } else {
    offset += 100;
  }
  H5Dclose(d);
  H5Fclose(f);
  return offset;
}

inline void flip_byte(const std::string& path, uint64_t offset) {
  std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
  f.seekg(std::streamoff(offset));
  char c = 0;
  f.read(&c, 1);
  c = static_cast<char>(c ^ 0x5A);
  f.seekp(std::streamoff(offset));
  f.write(&c, 1);
}

// The InputError message of reading `path`, or "" when it reads.
inline std::string read_error(const std::string& path) {
  try {
    read_line_set(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// Reads `path` with the metadata walk in a child process and again in-process
// (LINEBAKE_ISOLATION on, then off) and expects each read to throw an InputError naming the file
// whose message holds every one of `phrases`: the reader's own checks, not just the walk's.
inline void expect_refused_either_way(const std::string& path,
                                      std::initializer_list<std::string> phrases) {
  for (const char* isolation : {"on", "off"}) {
    SCOPED_TRACE(std::string("LINEBAKE_ISOLATION=") + isolation);
    setenv("LINEBAKE_ISOLATION", isolation, 1);
    try {
      (void)read_line_set(path);
      ADD_FAILURE() << "no error";
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), path);
      for (const std::string& phrase : phrases)
        EXPECT_NE(std::string(e.what()).find(phrase), std::string::npos) << e.what();
    }
  }
  unsetenv("LINEBAKE_ISOLATION");
}

}  // namespace linebake::test
