#include "core/interrupt.hpp"

#include <atomic>
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
int scope_depth = 0;  // the embedder's signal thread only
volatile std::sig_atomic_t scoped_pending = 0;
std::atomic<int> embedded_calls{0};

// In a scope: the first SIGINT asks the work to stop; later ones change nothing.
void on_scoped_signal(int signal) {
  if (!scoped_pending) scoped_pending = signal;
}

}  // namespace

EmbeddedCall::EmbeddedCall() {
  ++embedded_calls;
}

EmbeddedCall::~EmbeddedCall() {
  --embedded_calls;
}

InterruptScope::InterruptScope() : outermost_(scope_depth++ == 0) {
  if (!outermost_) return;
  scoped_pending = 0;
  struct sigaction action {};
  action.sa_handler = on_scoped_signal;
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, &embedder_sigint);
}

int InterruptScope::finish() {
  if (finished_) return 0;
  finished_ = true;
  --scope_depth;
  if (!outermost_) return 0;
  sigaction(SIGINT, &embedder_sigint, nullptr);  // first: a later SIGINT is the program's
  const int signal = scoped_pending;
  scoped_pending = 0;
  return signal;
}

InterruptScope::~InterruptScope() {
  finish();
}

int interrupt_signal() {
  if (pending) return pending;
  // A scope's SIGINT is for its call: only when no other call could see it.
  if (scoped_pending && embedded_calls.load() <= 1) return scoped_pending;
  return 0;
}

void throw_if_interrupted() {
  if (const int signal = interrupt_signal()) throw Interrupted(signal);
}

}  // namespace linebake
