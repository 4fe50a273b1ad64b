#include "core/isolated.hpp"

#include <dlfcn.h>
#include <fcntl.h>
#include <poll.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <new>

#include "core/error.hpp"
#include "core/interrupt.hpp"

#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define LINEBAKE_ASAN 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__)
#define LINEBAKE_ASAN 1
#endif

// Sanitizer runtimes (the fuzz build) call this before they exit on a report; libFuzzer uses it to
// keep the input as a crash. A contained crash in the child is not one, so the child clears it.
extern "C" void __sanitizer_set_death_callback(void (*callback)(void)) __attribute__((weak));

namespace linebake {
namespace {

#ifndef LINEBAKE_ASAN
// The address space the process has mapped now (/proc/self/statm's first field), or 0.
uint64_t mapped_bytes() {
  FILE* f = std::fopen("/proc/self/statm", "r");
  if (!f) return 0;
  unsigned long long pages = 0;
  const int n = std::fscanf(f, "%llu", &pages);
  std::fclose(f);
  return n == 1 ? pages * static_cast<uint64_t>(sysconf(_SC_PAGESIZE)) : 0;
}
#endif

void write_all(int fd, const char* data, size_t size) {
  while (size > 0) {
    const ssize_t n = ::write(fd, data, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return;
    data += n;
    size -= static_cast<size_t>(n);
  }
}

const char* signal_text(int signal) {
  switch (signal) {
    case SIGSEGV:
      return "SIGSEGV";
    case SIGBUS:
      return "SIGBUS";
    case SIGABRT:
      return "SIGABRT";
    case SIGFPE:
      return "SIGFPE";
    case SIGILL:
      return "SIGILL";
    case SIGKILL:
      return "SIGKILL";
    default:
      return nullptr;
  }
}

}  // namespace

[[noreturn]] void serve_isolated(int fd, const std::function<std::string()>& work,
                                 [[maybe_unused]] const IsolationLimits& limits) {
  // A crash must end the child with its signal, not run the parent's handlers (libFuzzer's, the
  // interrupt flag); no core file either.
  for (int s : {SIGSEGV, SIGBUS, SIGABRT, SIGFPE, SIGILL, SIGALRM, SIGXFSZ, SIGPIPE})
    std::signal(s, SIG_DFL);
  // Ctrl-C reaches the whole process group: the parent decides, and kills the child itself.
  for (int s : {SIGINT, SIGTERM, SIGHUP}) std::signal(s, SIG_IGN);
  if (__sanitizer_set_death_callback) __sanitizer_set_death_callback(nullptr);
  struct rlimit core {};
  setrlimit(RLIMIT_CORE, &core);
#ifndef LINEBAKE_ASAN
  // AddressSanitizer reserves terabytes of shadow memory: there the cap is the sanitizer's own
  // allocation limit, set by scripts/fuzz.
  const uint64_t mapped = mapped_bytes();  // 0 without /proc: then no cap, rather than a wrong one
  if (limits.memory_bytes > 0 && mapped > 0) {
    const rlim_t cap = static_cast<rlim_t>(mapped + limits.memory_bytes);
    struct rlimit as {
      cap, cap
    };
    setrlimit(RLIMIT_AS, &as);
  }
#endif
  char tag = 'R';
  std::string text;
  try {
    text = work();
  } catch (const std::bad_alloc&) {
    tag = 'M';
  } catch (const std::exception& e) {
    tag = 'E';
    text = e.what();
  } catch (...) {
    tag = 'E';
    text = "unknown exception";
  }
  write_all(fd, &tag, 1);
  write_all(fd, text.data(), text.size());
  ::close(fd);
  _exit(0);
}

std::string IsolatedOutcome::describe(const IsolationLimits& limits) const {
  switch (kind) {
    case Kind::Finished:
      return "finished";
    case Kind::Failed:
      return "failed: " + result;
    case Kind::OutOfMemory:
      return "needed more than " + std::to_string(limits.memory_bytes >> 20) + " MiB";
    case Kind::Signal: {
      const char* name = signal_text(signal);
      return std::string("crashed on ") + (name ? name : "signal " + std::to_string(signal)) +
             " (" + strsignal(signal) + ")";
    }
    case Kind::Exited:
      return "ended its process with status " + std::to_string(exit_code);
    case Kind::TimedOut:
      return "ran past " + std::to_string(static_cast<int>(limits.seconds)) + " s";
  }
  return "";
}

namespace {

// What an isolated child left: its reply, how it ended.
struct ChildEnd {
  std::string received;
  int status = 0;
  bool timed_out = false, ended = false;
  int interrupted = 0;  // the signal that asked this process to stop, or 0
};

// Waits for the isolated child `pid` that replies on `fd` (its read end, closed here) and
// started at `start`, within `limits`; kills it past them or on an interruption. The child's end
// is seen by its reply's end of file or, every 100 ms, by waitpid: a process forked elsewhere in
// this one (another thread's) may hold the pipe's write end open, and no end of file comes.
ChildEnd wait_for_child(pid_t pid, int fd, std::chrono::steady_clock::time_point start,
                        const IsolationLimits& limits) {
  ChildEnd end;
  bool reaped = false;
  const auto drain = [&] {  // what the child wrote before it ended
    char buffer[4096];
    for (pollfd p{fd, POLLIN, 0}; poll(&p, 1, 0) > 0;) {
      const ssize_t n = ::read(fd, buffer, sizeof buffer);
      if (n <= 0) break;
      end.received.append(buffer, static_cast<size_t>(n));
    }
  };
  for (;;) {
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (elapsed >= limits.seconds) {
      end.timed_out = true;
      break;
    }
    if ((end.interrupted = interrupt_signal()) != 0) break;
    pollfd p{fd, POLLIN, 0};
    const int wait_ms = static_cast<int>(std::min(100.0, (limits.seconds - elapsed) * 1000) + 1);
    const int ready = poll(&p, 1, wait_ms);
    if (ready < 0 && errno != EINTR) break;
    if (ready > 0) {
      char buffer[4096];
      const ssize_t n = ::read(fd, buffer, sizeof buffer);
      if (n < 0 && errno == EINTR) continue;
      if (n > 0) {
        end.received.append(buffer, static_cast<size_t>(n));
        continue;
      }
      end.ended = n == 0;  // end of file: the child has exited (or closed its end)
      break;
    }
    const pid_t r = waitpid(pid, &end.status, WNOHANG);
    if (r == pid) {
      reaped = end.ended = true;
      drain();
      break;
    }
  }
  ::close(fd);
  if (!end.ended) kill(pid, SIGKILL);  // timed out, interrupted, or poll/read failed
  if (!end.interrupted) end.interrupted = interrupt_signal();
  if (!reaped)
    while (waitpid(pid, &end.status, 0) < 0 && errno == EINTR) {
    }
  return end;
}

// The outcome of a child that ended as `end` says.
IsolatedOutcome outcome_of(const ChildEnd& end, std::chrono::steady_clock::time_point start) {
  IsolatedOutcome outcome;
  outcome.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (end.interrupted) throw Interrupted(end.interrupted, "while a reader ran isolated");
  if (end.timed_out || !end.ended) {
    outcome.kind = IsolatedOutcome::Kind::TimedOut;
  } else if (WIFSIGNALED(end.status)) {
    const int signal = WTERMSIG(end.status);
    // The user's Ctrl-C (or a job's end) reached the child before it could ignore it: not the
    // file's doing.
    if (signal == SIGINT || signal == SIGTERM || signal == SIGHUP)
      throw Interrupted(signal, "while a reader ran isolated");
    outcome.kind = IsolatedOutcome::Kind::Signal;
    outcome.signal = signal;
  } else if (WIFEXITED(end.status) && WEXITSTATUS(end.status) != 0) {
    outcome.kind = IsolatedOutcome::Kind::Exited;
    outcome.exit_code = WEXITSTATUS(end.status);
  } else if (end.received.empty()) {
    outcome.kind = IsolatedOutcome::Kind::Exited;  // exited 0 without a result: never ours
  } else {
    const char tag = end.received[0];
    outcome.result = end.received.substr(1);
    outcome.kind = tag == 'R'   ? IsolatedOutcome::Kind::Finished
                   : tag == 'M' ? IsolatedOutcome::Kind::OutOfMemory
                                : IsolatedOutcome::Kind::Failed;
  }
  return outcome;
}

}  // namespace

IsolatedOutcome run_isolated(const std::function<std::string()>& work,
                             const IsolationLimits& limits) {
  const auto start = std::chrono::steady_clock::now();
  int fds[2];
  if (pipe2(fds, O_CLOEXEC) != 0)
    throw Error(std::string("cannot start an isolated reader: pipe: ") + std::strerror(errno));
  std::fflush(nullptr);  // nothing buffered may be written twice
  const pid_t pid = fork();
  if (pid < 0) {
    const int error = errno;
    ::close(fds[0]);
    ::close(fds[1]);
    throw Error(std::string("cannot start an isolated reader: fork: ") + std::strerror(error) +
                " (LINEBAKE_ISOLATION=off reads in-process; docs/reliability.md)");
  }
  if (pid == 0) {
    ::close(fds[0]);
    serve_isolated(fds[1], work, limits);
  }
  ::close(fds[1]);
  return outcome_of(wait_for_child(pid, fds[0], start, limits), start);
}

IsolatedOutcome run_isolated_program(const std::vector<std::string>& argv,
                                     const IsolationLimits& limits) {
  const auto start = std::chrono::steady_clock::now();
  int fds[2];
  if (pipe2(fds, O_CLOEXEC) != 0)
    throw Error(std::string("cannot start an isolated reader: pipe: ") + std::strerror(errno));
  // The program replies on its descriptor 3 (its standard output may be a library's to print
  // on: /dev/null); it gets no other descriptor of this process. The write end goes to 3 from a
  // descriptor above it, as a dup2 onto itself would keep its close-on-exec.
  const int reply = fcntl(fds[1], F_DUPFD_CLOEXEC, 10);
  ::close(fds[1]);
  if (reply < 0) {
    ::close(fds[0]);
    throw Error(std::string("cannot start an isolated reader: fcntl: ") + std::strerror(errno));
  }
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, reply, kIsolatedReplyFd);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
#if defined(__GLIBC__) && (__GLIBC__ > 2 || (__GLIBC__ == 2 && __GLIBC_MINOR__ >= 34))
  posix_spawn_file_actions_addclosefrom_np(&actions, kIsolatedReplyFd + 1);
#endif
  // Ctrl-C, SIGTERM and SIGHUP reach the whole process group; the program starts with them
  // blocked (it ignores them once it runs: this process decides and kills it), and with the
  // crash signals and SIGPIPE at their defaults whatever this process does with them.
  posix_spawnattr_t attributes;
  posix_spawnattr_init(&attributes);
  sigset_t blocked, defaults;
  sigemptyset(&blocked);
  for (int s : {SIGINT, SIGTERM, SIGHUP}) sigaddset(&blocked, s);
  sigemptyset(&defaults);
  for (int s : {SIGSEGV, SIGBUS, SIGABRT, SIGFPE, SIGILL, SIGPIPE, SIGXFSZ})
    sigaddset(&defaults, s);
  posix_spawnattr_setsigmask(&attributes, &blocked);
  posix_spawnattr_setsigdefault(&attributes, &defaults);
  posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF);
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid = 0;
  const int error =
      posix_spawn(&pid, argv.at(0).c_str(), &actions, &attributes, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attributes);
  ::close(reply);
  if (error != 0) {
    ::close(fds[0]);
    throw Error("cannot start an isolated reader: " + argv[0] + ": " + std::strerror(error) +
                " (LINEBAKE_ISOLATION=off reads in-process; docs/reliability.md)");
  }
  ChildEnd end = wait_for_child(pid, fds[0], start, limits);
  // A program that never said it was linebake-probe of this version (a loader that could not
  // find its libraries, another version's) did not walk anything: that is no verdict on the
  // file, and said as what it is.
  if (!end.interrupted && !end.timed_out && end.received.rfind(kIsolatedHandshake, 0) != 0) {
    IsolatedOutcome failed = outcome_of(end, start);
    const std::string said = end.received.substr(0, end.received.find('\n'));
    throw Error("cannot run " + argv[0] + ": it " +
                (failed.kind == IsolatedOutcome::Kind::Finished ||
                         failed.kind == IsolatedOutcome::Kind::Failed
                     ? "replied '" + said.substr(0, 80) + "'"
                     : failed.describe(limits)) +
                ", not as " + kIsolatedHandshake.substr(0, kIsolatedHandshake.size() - 1) +
                " (reinstall linebake, or LINEBAKE_ISOLATION=off reads in-process)");
  }
  if (end.received.rfind(kIsolatedHandshake, 0) == 0)
    end.received.erase(0, kIsolatedHandshake.size());
  return outcome_of(end, start);
}

