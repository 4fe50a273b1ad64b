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

int interrupt_signal() {
  return pending;
}

void throw_if_interrupted() {
  if (pending) throw Interrupted(pending);
}

}  // namespace linebake
