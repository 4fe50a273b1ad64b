#include "core/spill_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "core/atomic_file.hpp"
#include "core/error.hpp"

namespace linebake {

SpillFile::SpillFile(const std::string& output, const std::string& tag)
    : path_(temporary_name(output, tag)), output_(output) {
  fd_ = ::open(path_.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd_ < 0)
    throw OutputError(output,
                      "cannot create the spill file " + path_ + ": " + std::strerror(errno));
  // Unnamed at once: only the descriptor holds it, so a process killed outright (SIGKILL, the
  // kernel's OOM killer, an MPI job aborted by another rank) leaves no spill behind.
  ::unlink(path_.c_str());
}

SpillFile::~SpillFile() {
  if (fd_ >= 0) ::close(fd_);
}

uint64_t SpillFile::append(const void* data, size_t bytes) {
  const uint64_t at = size_;
  const char* p = static_cast<const char*>(data);
  size_t left = bytes;
  while (left > 0) {
    const ssize_t n = ::pwrite(fd_, p, left, off_t(size_));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0)
      throw OutputError(output_, "cannot write the spill file " + path_ + ": " +
                                     std::strerror(n < 0 ? errno : ENOSPC));
    p += n;
    left -= size_t(n);
    size_ += uint64_t(n);
  }
  return at;
}

void SpillFile::read(uint64_t offset, void* out, size_t bytes) const {
  char* p = static_cast<char*>(out);
  while (bytes > 0) {
    const ssize_t n = ::pread(fd_, p, bytes, off_t(offset));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0)
      throw OutputError(output_, "cannot read back the spill file " + path_ + ": " +
                                     (n < 0 ? std::strerror(errno) : "short read"));
    p += n;
    bytes -= size_t(n);
    offset += uint64_t(n);
  }
}

}  // namespace linebake
