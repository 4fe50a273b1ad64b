// OutputLock: one writer at a time for an output path, across threads and processes.

#include <gtest/gtest.h>
#include <poll.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/output_lock.hpp"
#include "core/spill_file.hpp"
#include "test_util.hpp"

namespace linebake {
namespace {

using namespace std::chrono_literals;

// Whether a waiting thread got past the lock within `wait`.
bool taken_within(std::atomic<bool>& taken, std::chrono::milliseconds wait) {
  const auto until = std::chrono::steady_clock::now() + wait;
  while (!taken && std::chrono::steady_clock::now() < until) std::this_thread::sleep_for(10ms);
  return taken;
}

TEST(OutputLock, AnotherThreadWaitsUntilTheHolderReleases) {
  test::TempDir dir;
  const std::string cache = dir.file("c.lbc.h5");
  std::atomic<bool> taken{false};
  std::thread waiter;
  {
    const OutputLock held(cache);
    EXPECT_TRUE(std::filesystem::exists(cache + ".lock"));
    waiter = std::thread([&] {
      const OutputLock second(cache);
      taken = true;
    });
    EXPECT_FALSE(taken_within(taken, 300ms));
  }
  EXPECT_TRUE(taken_within(taken, 5000ms));
  waiter.join();
  EXPECT_FALSE(std::filesystem::exists(cache + ".lock"));
}

TEST(OutputLock, TheHoldingThreadTakesItAgain) {
  test::TempDir dir;
  const std::string cache = dir.file("c.lbc.h5");
  {
    const OutputLock outer(cache);
    {
      const OutputLock inner(cache);  // would wait for itself forever if not re-entrant
    }
    // Still held by the outer one after the inner one went.
    EXPECT_TRUE(std::filesystem::exists(cache + ".lock"));
  }
  EXPECT_FALSE(std::filesystem::exists(cache + ".lock"));
}

TEST(OutputLock, TwoSpellingsOfOnePathShareTheLock) {
  test::TempDir dir;
  const std::string cache = dir.file("c.lbc.h5");
  std::filesystem::create_directories(dir.file("sub"));
  std::filesystem::create_symlink(cache, dir.file("link.lbc.h5"));
  EXPECT_EQ(OutputLock::lock_path(dir.file("link.lbc.h5")), cache + ".lock");
  std::atomic<bool> taken{false};
  std::thread waiter;
  {
    const OutputLock held(cache);
    waiter = std::thread([&] {
      const OutputLock second(dir.file("sub/../c.lbc.h5"));
      taken = true;
    });
    EXPECT_FALSE(taken_within(taken, 300ms));
  }
  EXPECT_TRUE(taken_within(taken, 5000ms));
  waiter.join();
}

// A forked child that holds the lock on `output` from construction until release(), which
// returns whether the child held it and exited cleanly.
class HeldByAChild {
 public:
  explicit HeldByAChild(const std::string& output) {
    if (::pipe(held_) != 0 || ::pipe(release_) != 0) return;
    child_ = ::fork();
    if (child_ == 0) {
      int status = 1;
      {
        const OutputLock held(output);
        char byte = 'h';
        if (::write(held_[1], &byte, 1) == 1 && ::read(release_[0], &byte, 1) == 1) status = 0;
      }
      ::_exit(status);
    }
    char byte = 0;
    holding_ = child_ > 0 && ::read(held_[0], &byte, 1) == 1;
  }
  ~HeldByAChild() {
    if (child_ > 0) release();
    for (int fd : {held_[0], held_[1], release_[0], release_[1]})
      if (fd >= 0) ::close(fd);
  }
  bool holding() const { return holding_; }
  bool release() {
    const char byte = 'r';
    const bool told = ::write(release_[1], &byte, 1) == 1;
    int status = -1;
    const bool ended = ::waitpid(child_, &status, 0) == child_;
    child_ = -1;
    return told && ended && WIFEXITED(status) && WEXITSTATUS(status) == 0;
  }

