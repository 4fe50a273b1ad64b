#pragma once
// Runs work we cannot trust (a third-party parser on a hostile file) in a forked child, so that its
// crash, hang or runaway allocation ends the child and not linebake. The child shares nothing back
// but a short text result through a pipe; it never flushes the parent's buffers or runs its exit
// handlers. Used to walk foreign HDF5 and NetCDF metadata before the parent reads the file
// (core/h5_probe.hpp, docs/reliability.md).

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace linebake {

// The child's wall-clock limit: LINEBAKE_ISOLATION_SECONDS where it is a number from 1 to
// 86400 (scripts/fuzz sets 10), else 120. Throws Error naming the variable for any other value.
double isolation_seconds();

struct IsolationLimits {
  double seconds = isolation_seconds();       // wall clock; the child is killed past it
  uint64_t memory_bytes = uint64_t{1} << 30;  // address space the child may add to the parent's
};

struct IsolatedOutcome {
  enum class Kind {
    Finished,     // the work returned; `result` holds what it returned
    Failed,       // the work threw; `result` holds the exception's message
    OutOfMemory,  // the work threw std::bad_alloc: it hit the memory cap
    Signal,       // the child died on `signal` (SIGSEGV, SIGABRT, ...)
    Exited,       // the child exited on its own with `exit_code` (a sanitizer's report)
    TimedOut,     // killed after the time limit
  };
  Kind kind = Kind::Finished;
  std::string result;
  int signal = 0;
  int exit_code = 0;
  double wall_s = 0;

  bool contained_crash() const {
    return kind == Kind::Signal || kind == Kind::Exited || kind == Kind::TimedOut ||
           kind == Kind::OutOfMemory;
  }
  // "died on SIGSEGV (Segmentation fault)", "ran past its 120 s limit", ...
  std::string describe(const IsolationLimits& limits) const;
};

// Forks, runs `work` in the child under `limits`, and waits for it. Throws Error when the child
// cannot be started (fork or pipe failing) and Interrupted when Ctrl-C or SIGTERM arrives while
// waiting (the child is killed first).
IsolatedOutcome run_isolated(const std::function<std::string()>& work,
                             const IsolationLimits& limits = {});

// What a child does (the forked one, and linebake-probe): runs `work` under `limits` with the
// default handlers of crash signals and no core file, writes its reply to `fd` ('R' and what it
// returned, 'E' and an exception's message, 'M' for std::bad_alloc) and ends the process.
[[noreturn]] void serve_isolated(int fd, const std::function<std::string()>& work,
                                 const IsolationLimits& limits);

// What linebake-probe writes first on kIsolatedReplyFd, before it replies as serve_isolated does.
// The protocol's number changes with its arguments, so a stale build's program says so.
inline const std::string kIsolatedHandshake = "linebake-probe " LINEBAKE_VERSION " protocol 2\n";
constexpr int kIsolatedReplyFd = 3;

// Runs the program `argv` (argv[0] a path), which writes kIsolatedHandshake and then replies as
// serve_isolated does on its descriptor kIsolatedReplyFd, under the same limits and waiting as
// run_isolated. Throws Error when the program does not say it is linebake-probe of this version
// (it could not start, or is another version's): no verdict on the file.
IsolatedOutcome run_isolated_program(const std::vector<std::string>& argv,
                                     const IsolationLimits& limits = {});

// linebake-probe (tools/linebake_probe.cpp), which runs the metadata walks in a fresh process:
// beside the file this code is in (the executable, or the Python module), else where the build
// tree made it, else beside the executable; "" when there is none.
const std::string& isolation_program();

// Runs `walk` (which opens `path` with `library` and touches what linebake will read) isolated, and
// turns a contained crash into an InputError naming the file: "the HDF5 library died on SIGSEGV
// (Segmentation fault) while reading its metadata: the file is malformed". A walk that throws
// becomes an InputError with its message. Does nothing when isolation is off.
//
// A process with more than one thread runs the walk in linebake-probe with `program_args` (what
// follows the program and the memory cap on its command line) where they are given and the
// program is found: a child forked from it would inherit the locks its other threads held at
// the fork (HDF5's global lock, while another thread is in HDF5) and stall on them. Otherwise,
// and in a process of one thread, a forked child runs `walk`.
void check_in_isolation(const std::string& path, const std::string& library,
                        const std::function<void()>& walk, const IsolationLimits& limits = {},
                        const std::vector<std::string>& program_args = {});

// How many crashes check_in_isolation() contained in this process (the fuzz targets report it).
uint64_t contained_crashes();

// False in AddressSanitizer builds (the fuzz preset), where RLIMIT_AS cannot cap the child: the
// sanitizer reserves terabytes of shadow memory. scripts/fuzz caps single allocations instead.
bool memory_cap_enforced();

// False when LINEBAKE_ISOLATION=off asks to read foreign files in-process (MPI stacks that forbid
// fork, debugging HDF5 itself).
bool isolation_enabled();

}  // namespace linebake
