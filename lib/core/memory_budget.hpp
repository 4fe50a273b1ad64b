#pragma once
// Memory as a budget: the most resident memory a command may use, the process's own included.
// Stages size their batches and buffers from what the budget leaves, and refuse work that cannot
// fit with the figures, instead of being killed by the kernel.

#include <cstdint>
#include <string>

namespace linebake {

// "2G", "1.5GiB", "2Gi", "512M", "64k", "4096", "1e9": a decimal number and a binary unit (K, M,
// G, T = 2^10, 2^20, 2^30, 2^40, with or without "B", "i" or "iB"; any case). Throws Error on
// anything else: spaces, a sign, hexadecimal.
uint64_t parse_size(const std::string& text);
// "1.50 GiB", "512.00 MiB", "17 B": binary units, two decimals.
std::string format_bytes(uint64_t bytes);
// Physical memory of the machine, or what the kernel lets this process have when that is smaller:
// its cgroups' memory limits (cgroup_memory_limit) and its address-space limit (ulimit -v).
uint64_t physical_memory_bytes();
// The smallest memory limit of the cgroups listed in `proc_self_cgroup` (the text of
// /proc/self/cgroup), v2 (memory.max) and v1 (memory.limit_in_bytes), each cgroup's and every
// one's above it, under `root` (/sys/fs/cgroup); 0 when there is none.
uint64_t cgroup_memory_limit(const std::string& proc_self_cgroup, const std::string& root);
// What the address-space limit (ulimit -v) leaves this process, UINT64_MAX without one. Drivers
// reserve address space far beyond what they touch (lavapipe: a malloc arena and a stack for
// each of its threads), which only this limit, not the memory budget, sees.
uint64_t address_space_left();
// The default budget: half of physical_memory_bytes().
uint64_t default_memory_budget();

// What a budget of 0 bytes is told (a usage error wherever a budget is given: `unlimited` is the
// word for none).
inline constexpr const char* kZeroBudget =
    "a memory budget of 0 bytes leaves no room for any work: give a size, or unlimited for none";

class MemoryBudget {
 public:
  // `total`: the process's whole budget; 0 means unlimited. What the process already holds when
  // the budget starts is counted as used.
  explicit MemoryBudget(uint64_t total);

  bool unlimited() const { return total_ == 0; }
  uint64_t total() const { return total_; }
  uint64_t baseline() const { return baseline_; }  // resident bytes when the budget started
  uint64_t reserved() const { return reserved_; }
  // What is left for work: total less the baseline and the reservations (UINT64_MAX when
  // unlimited).
  uint64_t available() const;
  // Takes `bytes` for `what`; throws BudgetExceeded naming `what`, the bytes and the budget.
  void reserve(uint64_t bytes, const std::string& what);
  void release(uint64_t bytes);

 private:
  uint64_t total_ = 0, baseline_ = 0, reserved_ = 0;
};

}  // namespace linebake
