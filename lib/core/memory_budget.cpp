#include "core/memory_budget.hpp"

#include <unistd.h>

#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>

#include "core/error.hpp"
#include "core/measure.hpp"

namespace linebake {

uint64_t parse_size(const std::string& text) {
  size_t end = 0;
  double value = 0;
  try {
    value = std::stod(text, &end);
  } catch (const std::exception&) {
    end = 0;
  }
  std::string unit = text.substr(end);
  for (char& c : unit) c = char(std::toupper(static_cast<unsigned char>(c)));
  int shift = -1;
  if (unit.empty() || unit == "B") shift = 0;
  const char* prefixes = "KMGT";
  for (int i = 0; i < 4; ++i) {
    const std::string p(1, prefixes[i]);
    if (unit == p || unit == p + "B" || unit == p + "IB") shift = 10 * (i + 1);
  }
  if (end == 0 || shift < 0 || !(value >= 0) || !std::isfinite(value))
    throw Error("bad size '" + text + "' (expected bytes, or a number with K, M, G or T)");
  const double bytes = value * std::ldexp(1.0, shift);
  if (bytes > 1.8e19) throw Error("size '" + text + "' is too large");
  return uint64_t(std::llround(bytes));
}

std::string format_bytes(uint64_t bytes) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  double value = double(bytes);
  int unit = 0;
  while (value >= 1024 && unit < 4) value /= 1024, ++unit;
  char text[32];
  std::snprintf(text, sizeof text, unit == 0 ? "%.0f %s" : "%.2f %s", value, units[unit]);
  return text;
}

uint64_t physical_memory_bytes() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGE_SIZE);
  uint64_t bytes = pages > 0 && page > 0 ? uint64_t(pages) * uint64_t(page) : 0;
  // A cgroup v2 limit (containers, batch schedulers) is what the kernel enforces.
  std::ifstream limit("/sys/fs/cgroup/memory.max");
  std::string text;
  if (limit >> text && text != "max") {
    try {
      const uint64_t cgroup = std::stoull(text);
      if (cgroup > 0 && (bytes == 0 || cgroup < bytes)) bytes = cgroup;
    } catch (const std::exception&) {
    }
  }
  return bytes;
}

uint64_t default_memory_budget() {
  return physical_memory_bytes() / 2;
}

MemoryBudget::MemoryBudget(uint64_t total) : total_(total), baseline_(current_rss_bytes()) {}

uint64_t MemoryBudget::available() const {
  if (unlimited()) return UINT64_MAX;
  const uint64_t used = baseline_ + reserved_;
  return used < total_ ? total_ - used : 0;
}

void MemoryBudget::reserve(uint64_t bytes, const std::string& what) {
  if (!unlimited() && bytes > available())
    throw BudgetExceeded(what + " needs about " + format_bytes(bytes) + ", more than the " +
                         format_bytes(available()) + " the memory budget of " +
                         format_bytes(total_) + " leaves (the process held " +
                         format_bytes(baseline_) + " at the start, the work's other buffers take " +
                         format_bytes(reserved_) + "); raise --memory-budget or ask for less");
  reserved_ += bytes;
}

void MemoryBudget::release(uint64_t bytes) {
  reserved_ -= std::min(bytes, reserved_);
}

}  // namespace linebake
