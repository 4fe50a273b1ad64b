#pragma once
// Build figures as the paper's Table 1 reports them: wall time, CPU time and peak memory of one
// step. Peak memory is the process's resident high-water mark (VmHWM), reset at the start of the
// step where the kernel allows it (/proc/self/clear_refs), so it is the step's own peak plus
// whatever the process already held.

#include <chrono>
#include <cstdint>
#include <string>
#include <vector>

namespace linebake {

struct StepFigures {
  double wall_s = 0;
  double cpu_s = 0;                 // user + system, all threads
  uint64_t rss_before = 0;          // resident bytes when the step started
  uint64_t peak_rss = 0;            // resident high-water mark during the step
  bool peak_is_step_local = false;  // false: the kernel refused the reset, peak is since start
  // Steps built in the same passes over the data (a bake builds its assets from the same
  // batches): the peak is those passes', and tubes and voxels, built side by side, overlap in
  // wall and CPU time. Empty: the step's figures are its own.
  std::vector<std::string> built_with;
};

class StepMeter {
 public:
  StepMeter();  // starts measuring
  StepFigures stop() const;

 private:
  std::chrono::steady_clock::time_point wall_start_;
  double cpu_start_ = 0;
  uint64_t rss_before_ = 0;
  bool reset_ok_ = false;
};

// Wall seconds since `start` on the steady clock.
inline double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

uint64_t current_rss_bytes();
// The process's address space (VmSize): what an address-space limit (ulimit -v) counts.
uint64_t address_space_bytes();
// Gives the C library's free heap memory back to the system (malloc_trim): freed memory the
// allocator keeps (above all under a high M_TRIM_THRESHOLD, as linebake-mpi sets) stays resident.
void trim_free_heap();
// trim_free_heap(), and the resident size then: memory freed by the process (lavapipe's device
// memory comes from malloc) can stay resident in the heap, which a budget of resident memory must
// not count as held.
uint64_t trimmed_rss_bytes();
uint64_t peak_rss_bytes();
double process_cpu_seconds();

}  // namespace linebake
