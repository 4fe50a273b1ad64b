#include "core/progress.hpp"

#include <unistd.h>

#include <cstdio>

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

bool TerminalProgress::enabled() {
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
