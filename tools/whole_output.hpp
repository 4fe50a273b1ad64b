#pragma once
// What `convert` and `synth` share about memory: a .binlines output is written as the batches
// come; the other formats collect the line set and write it at the end, which holds the lines
// and, at the write's peak, a multiple of them more. Both are held within --memory-budget.

#include <cstdint>
#include <string>

#include "core/memory_budget.hpp"
#include "formats/registry.hpp"

namespace linebake::cli {

// The process's budget from a --memory-budget option: "" is half of physical memory, "unlimited"
// none (a MemoryBudget of 0); a size of 0 is a UsageError (no room for any work).
uint64_t memory_budget_bytes(const std::string& option);

class WholeOutput {
 public:
  // What the process holds now is what it holds besides the lines.
  WholeOutput(const std::string& budget_option, Format output);
  bool streams() const { return streams_; }
  // What writing a format whole takes besides the lines it holds, as a multiple of their bytes
  // (0 for .binlines).
  double writing() const { return writing_; }
  // Throws BudgetExceeded ("WHERE: WHY N points take X, about Y with writing them, more than the
  // memory budget of B leaves (L); ADVICE, or raise --memory-budget") when `held` bytes of lines
  // and `overhead` times them more do not fit what the budget left.
  void check(uint64_t held, uint64_t points, double overhead, const std::string& where,
             const std::string& why, const std::string& advice) const;
  // For a .binlines output, written as the batches come: points a batch of `header`'s lines may
  // hold, a sixteenth of what the budget left over a point's bytes, from 4,096 to `most`.
  uint64_t batch_points(const LineSet& header, uint64_t most) const;
  // After a batch: throws BudgetExceeded naming `where` when the process's resident high-water
  // mark has passed the budget (the reader's or generator's own buffers are not estimated).
  void check_resident(const std::string& where) const;

 private:
  uint64_t total_ = 0, before_ = 0;
  bool streams_ = false;
  double writing_ = 0;
};

}  // namespace linebake::cli
