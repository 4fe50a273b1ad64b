#include "core/output_lock.hpp"

#include <fcntl.h>
#include <pthread.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
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
  std::string file;     // the lock file, absolute: a chdir while held does not move it
  std::string display;  // as the user named it, for messages
  pid_t pid = ::getpid();
};

namespace {

constexpr auto kPoll = std::chrono::milliseconds(100);

std::mutex table_mutex;
std::map<std::string, std::weak_ptr<OutputLock::Entry>>& table() {
  static std::map<std::string, std::weak_ptr<OutputLock::Entry>> entries;
  return entries;
}

// A child forked while this process holds a lock (multiprocessing's fork) shares the lock file's
// open description: were it to keep its copy, the lock would outlive the parent's release for as
// long as the child ran. The child closes its copies, forgets the table (the threads that held
// or waited are not in it), and leaves the file to the parent. table_mutex is taken across the
// fork, so the child's is not held by a thread it does not have.
void before_fork() {
  table_mutex.lock();
}
void after_fork_in_parent() {
  table_mutex.unlock();
}
void after_fork_in_child() {
  for (auto& [key, weak] : table())
    if (const auto entry = weak.lock(); entry && entry->fd >= 0) {
      ::close(entry->fd);
      entry->fd = -1;
    }
  table().clear();
  table_mutex.unlock();
}

std::once_flag fork_handlers;

// Whether `fd` is the file now at `path` (the holder before removes it as it releases).
bool still_there(int fd, const std::string& path) {
  struct stat held {
  }, now{};
  return ::fstat(fd, &held) == 0 && ::stat(path.c_str(), &now) == 0 && held.st_dev == now.st_dev &&
         held.st_ino == now.st_ino;
}

// The lock file's descriptor, once this process holds the flock on the file now at `file`
// (-1 where the file system has no flock). A file another holder removed as it released it is
// not the lock any longer: taken again under the file now there.
int take_file_lock(const std::string& file, const std::string& display, const std::string& output,
                   OutputLock::Wait wait) {
  bool said = false;
  int no_locks = 0;
  for (;;) {
    // Made writable for the group and others as the umask allows, so that another user who may
    // write the cache may lock it too; one of theirs is locked read-only. Never through a link.
    int fd = ::open(file.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0666);
    bool read_only = false;
    if (fd < 0 && errno == EACCES) {
      fd = ::open(file.c_str(), O_RDONLY | O_CLOEXEC | O_NOFOLLOW);
      if (fd < 0 && errno == ENOENT) errno = EACCES;  // the directory's, not a missing file
      read_only = fd >= 0;
    }
    if (fd < 0) {
      const int error = errno;
      throw OutputError(output, "cannot open its lock file " + display + ": " +
                                    (error == ELOOP ? "it is a symbolic link (remove it)"
                                                    : std::string(std::strerror(error))));
    }
    if (::flock(fd, LOCK_EX | LOCK_NB) == 0) {
      if (still_there(fd, file)) return fd;
      ::close(fd);
      continue;
    }
    const int error = errno;
    ::close(fd);
    // NFS emulates flock with fcntl locks, and an exclusive one needs a writable descriptor:
    // another user's lock file there cannot be locked at all (EBADF).
    if (error == ENOLCK || error == EOPNOTSUPP || error == ENOSYS || error == EINVAL ||
        (error == EBADF && read_only)) {
      // ENOLCK may pass (an NFS lock manager's table full): a second's tries first.
      if (error == ENOLCK && ++no_locks < 10) {
        std::this_thread::sleep_for(kPoll);
        throw_if_interrupted();
        continue;
      }
      static std::atomic<bool> told{false};
      if (!told.exchange(true))
        notify(output + ": its file system has no file locks (" + std::strerror(error) +
               "); written without one, so another process writing it at the same time may "
               "replace what this one writes");
      return -1;
    }
    if (error != EWOULDBLOCK && error != EINTR)
      throw OutputError(output, "cannot lock " + display + ": " + std::strerror(error));
    if (error == EWOULDBLOCK && wait == OutputLock::Wait::no)
      throw OutputBusy(output, "another process is writing it (it holds " + display + ")");
    if (!said) {
      notify("waiting for another process writing " + output + " to finish (it holds " + display +
             ")");
      said = true;
    }
    std::this_thread::sleep_for(kPoll);
    throw_if_interrupted();
  }
}

}  // namespace

std::string OutputLock::lock_path(const std::string& output) {
  return side_name(output_target(output), 5) + ".lock";
}

OutputLock::OutputLock(const std::string& output, Wait wait) {
  std::call_once(fork_handlers,
                 [] { ::pthread_atfork(before_fork, after_fork_in_parent, after_fork_in_child); });
  const std::string display = lock_path(output);
  std::error_code ignored;
  const std::string key =
      std::filesystem::weakly_canonical(std::filesystem::absolute(display, ignored), ignored)
          .string();
  {
    const std::lock_guard<std::mutex> lock(table_mutex);
    std::weak_ptr<Entry>& slot = table()[key];
    entry_ = slot.lock();
    if (!entry_) {
      entry_ = std::make_shared<Entry>();
      entry_->file = key;
      entry_->display = display;
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
  if (e.depth > 0 && wait == Wait::no) {
    lock.unlock();
    entry_.reset();
    throw OutputBusy(output, "another thread of this process is writing it");
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
    const int fd = take_file_lock(e.file, e.display, output, wait);
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
  // In a forked child the lock is the parent's: its copy of the file was closed at the fork.
  if (entry_->pid != ::getpid()) return;
  Entry& e = *entry_;
  {
    const std::lock_guard<std::mutex> lock(e.mutex);
    if (--e.depth == 0) {
      if (e.fd >= 0) {
        // Removed while held, so that a waiter that opened it sees it gone and opens the next;
        // unlocked before it is closed, so that a copy of the descriptor a forked child may
        // hold (a fork between the lock and this entry's record of it) does not keep it.
        ::unlink(e.file.c_str());
        ::flock(e.fd, LOCK_UN);
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
