#include "core/progress.hpp"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace linebake {

TerminalProgress::TerminalProgress(std::string label)
    : label_(std::move(label)), active_(enabled()) {}

TerminalProgress::~TerminalProgress() {
  finish();
}

void TerminalProgress::finish() {
  if (drawn_) std::fprintf(stderr, "\r\033[K");
  drawn_ = false;
  active_ = false;
}

// LINEBAKE_PROGRESS=always draws on stderr whatever it is, =never never; otherwise when stderr is
// a terminal. Under mpirun a rank's stderr is a pipe whatever mpirun's is (and its stdout a pty
// even when mpirun's is a file), so a rank cannot tell: `mpirun -x LINEBAKE_PROGRESS=always`
// asks for rank 0's bars.
bool TerminalProgress::enabled() {
  if (const char* setting = std::getenv("LINEBAKE_PROGRESS")) {
    if (std::strcmp(setting, "always") == 0) return true;
    if (std::strcmp(setting, "never") == 0) return false;
  }
  return ::isatty(STDERR_FILENO) == 1;
}

void TerminalProgress::update(uint64_t done, uint64_t total) {
  if (!active_) return;
  const auto now = std::chrono::steady_clock::now();
  if (drawn_ && now - last_ < std::chrono::milliseconds(100) && done != total) return;
  last_ = now;
  drawn_ = true;
  if (total > 0) {
    const double fraction = static_cast<double>(done) / static_cast<double>(total);
    const int width = 30;
    const int filled = static_cast<int>(fraction * width);
    std::fprintf(stderr, "\r%s [%.*s%*s] %5.1f%%", label_.c_str(), filled,
                 "##############################", width - filled, "", 100.0 * fraction);
  } else {
    std::fprintf(stderr, "\r%s %llu", label_.c_str(), static_cast<unsigned long long>(done));
  }
  std::fflush(stderr);
}

ProgressFn TerminalProgress::callback() {
  if (!active_) return {};
  return [this](uint64_t done, uint64_t total) { update(done, total); };
}

}  // namespace linebake
