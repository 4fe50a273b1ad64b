#include "core/output_lock.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <filesystem>
#include <map>
#include <mutex>
#include <thread>

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/interrupt.hpp"

namespace linebake {

// One per output path held or waited for in this process: which thread holds it, how often,
// and the lock file's descriptor while it does.
struct OutputLock::Entry {
  std::mutex mutex;
  std::condition_variable released;
  std::thread::id owner;
  int depth = 0;
  int fd = -1;
  std::string lock_path;
};

namespace {

constexpr auto kPoll = std::chrono::milliseconds(100);

std::mutex table_mutex;
std::map<std::string, std::weak_ptr<OutputLock::Entry>>& table() {
  static std::map<std::string, std::weak_ptr<OutputLock::Entry>> entries;
  return entries;
}

// The lock file's descriptor, once this process holds the flock on the file now at `path`
// (-1 where the file system has no flock). A file another holder removed as it released it is
// not the lock any longer: taken again under the file now there.
int take_file_lock(const std::string& path, const std::string& output) {
  bool said = false;
  for (;;) {
    const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd < 0)
      throw OutputError(output,
                        "cannot create its lock file " + path + ": " + std::strerror(errno));
    if (::flock(fd, LOCK_EX | LOCK_NB) == 0) {
      struct stat held {
      }, now{};
      if (::fstat(fd, &held) == 0 && ::stat(path.c_str(), &now) == 0 && held.st_dev == now.st_dev &&
          held.st_ino == now.st_ino)
        return fd;
      ::close(fd);
      continue;
    }
    const int error = errno;
    ::close(fd);
    if (error == ENOLCK || error == EOPNOTSUPP || error == ENOSYS || error == EINVAL) {
      notify(output + ": its file system has no file locks (" + std::strerror(error) +
             "); written without one, so another process writing it at the same time may "
             "replace what this one writes");
      ::unlink(path.c_str());
      return -1;
    }
    if (error != EWOULDBLOCK && error != EINTR)
      throw OutputError(output, "cannot lock " + path + ": " + std::strerror(error));
    if (!said) {
      notify("waiting for another process writing " + output + " to finish (it holds " + path +
             ")");
      said = true;
    }
    std::this_thread::sleep_for(kPoll);
    throw_if_interrupted();
  }
}

}  // namespace

std::string OutputLock::lock_path(const std::string& output) {
  return output_target(output) + ".lock";
}

OutputLock::OutputLock(const std::string& output) {
  const std::string path = lock_path(output);
  std::error_code ignored;
  const std::string key =
      std::filesystem::weakly_canonical(std::filesystem::absolute(path, ignored), ignored).string();
  {
    const std::lock_guard<std::mutex> lock(table_mutex);
    std::weak_ptr<Entry>& slot = table()[key];
    entry_ = slot.lock();
    if (!entry_) {
      entry_ = std::make_shared<Entry>();
      entry_->lock_path = path;
      slot = entry_;
    }
  }
  Entry& e = *entry_;
  std::unique_lock<std::mutex> lock(e.mutex);
  const std::thread::id me = std::this_thread::get_id();
  if (e.depth > 0 && e.owner == me) {
    ++e.depth;
    return;
  }
  while (e.depth > 0) {
    e.released.wait_for(lock, kPoll);
    if (interrupt_signal() != 0) {
      lock.unlock();
      entry_.reset();
      throw_if_interrupted();
    }
  }
  // Claimed within the process first; the other process is waited for without the mutex, so
  // that threads here waiting for this one still see Ctrl-C.
  e.owner = me;
  e.depth = 1;
  lock.unlock();
  try {
    const int fd = take_file_lock(e.lock_path, output);
    lock.lock();
    e.fd = fd;
  } catch (...) {
    lock.lock();
    e.depth = 0;
    e.owner = {};
    e.released.notify_all();
    lock.unlock();
    entry_.reset();
    throw;
  }
}

OutputLock::~OutputLock() {
  if (!entry_) return;
  Entry& e = *entry_;
  {
    const std::lock_guard<std::mutex> lock(e.mutex);
    if (--e.depth == 0) {
      if (e.fd >= 0) {
        // Removed while held, so that a waiter that opened it sees it gone and opens the next.
        ::unlink(e.lock_path.c_str());
        ::close(e.fd);
        e.fd = -1;
      }
      e.owner = {};
      e.released.notify_all();
    }
  }
  const std::lock_guard<std::mutex> lock(table_mutex);
  entry_.reset();
  for (auto it = table().begin(); it != table().end();)
    it = it->second.expired() ? table().erase(it) : std::next(it);
}

}  // namespace linebake