namespace {

// Threads of this process (/proc/self/task's entries); 1 without /proc.
int thread_count() {
  std::error_code ec;
  int threads = 0;
  for (auto it = std::filesystem::directory_iterator("/proc/self/task", ec);
       !ec && it != std::filesystem::directory_iterator(); it.increment(ec))
    ++threads;
  return std::max(threads, 1);
}

// The directory of the file that holds this code: the executable, or the shared object (the
// Python module) it was linked into.
std::filesystem::path code_directory() {
  Dl_info info{};
  if (dladdr(reinterpret_cast<void*>(&thread_count), &info) == 0 || !info.dli_fname) return {};
  std::error_code ec;
  const std::filesystem::path file = std::filesystem::canonical(info.dli_fname, ec);
  return ec ? std::filesystem::path() : file.parent_path();
}

}  // namespace

const std::string& isolation_program() {
  static const std::string program = [] {
    // Beside this code first, then where the build made it, then beside the executable: the
    // Python module's own before one beside python3.
    std::vector<std::filesystem::path> places{code_directory()};
#ifdef LINEBAKE_PROBE_DIR
    places.push_back(LINEBAKE_PROBE_DIR);
#endif
    std::error_code ec;
    const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
    if (!ec) places.push_back(self.parent_path());
    for (const std::filesystem::path& dir : places) {
      if (dir.empty()) continue;
      const std::filesystem::path candidate = dir / "linebake-probe";
      if (::access(candidate.c_str(), X_OK) == 0) return candidate.string();
    }
    return std::string();
  }();
  return program;
}

