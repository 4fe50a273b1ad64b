// The default memory budget follows what the kernel enforces: cgroup v2 and v1 memory limits,
// nested, read from a hand-built cgroup tree.

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <utility>

#include "core/memory_budget.hpp"
#include "test_util.hpp"

using namespace linebake;
using linebake::test::TempDir;

namespace {

void write_limit(const std::string& path, const std::string& value) {
  std::filesystem::create_directories(std::filesystem::path(path).parent_path());
  std::ofstream(path) << value << "\n";
}

}  // namespace

// v2 (Slurm's job cgroup above its step's): the smallest limit on the way up binds.
TEST(MemoryBudget, CgroupV2LimitsBindFromAnyLevelAbove) {
  TempDir dir;
  const std::string root = dir.file("cg");
  write_limit(root + "/memory.max", "max");
  write_limit(root + "/slurm/job_7/memory.max", "8589934592");
  write_limit(root + "/slurm/job_7/step_0/memory.max", "max");
  EXPECT_EQ(cgroup_memory_limit("0::/slurm/job_7/step_0\n", root), uint64_t{8} << 30);
  write_limit(root + "/slurm/job_7/step_0/memory.max", "1073741824");
  EXPECT_EQ(cgroup_memory_limit("0::/slurm/job_7/step_0\n", root), uint64_t{1} << 30);
  // Inside a container the path names the host's cgroup, which is not under the mount: the
  // mount's own (the container's cgroup) still counts.
  write_limit(root + "/memory.max", "2147483648");
  EXPECT_EQ(cgroup_memory_limit("0::/docker/abc\n", root), uint64_t{2} << 30);
}

// v1 (this development VM's kind): the memory controller's hierarchy, "no limit" as about 2^63;
// a hybrid mount's v2 unified/ tree counts too; lines of other controllers do not.
TEST(MemoryBudget, CgroupV1AndHybridLimits) {
  TempDir dir;
  const std::string root = dir.file("cg");
  const std::string self =
      "9:name=systemd:/\n4:memory:/process_api/f2e2\n3:cpuset:/\n1:cpu:/\n0::/\n";
  write_limit(root + "/memory/memory.limit_in_bytes", "9223372036854771712");
  write_limit(root + "/memory/process_api/f2e2/memory.limit_in_bytes", "9223372036854771712");
  EXPECT_EQ(cgroup_memory_limit(self, root), 0u);
  write_limit(root + "/memory/process_api/memory.limit_in_bytes", "4294967296");
  EXPECT_EQ(cgroup_memory_limit(self, root), uint64_t{4} << 30);
  write_limit(root + "/cpuset/memory.limit_in_bytes", "1024");  // not the memory controller's
  write_limit(root + "/unified/memory.max", "3221225472");
  EXPECT_EQ(cgroup_memory_limit(self, root), uint64_t{3} << 30);
  EXPECT_EQ(cgroup_memory_limit("", root), 0u);
  EXPECT_EQ(cgroup_memory_limit("4:memory:/x\n", dir.file("none")), 0u);
}

// The default is half of what physical_memory_bytes() finds, which is never more than the
// machine's memory.
TEST(MemoryBudget, TheDefaultIsHalfOfWhatTheProcessMayHave) {
  EXPECT_EQ(default_memory_budget(), physical_memory_bytes() / 2);
  EXPECT_GT(physical_memory_bytes(), 0u);
}

// Sizes as users write them, with the bytes worked out by hand; what std::stod had also taken
// (spaces, signs, hexadecimal: "0x100M" was 256 MiB) and Kubernetes' "Gi" it had refused.
TEST(MemoryBudget, SizesAreDecimalNumbersWithBinaryUnits) {
  const std::pair<const char*, uint64_t> sizes[] = {
      {"4096", 4096},
      {"4096B", 4096},
      {"64k", 65536},
      {"512M", 536870912},
      {"512MB", 536870912},
      {"1.5GiB", 1610612736},
      {"2Gi", 2147483648},
      {"2gib", 2147483648},
      {"1T", 1099511627776},
      {".5K", 512},
      {"1e9", 1000000000},
      {"0", 0},
      {"1e19", 10000000000000000000u}};  // past 2^63, which llround had not held
  for (const auto& [text, bytes] : sizes) EXPECT_EQ(parse_size(text), bytes) << text;
  for (const char* text : {"", "G", " 2", "2 ", "+2", "-1", "0x10", "0x100M", "1e", "2GG", "2P",
                           "inf", "nan", "1,5G", "2 G", "1e400"}) {
    try {
      parse_size(text);
      ADD_FAILURE() << "'" << text << "' was taken";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(std::string("'") + text + "'"), std::string::npos)
          << e.what();
    }
  }
  EXPECT_THROW(parse_size("16777216T"), Error);  // 2^64 bytes
}
