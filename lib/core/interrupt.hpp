#pragma once
// Ctrl-C, SIGTERM (a scheduler's end of job) and SIGHUP stop long work at its next safe point:
// the first signal sets a flag that loops check between batches, chunks, frames and steps;
// throwing Interrupted unwinds the stack, so every temporary and spill file is removed by the
// object that owns it. A second signal ends the process at once, unless it is the first one's
// copy: the same signal from the same process within a second (coreutils' `timeout` signals the
// command and then its process group).

#include <atomic>
#include <string>

#include "core/error.hpp"

namespace linebake {

class Interrupted : public Error {
 public:
  // `where`: what was interrupted and what was kept, for the user.
  explicit Interrupted(int signal, const std::string& where = "");
  int signal() const { return signal_; }

 private:
  int signal_;
};

// Installs the handlers (idempotent). Commands that write call it; tests need not.
void install_interrupt_handlers();

// For a program that embeds linebake and calls it from several threads (the Python module):
// one call into the library in flight, on any thread, for as long as it lives.
class EmbeddedCall {
 public:
  EmbeddedCall();
  ~EmbeddedCall();
  EmbeddedCall(const EmbeddedCall&) = delete;
  EmbeddedCall& operator=(const EmbeddedCall&) = delete;
};

// For such a program that owns SIGINT itself (the Python interpreter), around a call made on
// the thread its signals go to: while the scope lives, SIGINT sets a flag the work checks, in
// place of the program's handler, which finish() puts back. The flag stops the work only while
// its call is the only EmbeddedCall in flight (another thread's call would see it too); else
// finish() hands it back for the program to deliver. A second SIGINT does not end the process.
// Scopes nest: the outermost installs.
class InterruptScope {
 public:
  InterruptScope();
  ~InterruptScope();
  InterruptScope(const InterruptScope&) = delete;
  InterruptScope& operator=(const InterruptScope&) = delete;
  // Puts the program's handler back first, then returns the signal that came in the scope (0:
  // none) and clears it. Idempotent; the destructor calls it.
  int finish();

 private:
  bool outermost_ = false, finished_ = false;
};
// The signal that asked to stop, or 0.
int interrupt_signal();
// Throws Interrupted when a signal asked to stop.
void throw_if_interrupted();

// For the tasks of one parallel loop (or the callbacks of one build): the first signal any of
// them sees, kept. interrupt_signal() can read as 0 again (an embedded program's SIGINT once
// another thread's call starts), and a loop that skipped work for a signal must not then go on
// as if it had done it.
class StopLatch {
 public:
  // Whether to stop: a signal seen now or before.
  bool stopped() {
    if (signal_.load(std::memory_order_relaxed) != 0) return true;
    const int signal = interrupt_signal();
    if (signal != 0) signal_ = signal;
    return signal != 0;
  }
  // Throws Interrupted when stopped() has seen a signal (after the loop).
  void throw_if_stopped() const {
    if (const int signal = signal_.load()) throw Interrupted(signal);
  }

 private:
  std::atomic<int> signal_{0};
};

}  // namespace linebake
