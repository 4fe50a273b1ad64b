#pragma once
// A temporary file for data that does not fit the memory budget: written once front to back,
// read back by offset. It is created beside an output (the same file system, which the output's
// space check covers) under a temporary name and unlinked at once: its space is given back when
// the object goes, on success, on an error, on an interruption, or when the process is killed.

#include <cstddef>
#include <cstdint>
#include <string>

namespace linebake {

class SpillFile {
 public:
  // Creates `<output>.<tag>.tmp-<host>-<pid>-<n>` and unlinks it. Throws OutputError when it
  // cannot.
  SpillFile(const std::string& output, const std::string& tag);
  ~SpillFile();
  SpillFile(const SpillFile&) = delete;
  SpillFile& operator=(const SpillFile&) = delete;

  // Appends and returns the offset the bytes start at.
  uint64_t append(const void* data, size_t bytes);
  void read(uint64_t offset, void* out, size_t bytes) const;
  uint64_t size() const { return size_; }
  const std::string& path() const { return path_; }

 private:
  std::string path_, output_;
  int fd_ = -1;
  uint64_t size_ = 0;
};

}  // namespace linebake
