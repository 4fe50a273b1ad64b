#include "core/measure.hpp"

#include <malloc.h>
#include <sys/resource.h>

#include <fstream>
#include <string>

namespace linebake {
namespace {

// A field of /proc/self/status in kB, as bytes.
uint64_t status_field(const char* name) {
  std::ifstream in("/proc/self/status");
  std::string line;
  const std::string prefix = std::string(name) + ":";
  while (std::getline(in, line)) {
    if (line.compare(0, prefix.size(), prefix) == 0)
      return std::stoull(line.substr(prefix.size())) * 1024;
  }
  return 0;
}

}  // namespace

uint64_t current_rss_bytes() {
  return status_field("VmRSS");
}
uint64_t address_space_bytes() {
  return status_field("VmSize");
}
void trim_free_heap() {
#ifdef __GLIBC__
  malloc_trim(0);
#endif
}
uint64_t trimmed_rss_bytes() {
  trim_free_heap();
  return current_rss_bytes();
}
uint64_t peak_rss_bytes() {
  return status_field("VmHWM");
}

double process_cpu_seconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  const auto seconds = [](timeval t) { return double(t.tv_sec) + double(t.tv_usec) * 1e-6; };
  return seconds(usage.ru_utime) + seconds(usage.ru_stime);
}

StepMeter::StepMeter() {
  // Writing 5 resets the high-water mark to the current resident size (Linux >= 4.0).
  std::ofstream clear("/proc/self/clear_refs");
  reset_ok_ = bool(clear << "5" << std::flush);
  rss_before_ = current_rss_bytes();
  cpu_start_ = process_cpu_seconds();
  wall_start_ = std::chrono::steady_clock::now();
}

StepFigures StepMeter::stop() const {
  StepFigures f;
  f.wall_s = seconds_since(wall_start_);
  f.cpu_s = process_cpu_seconds() - cpu_start_;
  f.rss_before = rss_before_;
  f.peak_rss = peak_rss_bytes();
  f.peak_is_step_local = reset_ok_;
  return f;
}

}  // namespace linebake
