#pragma once
// Ctrl-C, SIGTERM (a scheduler's end of job) and SIGHUP stop long work at its next safe point:
// the first signal sets a flag that loops check between batches, chunks, frames and steps;
// throwing Interrupted unwinds the stack, so every temporary and spill file is removed by the
// object that owns it. A second signal ends the process at once.

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

// For a program that embeds linebake and owns SIGINT itself (the Python interpreter): while a
// scope lives, SIGINT sets the flag the work checks, in place of the program's own handler,
// which it puts back when it ends, clearing the flag. A second SIGINT here does not end the
// process (the interpreter lives on); the work stops at its next check. Scopes nest: the
// outermost installs. Only for the thread the program's signals go to (Python's main thread).
class InterruptScope {
 public:
  InterruptScope();
  ~InterruptScope();
  InterruptScope(const InterruptScope&) = delete;
  InterruptScope& operator=(const InterruptScope&) = delete;
  // The signal that arrived in the scope (0: none); read before the scope ends.
  int signal() const;

 private:
  bool outermost_ = false;
};
// The signal that asked to stop, or 0.
int interrupt_signal();
// Throws Interrupted when a signal asked to stop.
void throw_if_interrupted();

}  // namespace linebake
