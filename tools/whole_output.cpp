#include "whole_output.hpp"

#include <algorithm>

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

uint64_t WholeOutput::batch_points(const LineSet& header, uint64_t most) const {
  const uint64_t per_point = 12 + 4 * header.attributes.size() + 8;
  const uint64_t left = total_ == 0 ? UINT64_MAX : (total_ > before_ ? total_ - before_ : 0);
  return std::clamp<uint64_t>(left / 16 / per_point, 4096, std::max<uint64_t>(most, 4096));
}

void WholeOutput::check_resident(const std::string& where) const {
  const uint64_t peak = peak_rss_bytes();
  if (total_ == 0 || peak <= total_) return;
  throw BudgetExceeded(where + ": the process's resident memory reached " + format_bytes(peak) +
                       ", more than the memory budget of " + format_bytes(total_) + " (it held " +
                       format_bytes(before_) + " before the first batch); raise --memory-budget");
}

}  // namespace linebake::cli
