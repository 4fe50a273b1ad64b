#include "core/memory_budget.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>

#include "core/error.hpp"
#include "core/measure.hpp"

namespace linebake {

uint64_t parse_size(const std::string& text) {
  // A decimal number as written (digits, a fraction, an exponent), then the unit: std::stod had
  // also taken leading spaces, a sign and hexadecimal ("0x100M" was 256 MiB).
  double value = 0;
  const char* const last = text.data() + text.size();
  const char* end = text.data();
  bool out_of_range = false;
  if (!text.empty() && (std::isdigit(static_cast<unsigned char>(text[0])) || text[0] == '.')) {
    const auto parsed = std::from_chars(text.data(), last, value, std::chars_format::general);
    if (parsed.ec == std::errc() || parsed.ec == std::errc::result_out_of_range) end = parsed.ptr;
    out_of_range = parsed.ec == std::errc::result_out_of_range;
  }
  std::string unit(end, last);
  for (char& c : unit) c = char(std::toupper(static_cast<unsigned char>(c)));
  int shift = -1;
  if (unit.empty() || unit == "B") shift = 0;
  const char* prefixes = "KMGT";
  for (int i = 0; i < 4; ++i) {
    const std::string p(1, prefixes[i]);
    if (unit == p || unit == p + "B" || unit == p + "I" || unit == p + "IB") shift = 10 * (i + 1);
  }
  if (end == text.data() || shift < 0 || !std::isfinite(value))
    throw Error("bad size '" + text +
                "' (expected a number of bytes, or one with the binary unit K, M, G or T, "
                "as 512M, 1.5GiB or 2Gi)");
  const double bytes = value * std::ldexp(1.0, shift);
  // Below 2^64 a double rounds to a whole number that uint64_t holds (llround's long long did
  // not hold 2^63 to 2^64).
  if (out_of_range || !(bytes < 0x1p64)) throw Error("size '" + text + "' is too large");
  return uint64_t(std::round(bytes));
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

namespace {

// A limit file's value: bytes, or 0 for none ("max" in v2; v1 writes "no limit" as about 2^63).
uint64_t limit_in(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::string text;
  if (!(in >> text) || text == "max") return 0;
  try {
    const uint64_t bytes = std::stoull(text);
    return bytes >= (uint64_t{1} << 62) ? 0 : bytes;
  } catch (const std::exception&) {
    return 0;
  }
}

// The smallest limit in `file_name` of `path`'s directory under `mount` and of each directory
// above it, up to the mount (a parent's limit binds its children; inside a container the mount
// is the container's own cgroup, and `path` may not exist under it).
uint64_t smallest_limit(const std::filesystem::path& mount, const std::string& path,
                        const char* file_name) {
  uint64_t smallest = 0;
  std::filesystem::path relative = std::filesystem::path(path).relative_path();
  while (true) {
    const uint64_t bytes = limit_in(mount / relative / file_name);
    if (bytes > 0 && (smallest == 0 || bytes < smallest)) smallest = bytes;
    if (relative.empty()) break;
    relative = relative.parent_path();
  }
  return smallest;
}

}  // namespace

uint64_t cgroup_memory_limit(const std::string& proc_self_cgroup, const std::string& root) {
  uint64_t smallest = 0;
  const auto take = [&](uint64_t bytes) {
    if (bytes > 0 && (smallest == 0 || bytes < smallest)) smallest = bytes;
  };
  std::istringstream lines(proc_self_cgroup);
  std::string line;
  while (std::getline(lines, line)) {
    // "hierarchy-ID:controller-list:cgroup-path" (cgroups(7)); v2's line is "0::path".
    const size_t first = line.find(':'), second = line.find(':', first + 1);
    if (first == std::string::npos || second == std::string::npos) continue;
    const std::string controllers = line.substr(first + 1, second - first - 1);
    const std::string path = line.substr(second + 1);
    if (line.compare(0, first, "0") == 0 && controllers.empty()) {
      // v2, mounted at the root, or at unified/ beside v1's hierarchies (hybrid).
      take(smallest_limit(root, path, "memory.max"));
      take(smallest_limit(std::filesystem::path(root) / "unified", path, "memory.max"));
    } else if (("," + controllers + ",").find(",memory,") != std::string::npos) {
      take(smallest_limit(std::filesystem::path(root) / "memory", path, "memory.limit_in_bytes"));
    }
  }
  return smallest;
}

uint64_t physical_memory_bytes() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGE_SIZE);
  uint64_t bytes = pages > 0 && page > 0 ? uint64_t(pages) * uint64_t(page) : 0;
  const auto take = [&](uint64_t limit) {
    if (limit > 0 && (bytes == 0 || limit < bytes)) bytes = limit;
  };
  // What the kernel enforces on this process: its cgroups' memory limits (containers, batch
  // schedulers: Slurm's --mem), v1 or v2, and its address-space limit (ulimit -v).
  std::ifstream self("/proc/self/cgroup");
  const std::string cgroups((std::istreambuf_iterator<char>(self)),
                            std::istreambuf_iterator<char>());
  take(cgroup_memory_limit(cgroups, "/sys/fs/cgroup"));
  rlimit address_space{};
  if (::getrlimit(RLIMIT_AS, &address_space) == 0 && address_space.rlim_cur != RLIM_INFINITY)
    take(uint64_t(address_space.rlim_cur));
  return bytes;
}

uint64_t address_space_left() {
  rlimit address_space{};
  if (::getrlimit(RLIMIT_AS, &address_space) != 0 || address_space.rlim_cur == RLIM_INFINITY)
    return UINT64_MAX;
  const uint64_t used = address_space_bytes();
  return used < address_space.rlim_cur ? uint64_t(address_space.rlim_cur) - used : 0;
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
