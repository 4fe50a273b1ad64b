#include "whole_output.hpp"

#include "core/error.hpp"
#include "core/measure.hpp"

namespace linebake::cli {

uint64_t memory_budget_bytes(const std::string& option) {
  if (option == "unlimited") return 0;
  if (option.empty()) return default_memory_budget();
  const uint64_t bytes = parse_size(option);
  if (bytes == 0) throw UsageError(kZeroBudget);
  return bytes;
}

// Measured on convection at scale 0.2 (2 million segments) on the development VM: vtp's
// compressed blocks and their encoding 3.4 times the lines, vtk 1.6, obj, csv and h5 1.1.
static double writing_overhead(Format format) {
  switch (format) {
    case Format::binlines:
      return 0;
    case Format::vtp:
      return 3.5;
    case Format::vtk:
      return 1.75;
    default:
      return 1.25;
  }
}

WholeOutput::WholeOutput(const std::string& budget_option, Format output)
    : total_(memory_budget_bytes(budget_option)),
      before_(trimmed_rss_bytes()),
      streams_(output == Format::binlines),  // open_line_writer's
      writing_(writing_overhead(output)) {}

void WholeOutput::check(uint64_t held, uint64_t points, double overhead, const std::string& where,
                        const std::string& why, const std::string& advice) const {
  const uint64_t needed = held + uint64_t(double(held) * overhead);
  if (total_ == 0 || before_ + needed <= total_) return;
  throw BudgetExceeded(
      where + ": " + why + " " + std::to_string(points) + " points take " + format_bytes(held) +
      (overhead > 0 ? ", about " + format_bytes(needed) + " with writing them" : std::string()) +
      ", more than the memory budget of " + format_bytes(total_) + " leaves (" +
      format_bytes(total_ > before_ ? total_ - before_ : 0) + "); " + advice +
      ", or raise --memory-budget");
}

}  // namespace linebake::cli
