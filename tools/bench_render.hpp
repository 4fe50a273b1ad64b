#pragma once
// `linebake bench render`: the techniques of the registry timed and compared on caches.

#include <limits>
#include <string>
#include <vector>

namespace linebake::cli {

struct BenchRenderArgs {
  std::vector<std::string> caches;
  std::vector<std::string> techniques;  // empty: every technique of the registry
  std::vector<std::string> transfer_functions{"semi"};
  int frames = 8;
  int warm_up = 1;  // frames rendered before the flight's, not counted
  std::string size = "1920x1080", device;
  // Per technique and transfer function: stop after the frame past it (0: after the first).
  double max_seconds = std::numeric_limits<double>::infinity();
  std::string memory_budget;       // as render's: "" (half of physical memory), "8G", "unlimited"
  bool early_termination = false;  // as render's: embree, ll, rtx, tiles (never reference)
  bool every_hit = false;          // embree, reference: every hit of every ray, no interval walk
  bool json = false;
};

void bench_render(const BenchRenderArgs& args);

}  // namespace linebake::cli
