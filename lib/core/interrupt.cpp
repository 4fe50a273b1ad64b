#include "core/interrupt.hpp"

#include <atomic>
#include <csignal>
#include <cstring>
#include <ctime>

namespace linebake {
namespace {

volatile std::sig_atomic_t pending = 0;
volatile std::sig_atomic_t first_sender = 0;  // the first signal's sending process, 0: the kernel's
struct timespec first_at {};

// Whether `now` is within a second of the first signal.
bool soon_after_first(const struct timespec& now) {
  const long long ns =
      (now.tv_sec - first_at.tv_sec) * 1000000000LL + (now.tv_nsec - first_at.tv_nsec);
  return ns >= 0 && ns < 1000000000LL;
}

void on_signal(int signal, siginfo_t* info, void*) {
  struct timespec now {};
  ::clock_gettime(CLOCK_MONOTONIC, &now);  // async-signal-safe (POSIX)
  const bool sent = info != nullptr && info->si_code == SI_USER && info->si_pid > 0;
  if (pending) {
    // coreutils' timeout signals the command and then its process group, so one request can come
    // twice from one process at once: that copy changes nothing.
    if (sent && signal == pending && info->si_pid == first_sender && soon_after_first(now)) return;
    // The second one: stop now, as the user asked twice.
    std::signal(signal, SIG_DFL);
    std::raise(signal);
    return;
  }
  first_sender = sent ? info->si_pid : 0;
  first_at = now;
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
  action.sa_sigaction = on_signal;
  action.sa_flags = SA_SIGINFO;
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
