#include "core/interrupt.hpp"

#include <csignal>
#include <cstring>

namespace linebake {
namespace {

volatile std::sig_atomic_t pending = 0;

void on_signal(int signal) {
  if (pending) {  // the second one: stop now, as the user asked twice
    std::signal(signal, SIG_DFL);
    std::raise(signal);
    return;
  }
  pending = signal;
}

}  // namespace

namespace {
std::string signal_name(int signal) {
  if (signal == SIGINT) return "SIGINT (Ctrl-C)";
  if (signal == SIGTERM) return "SIGTERM";
  if (signal == SIGHUP) return "SIGHUP";
  return "signal " + std::to_string(signal);
}
}  // namespace

Interrupted::Interrupted(int signal, const std::string& where)
    : Error("interrupted by " + signal_name(signal) + (where.empty() ? "" : " " + where)),
      signal_(signal) {}

void install_interrupt_handlers() {
  struct sigaction action {};
  action.sa_handler = on_signal;
  sigemptyset(&action.sa_mask);
  for (int s : {SIGINT, SIGTERM, SIGHUP}) sigaction(s, &action, nullptr);
}

namespace {

struct sigaction embedder_sigint {};
int scope_depth = 0;  // the embedder's thread only

// In a scope: the first SIGINT asks the work to stop; later ones change nothing.
void on_scoped_signal(int signal) {
  if (!pending) pending = signal;
}

}  // namespace

InterruptScope::InterruptScope() : outermost_(scope_depth++ == 0) {
  if (!outermost_) return;
  pending = 0;
  struct sigaction action {};
  action.sa_handler = on_scoped_signal;
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, &embedder_sigint);
}

InterruptScope::~InterruptScope() {
  --scope_depth;
  if (!outermost_) return;
  sigaction(SIGINT, &embedder_sigint, nullptr);
  pending = 0;
}

int InterruptScope::signal() const {
  return pending;
}

int interrupt_signal() {
  return pending;
}

void throw_if_interrupted() {
  if (pending) throw Interrupted(pending);
}

}  // namespace linebake
