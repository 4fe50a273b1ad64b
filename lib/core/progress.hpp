#pragma once
// Progress reporting. The library reports through a plain callback; the terminal bar is one
// implementation of it that draws only when stderr is a terminal.

#include <chrono>
#include <cstdint>
#include <functional>
#include <string>

namespace linebake {

// done/total in the unit the caller chose (bytes read, lines generated). total may be 0: unknown.
using ProgressFn = std::function<void(uint64_t done, uint64_t total)>;

class TerminalProgress {
 public:
  explicit TerminalProgress(std::string label);
  ~TerminalProgress();
  void update(uint64_t done, uint64_t total);
  // Erases the bar now (the destructor does otherwise), so a result line can follow it.
  void finish();
  ProgressFn callback();
  static bool enabled();  // stderr is a TTY

 private:
  std::string label_;
  bool active_;
  bool drawn_ = false;
  std::chrono::steady_clock::time_point last_{};
};

}  // namespace linebake