namespace {
std::atomic<uint64_t> contained{0};
}

uint64_t contained_crashes() {
  return contained.load();
}

void check_in_isolation(const std::string& path, const std::string& library,
                        const std::function<void()>& walk, const IsolationLimits& limits,
                        const std::vector<std::string>& program_args) {
  if (!isolation_enabled()) return;
  const std::string& program = isolation_program();
  IsolatedOutcome outcome;
  if (!program_args.empty() && !program.empty() && thread_count() > 1) {
    std::vector<std::string> argv{program, std::to_string(limits.memory_bytes),
                                  std::to_string(limits.seconds), std::to_string(getpid())};
    argv.insert(argv.end(), program_args.begin(), program_args.end());
    outcome = run_isolated_program(argv, limits);
  } else {
    outcome = run_isolated(
        [&walk] {
          walk();
          return std::string("ok");
        },
        limits);
  }
  if (outcome.kind == IsolatedOutcome::Kind::Finished) return;
  if (outcome.kind == IsolatedOutcome::Kind::Failed) throw InputError(path, "", outcome.result);
  ++contained;
  throw InputError(path, "",
                   "the " + library + " library " + outcome.describe(limits) +
                       " while reading its metadata in an isolated process: the file is "
                       "malformed");
}

bool memory_cap_enforced() {
#ifdef LINEBAKE_ASAN
  return false;
#else
  return true;
#endif
}

double isolation_seconds() {
  const char* value = std::getenv("LINEBAKE_ISOLATION_SECONDS");
  if (!value || !*value) return 120;
  char* end = nullptr;
  const double seconds = std::strtod(value, &end);
  if (*end != '\0' || !(seconds >= 1 && seconds <= 86400))
    throw Error("LINEBAKE_ISOLATION_SECONDS=" + std::string(value) +
                ": expected a number of seconds from 1 to 86400");
  return seconds;
}

bool isolation_enabled() {
  const char* value = std::getenv("LINEBAKE_ISOLATION");
  return !(value && (std::strcmp(value, "off") == 0 || std::strcmp(value, "0") == 0));
}

}  // namespace linebake
