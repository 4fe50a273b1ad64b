#pragma once
// `linebake bench shaders`: what a Vulkan driver's compiler makes of the embedded compute shaders
// (registers, spills, scratch, occupancy, as the driver names them), compiled without rendering:
// on a GPU, or on RADV's null device for an AMD GPU that is not there (docs/cli.md).

#include <string>
#include <vector>

namespace linebake::cli {

struct BenchShadersArgs {
  std::vector<std::string> shaders;     // substrings of the names; empty: every compute shader
  std::vector<std::string> statistics;  // substrings of the driver's statistic names; empty: all
  std::string device;
  bool json = false;
};

void bench_shaders(const BenchShadersArgs& args);

}  // namespace linebake::cli