 private:
  int held_[2] = {-1, -1}, release_[2] = {-1, -1};
  pid_t child_ = -1;
  bool holding_ = false;
};

// The flock is what another process sees: a child holds the lock until told to let it go.
TEST(OutputLock, AnotherProcessWaitsUntilTheHolderReleases) {
  test::TempDir dir;
  const std::string cache = dir.file("c.lbc.h5");
  HeldByAChild child(cache);
  ASSERT_TRUE(child.holding());
  std::atomic<bool> taken{false};
  std::thread waiter([&] {
    const OutputLock second(cache);
    taken = true;
  });
  EXPECT_FALSE(taken_within(taken, 400ms));
  EXPECT_TRUE(child.release());
  EXPECT_TRUE(taken_within(taken, 5000ms));
  waiter.join();
  EXPECT_FALSE(std::filesystem::exists(cache + ".lock"));
}

// Wait::no refuses a lock another thread or process holds (linebake run's output directory),
// takes a free one, and lets the holding thread take its own again.
TEST(OutputLock, WaitNoRefusesAHeldLockAndTakesAFreeOne) {
  test::TempDir dir;
  const std::string cache = dir.file("c.lbc.h5");
  {
    const OutputLock held(cache);
    { const OutputLock again(cache, OutputLock::Wait::no); }
    std::thread other([&] { EXPECT_THROW(OutputLock(cache, OutputLock::Wait::no), OutputBusy); });
    other.join();
  }
  {
    HeldByAChild child(cache);
    ASSERT_TRUE(child.holding());
    try {
      const OutputLock refused(cache, OutputLock::Wait::no);
      ADD_FAILURE() << "took a lock another process holds";
    } catch (const OutputBusy& e) {
      EXPECT_NE(std::string(e.what()).find("another process is writing it"), std::string::npos)
          << e.what();
    }
    EXPECT_TRUE(child.release());
  }
  {
    const OutputLock free_again(cache, OutputLock::Wait::no);
    EXPECT_TRUE(std::filesystem::exists(cache + ".lock"));
  }
  EXPECT_FALSE(std::filesystem::exists(cache + ".lock"));
}

// A child forked while a thread of the parent holds the lock (multiprocessing's fork) waits for
// the parent's flock like any process, and gets it once the parent lets go: it inherited the
// parent's table, whose holder is a thread it does not have, and had waited for ever on it.
TEST(OutputLock, AForkedChildWaitsForTheParentsLockNotForItsTable) {
  test::TempDir dir;
  const std::string cache = dir.file("c.lbc.h5");
  std::atomic<bool> held{false}, release{false};
  std::thread holder([&] {
    const OutputLock lock(cache);
    held = true;
    while (!release) std::this_thread::sleep_for(10ms);
  });
  while (!held) std::this_thread::sleep_for(10ms);
  int taken_pipe[2];
  ASSERT_EQ(::pipe(taken_pipe), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::alarm(20);  // a child that waits for ever fails the test rather than hanging it
    {
      const OutputLock lock(cache);
      const char byte = 't';
      if (::write(taken_pipe[1], &byte, 1) != 1) ::_exit(2);
    }
    ::_exit(0);
  }
  ::close(taken_pipe[1]);
  // Not while the parent holds it.
  pollfd waiting{taken_pipe[0], POLLIN, 0};
  EXPECT_EQ(::poll(&waiting, 1, 400), 0);
  release = true;
  holder.join();
  char byte = 0;
  EXPECT_EQ(::read(taken_pipe[0], &byte, 1), 1);
  int status = -1;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << status;
  ::close(taken_pipe[0]);
  EXPECT_FALSE(std::filesystem::exists(cache + ".lock"));
}

// Another user's lock file (a shared directory): locked read-only, not refused.
TEST(OutputLock, ALockFileThatIsNotWritableIsLockedReadOnly) {
  test::TempDir dir;
  const std::string cache = dir.file("c.lbc.h5");
  { std::ofstream(cache + ".lock").put('x'); }
  std::filesystem::permissions(cache + ".lock", std::filesystem::perms::owner_read);
  if (::access((cache + ".lock").c_str(), W_OK) == 0) GTEST_SKIP() << "root writes any file";
  EXPECT_NO_THROW({ const OutputLock lock(cache); });
}

TEST(OutputLock, ALockFileThatIsASymbolicLinkIsRefused) {
  test::TempDir dir;
  const std::string cache = dir.file("c.lbc.h5");
  std::filesystem::create_symlink(dir.file("elsewhere"), cache + ".lock");
  try {
    const OutputLock lock(cache);
    ADD_FAILURE() << "locked through a link";
  } catch (const OutputError& e) {
    EXPECT_NE(std::string(e.what()).find("it is a symbolic link"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(dir.file("elsewhere")));
}

TEST(OutputLock, ALockFileThatCannotBeMadeIsAnOutputError) {
  test::TempDir dir;
  EXPECT_THROW({ const OutputLock lock(dir.file("missing/c.lbc.h5")); }, OutputError);
}

}  // namespace
}  // namespace linebake

namespace linebake {
namespace {

// An output's name may take the file system's whole limit (255 bytes): the names made beside it
// (its temporary, a spill file, its lock) are shortened to fit; they had failed names of 230 to
// 255 bytes with "File name too long", once the work was done.
TEST(SideNames, AnOutputNameOfTheWholeLimitIsWrittenLockedAndSpilled) {
  test::TempDir dir;
  for (const size_t length : {size_t(200), size_t(255)}) {
    const std::string name = std::string(length - 4, 'n') + ".vtp";
    const std::string path = dir.file(name);
    {
      const OutputLock lock(path);
      EXPECT_LE(std::filesystem::path(OutputLock::lock_path(path)).filename().string().size(),
                255u);
      EXPECT_TRUE(std::filesystem::exists(OutputLock::lock_path(path)));
      SpillFile spill(path, "voxels-received");
      const uint64_t value = 42;
      spill.append(&value, sizeof value);
      AtomicFile file(path);
      EXPECT_LE(std::filesystem::path(file.temp_path()).filename().string().size(), 255u);
      std::ofstream(file.temp_path()) << "whole";
      file.commit();
    }
    std::ifstream in(path);
    std::string text;
    in >> text;
    EXPECT_EQ(text, "whole") << length;
  }
  // A short name is left as it is; a long one is cut to 100 bytes and its hash, the same for
  // every process (the lock is one file).
  EXPECT_EQ(side_name(dir.file("c.lbc.h5"), 60), dir.file("c.lbc.h5"));
  const std::string long_name(250, 'x');
  EXPECT_EQ(shortened_name(long_name).size(), 117u);
  EXPECT_EQ(shortened_name(long_name), shortened_name(long_name));
  EXPECT_NE(shortened_name(long_name), shortened_name(long_name + "y"));
  EXPECT_EQ(side_name(dir.file(long_name), 10), dir.file(shortened_name(long_name)));
}

// A temporary of a long name left by a process that is gone is removed by the next writer, as a
// short name's is.
TEST(SideNames, AStaleTemporaryOfALongNameIsRemoved) {
  test::TempDir dir;
  const std::string path = dir.file(std::string(240, 'n') + ".h5");
  const pid_t child = ::fork();
  if (child == 0) ::_exit(0);
  ASSERT_GT(child, 0);
  ::waitpid(child, nullptr, 0);  // a pid that no longer runs
  // The name the child would have used, with its pid in place of this process's.
  std::string stale = temporary_name(path);
  const std::string own = "-" + std::to_string(::getpid()) + "-";
  stale.replace(stale.rfind(own), own.size(), "-" + std::to_string(child) + "-");
  std::ofstream(stale) << "left";
  ASSERT_TRUE(std::filesystem::exists(stale));
  EXPECT_EQ(remove_stale_temporaries(path), 4u);
  EXPECT_FALSE(std::filesystem::exists(stale));
}

// MPI-IO reports a failed write without errno; the writer asks the file system. A file within
// a write of the file size limit is named so, and one far below it with room left is not.
TEST(WriteFailureCause, NamesTheFileSizeLimitWhereTheFileHasReachedIt) {
  test::TempDir dir;
  const std::string file = dir.file("c.h5");
  rlimit before{};
  ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &before), 0);
  if ((before.rlim_cur != RLIM_INFINITY && before.rlim_cur < (rlim_t{8} << 20)) ||
      free_bytes_for(file) < (uint64_t{16} << 20))
    GTEST_SKIP() << "the file size limit or the free space is below the test's";
  std::ofstream(file) << std::string(3 << 20, 'x');
  const auto cause_under = [&](rlim_t limit_bytes, uint64_t attempted) {
    rlimit limit = before;
    limit.rlim_cur = limit_bytes;
    EXPECT_EQ(::setrlimit(RLIMIT_FSIZE, &limit), 0);
    const std::string cause = write_failure_cause(file, attempted);
    EXPECT_EQ(::setrlimit(RLIMIT_FSIZE, &before), 0);
    return cause;
  };
  // 3 MiB written: a write of 2 MiB does not fit under 4 MiB, and does under 8.
  EXPECT_EQ(cause_under(rlim_t{4} << 20, 2 << 20),
            "the file is at the file size limit (ulimit -f) of 4.00 MiB");
  EXPECT_EQ(cause_under(rlim_t{8} << 20, 2 << 20), "");
}

}  // namespace
}  // namespace linebake
