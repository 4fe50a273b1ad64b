#pragma once
// One writer at a time for an output a command reads before it replaces it: a bake adds assets
// to the cache it finds at its output path, so two bakes into one path at once would each read
// the old cache and the later rename would drop what the earlier one added. The lock is an
// exclusive flock(2) on `<path>.lock` beside the output (the path resolved through symbolic
// links, so two spellings of one file share it), taken before the old output is read and held
// until the new one is renamed into place. Another process waits, checking for Ctrl-C while it
// does, and says once that it waits. Threads of one process wait for each other too, and the
// thread that holds the lock may take it again (the Python module holds it around a bake and
// the report it reads back). The lock file is removed on release; a process killed while holding
// it leaves the file, not the lock (the kernel drops a dead process's locks). It is made
// writable as the umask allows (another user's is locked read-only) and never opened through a
// symbolic link. A process forked while a lock is held or waited for (multiprocessing) starts
// with none: the parent's lock stays the parent's. On a file system without flock (after a
// second's tries where the error may pass) the output is written without it, and the process
// says so once.

#include <memory>
#include <string>

#include "core/error.hpp"

namespace linebake {

// The lock another process holds, where the caller asked not to wait (OutputLock::Wait::no).
class OutputBusy : public OutputError {
 public:
  using OutputError::OutputError;
};

class OutputLock {
 public:
  enum class Wait { yes, no };

  // Takes the lock on `output`, waiting for another process that holds it (Wait::yes) or
  // throwing OutputBusy (Wait::no). Throws OutputError when the lock file cannot be created,
  // Interrupted on a signal while waiting.
  explicit OutputLock(const std::string& output, Wait wait = Wait::yes);
  ~OutputLock();
  OutputLock(const OutputLock&) = delete;
  OutputLock& operator=(const OutputLock&) = delete;

  // `<output>.lock`, the output's path resolved as the lock resolves it.
  static std::string lock_path(const std::string& output);

  struct Entry;

 private:
  std::shared_ptr<Entry> entry_;
};

}  // namespace linebake
