#pragma once
// `linebake bench isolation`: what reading foreign HDF5 files in an isolated child costs
// (docs/reliability.md), against reading their data, and the alternative of reading the data in
// the child too and handing it over in shared memory.

#include <cstdint>
#include <string>
#include <vector>

namespace linebake::cli {

struct BenchIsolationArgs {
  std::vector<std::string> files;
  int repeat = 3;
  std::string resident = "0";  // touched before measuring: fork's cost grows with the parent's
  bool json = false;
};

void bench_isolation(const BenchIsolationArgs& args);

}  // namespace linebake::cli
