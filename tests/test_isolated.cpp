// The isolated runner (core/isolated.hpp) and the HDF5 metadata walk (core/h5_probe.hpp): what a
// crash, a hang, an allocation past the cap and a clean result in the child give the parent.

#include <fcntl.h>
#include <gtest/gtest.h>
#include <hdf5.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdlib>
#include <fstream>
#include <new>
#include <stdexcept>
#include <vector>

#include "core/error.hpp"
#include "core/h5.hpp"
#include "core/h5_probe.hpp"
#include "core/interrupt.hpp"
#include "core/isolated.hpp"
#include "formats/registry.hpp"
#include "lines/line_set.hpp"
#include "test_util.hpp"

using namespace linebake;
using linebake::test::read_text;
using linebake::test::TempDir;
using linebake::test::write_text;
using Kind = IsolatedOutcome::Kind;

TEST(Isolated, ReturnsTheChildsResult) {
  const IsolatedOutcome o = run_isolated([] { return std::string(100000, 'x') + "end"; });
  ASSERT_EQ(o.kind, Kind::Finished);
  EXPECT_EQ(o.result.size(), 100003u);  // more than one pipe buffer
  EXPECT_EQ(o.result.substr(100000), "end");
}

TEST(Isolated, ASegfaultEndsOnlyTheChild) {
  const IsolatedOutcome o = run_isolated([]() -> std::string {
    std::raise(SIGSEGV);
    return "unreachable";
  });
  ASSERT_EQ(o.kind, Kind::Signal);
  EXPECT_EQ(o.signal, SIGSEGV);
  EXPECT_TRUE(o.contained_crash());
  EXPECT_NE(o.describe({}).find("SIGSEGV"), std::string::npos) << o.describe({});
}

TEST(Isolated, AnAbortIsASignalToo) {
  const IsolatedOutcome o = run_isolated([]() -> std::string { std::abort(); });
  ASSERT_EQ(o.kind, Kind::Signal);
  EXPECT_EQ(o.signal, SIGABRT);
}

TEST(Isolated, AnExceptionIsAFailureWithItsMessage) {
  const IsolatedOutcome o =
      run_isolated([]() -> std::string { throw std::runtime_error("dataset /x: bad"); });
  ASSERT_EQ(o.kind, Kind::Failed);
  EXPECT_EQ(o.result, "dataset /x: bad");
  EXPECT_FALSE(o.contained_crash());
}

TEST(Isolated, AHangIsKilledAtTheTimeLimit) {
  const IsolatedOutcome o = run_isolated(
      []() -> std::string {
        for (;;) pause();
      },
      {0.3, uint64_t{1} << 30});
  ASSERT_EQ(o.kind, Kind::TimedOut);
  EXPECT_GE(o.wall_s, 0.3);
  EXPECT_LT(o.wall_s, 5.0);
}

TEST(Isolated, AllocationPastTheCapIsOutOfMemory) {
  if (!memory_cap_enforced()) GTEST_SKIP() << "no address-space cap under AddressSanitizer";
  // 64 MiB past what the parent maps is refused; 16 MiB is not.
  const IsolationLimits limits{30, uint64_t{64} << 20};
  const IsolatedOutcome big = run_isolated(
      [] {
        std::vector<char> v(size_t{256} << 20, 1);
        return std::to_string(v[12345]);
      },
      limits);
  EXPECT_EQ(big.kind, Kind::OutOfMemory);
  const IsolatedOutcome small = run_isolated(
      [] {
        std::vector<char> v(size_t{16} << 20, 1);
        return std::to_string(v[12345]);
      },
      limits);
  ASSERT_EQ(small.kind, Kind::Finished);
  EXPECT_EQ(small.result, "1");
}

TEST(Isolated, ACrashBecomesAnInputErrorNamingTheFile) {
  const uint64_t before = contained_crashes();
  try {
    check_in_isolation("/data/x.h5", "HDF5", [] { std::raise(SIGBUS); });
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "/data/x.h5");
    const std::string m = e.what();
    EXPECT_NE(m.find("HDF5 library crashed on SIGBUS"), std::string::npos) << m;
    EXPECT_NE(m.find("the file is malformed"), std::string::npos) << m;
  }
  EXPECT_EQ(contained_crashes(), before + 1);
}

// linebake-probe replies as a forked child does: the program runner's own outcomes (a reply,
// a crash, a hang, an exit status) from stand-in programs, then the walks themselves, which
// must give what the same walk gives in a forked child for sound, damaged and foreign files.
TEST(Isolated, TheProgramRunsLikeAForkedChild) {
  IsolationLimits quick;
  quick.seconds = 2;
  // Stand-ins for the program: sh with the handshake as $0, replying on descriptor 3.
  const auto sh = [](const std::string& script) {
    return std::vector<std::string>{"/bin/sh", "-c", script, kIsolatedHandshake};
  };
  const IsolatedOutcome reply = run_isolated_program(sh("printf '%sRhello' \"$0\" >&3"), quick);
  EXPECT_EQ(reply.kind, Kind::Finished);
  EXPECT_EQ(reply.result, "hello");
  const IsolatedOutcome crash =
      run_isolated_program(sh("printf '%s' \"$0\" >&3; kill -SEGV $$"), quick);
  EXPECT_EQ(crash.kind, Kind::Signal);
  EXPECT_EQ(crash.signal, SIGSEGV);
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(run_isolated_program(sh("printf '%s' \"$0\" >&3; sleep 60"), quick).kind,
            Kind::TimedOut);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 10.0);
  const IsolatedOutcome status = run_isolated_program(sh("printf '%s' \"$0\" >&3; exit 3"), quick);
  EXPECT_EQ(status.kind, Kind::Exited);
  EXPECT_EQ(status.exit_code, 3);
  // Ctrl-C reaches the program blocked: it walks on, and this process decides.
  const IsolatedOutcome blocked =
      run_isolated_program(sh("kill -INT $$; printf '%sRstill here' \"$0\" >&3"), quick);
  EXPECT_EQ(blocked.result, "still here");
  // A child that died of SIGINT anyway was stopped by the user, not by the file.
  EXPECT_THROW(run_isolated_program({"/usr/bin/python3", "-c",
                                     "import os, signal, sys\n"
                                     "signal.pthread_sigmask(signal.SIG_UNBLOCK, [signal.SIGINT])\n"
                                     "signal.signal(signal.SIGINT, signal.SIG_DFL)\n"
                                     "os.write(3, sys.argv[1].encode())\n"
                                     "os.kill(os.getpid(), signal.SIGINT)\n",
                                     kIsolatedHandshake},
                                    quick),
               Interrupted);
  // What does not say it is linebake-probe of this version walked nothing: an Error, no verdict
  // on the file (a loader's exit 127, another version's reply).
  for (const std::string& script : {std::string("exit 127"), std::string("printf Rok >&3"),
                                    std::string("printf 'linebake-probe 0.0.0\\nRok' >&3")})
    EXPECT_THROW(run_isolated_program(sh(script), quick), Error) << script;
  EXPECT_THROW(run_isolated_program({"/no/such/program"}, quick), Error);
  // It gets no descriptor of this process but its reply's: an open file here is not open there.
  const int null = ::open("/dev/null", O_RDONLY);
  const int mine = fcntl(null, F_DUPFD, 50);  // without close-on-exec
  ::close(null);
  ASSERT_GE(mine, 50);
  const IsolatedOutcome fds = run_isolated_program(
      sh("printf '%sR' \"$0\" >&3; ls /proc/self/fd | tr '\\n' ' ' >&3"), quick);
  ::close(mine);
  EXPECT_EQ(fds.result.find(" " + std::to_string(mine) + " "), std::string::npos) << fds.result;

  const std::string& program = isolation_program();
  const std::string parent = std::to_string(getpid());
  ASSERT_FALSE(program.empty()) << "linebake-probe is built with the tests";
  TempDir dir;
  LineSet lines;
  for (int i = 0; i < 50; ++i) lines.append_point(float(i), 0, 0);
  lines.end_line();
  write_line_set(lines, dir.file("sound.h5"));
  std::string bytes = read_text(dir.file("sound.h5"));
  write_text(dir.file("short.h5"), bytes.substr(0, bytes.size() / 2));
  // Damaged B-trees: a node type that is neither a group's nor a chunk index's.
  for (size_t at = bytes.find("TREE"); at != std::string::npos; at = bytes.find("TREE", at + 1))
    bytes[at + 4] = 5;
  write_text(dir.file("damaged.h5"), bytes);
  write_text(dir.file("text.h5"), "not HDF5\n");
  for (const char* name : {"sound.h5", "short.h5", "damaged.h5", "text.h5", "missing.h5"}) {
    const std::string path = dir.file(name);
    const IsolatedOutcome forked = run_isolated([&] {
      h5::walk_metadata(path, {"/"});
      return std::string("ok");
    });
    const IsolatedOutcome spawned =
        run_isolated_program({program, std::to_string(IsolationLimits{}.memory_bytes), "120",
                              parent, "hdf5", path, "/"});
    EXPECT_EQ(spawned.kind, forked.kind) << name;
    EXPECT_EQ(spawned.result, forked.result) << name;
    EXPECT_EQ(spawned.signal, forked.signal) << name;
  }
  EXPECT_EQ(
      run_isolated_program({program, "1073741824", "120", parent, "hdf5", dir.file("sound.h5")})
          .kind,
      Kind::Finished);
  // A program started for a parent that is not this process's (gone, its pid reused) stops.
  EXPECT_THROW(
      run_isolated_program({program, "1073741824", "120", "1", "hdf5", dir.file("sound.h5")}),
      Error);
}

// The child's end is seen when it exits, even where another process holds the reply's write
// end open (forked by another thread of the parent, or, here, by the child itself): end of file
// never comes, and the wait used to run to the time limit.
TEST(Isolated, AChildsEndIsSeenWhileAnotherProcessHoldsItsPipe) {
  IsolationLimits limits;
  limits.seconds = 20;
  const auto start = std::chrono::steady_clock::now();
  const IsolatedOutcome o = run_isolated(
      [] {
        const pid_t holder = fork();  // keeps the pipe's write end open after the child exits
        if (holder == 0) {
          sleep(60);
          _exit(0);
        }
        return std::to_string(holder);
      },
      limits);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_EQ(o.kind, Kind::Finished);
  kill(pid_t(std::stoi(o.result)), SIGKILL);
  EXPECT_LT(seconds, 5.0);
}

TEST(Isolated, OffRunsNothing) {
  setenv("LINEBAKE_ISOLATION", "off", 1);
  EXPECT_NO_THROW(check_in_isolation("x.h5", "HDF5", [] { std::raise(SIGSEGV); }));
  unsetenv("LINEBAKE_ISOLATION");
  EXPECT_TRUE(isolation_enabled());
}

// LINEBAKE_ISOLATION_SECONDS sets the child's limit (scripts/fuzz: 10 s instead of 120); a value
// that is not a number of seconds from 1 to 86400 is an error naming the variable.
TEST(Isolated, TheLimitComesFromTheEnvironment) {
  EXPECT_EQ(isolation_seconds(), 120.0);
  setenv("LINEBAKE_ISOLATION_SECONDS", "1", 1);
  const auto start = std::chrono::steady_clock::now();
  try {
    check_in_isolation("hung.nc", "NetCDF", [] {
      for (;;) pause();
    });
    ADD_FAILURE() << "a hung walk passed";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("ran past 1 s"), std::string::npos) << e.what();
  }
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 10.0);
  for (const char* bad : {"0", "abc", "5s", "1e9", "nan"}) {
    setenv("LINEBAKE_ISOLATION_SECONDS", bad, 1);
    EXPECT_THROW(isolation_seconds(), Error) << bad;
  }
  unsetenv("LINEBAKE_ISOLATION_SECONDS");
  EXPECT_EQ(isolation_seconds(), 120.0);
}

// The /line_offsets of a hand-built line file of one line of `points` points.
static bool write_one_line(hid_t file, uint64_t points) {
  const uint64_t offsets[2] = {0, points};
  const hsize_t two = 2;
  h5::Handle space(H5Screate_simple(1, &two, nullptr), H5Sclose);
  h5::Handle o(
      H5Dcreate2(file, "line_offsets", H5T_STD_U64LE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
      H5Dclose);
  return H5Dwrite(o, H5T_NATIVE_UINT64, H5S_ALL, H5S_ALL, H5P_DEFAULT, offsets) >= 0;
}

// The walk visits what the reader reads: a dataset whose chunk index is damaged fails the walk
// (in the child), and the reader's error names the file and the dataset.
TEST(H5Probe, AWalkFailureNamesTheDataset) {
  TempDir dir;
  const std::string path = dir.file("chunked.h5");
  {
    h5::init();
    h5::Handle file(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose);
    const hsize_t dims[2] = {4096, 3}, chunk[2] = {256, 3};
    h5::Handle space(H5Screate_simple(2, dims, nullptr), H5Sclose);
    h5::Handle dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
    H5Pset_chunk(dcpl, 2, chunk);
    h5::Handle d(H5Dcreate2(file, "points", H5T_IEEE_F32LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT),
                 H5Dclose);
    std::vector<float> values(4096 * 3, 1.0f);
    ASSERT_GE(H5Dwrite(d, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()), 0);
    ASSERT_TRUE(write_one_line(file, 4096));
  }
  EXPECT_NO_THROW(h5::probe(path, {"/points", "/line_offsets"}));
  EXPECT_EQ(read_line_set(path).point_count(), 4096u);
  // Damage the v1 B-tree of the chunk index: its node signature "TREE" is followed by the node
  // type, level and entry count; a wrong level sends HDF5 to a child node that is not there.
  std::string bytes = read_text(path);
  size_t at = bytes.find("TREE", 1000);  // the root group's is near the start; the chunk index
  ASSERT_NE(at, std::string::npos);      // comes after the dataset's header
  bytes[at + 4] = 5;                     // node type 5: neither group nor chunk
  write_text(path, bytes);
  try {
    (void)read_line_set(path);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), path);
    EXPECT_NE(std::string(e.what()).find("/points"), std::string::npos) << e.what();
  }
}

// A compact dataset keeps its data in its header. One whose header says it stores fewer bytes
// than its shape (a fuzzed file said 0) made HDF5 1.10.8 copy from a null buffer, in-process,
// when the reader read it: the walk and the reader both refuse it now, and a sound compact
// dataset still reads.
TEST(H5Probe, ACompactDatasetMustStoreItsShape) {
  TempDir dir;
  const std::string path = dir.file("compact.h5");
  {
    h5::init();
    h5::Handle file(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose);
    const hsize_t dims[2] = {4, 3};
    h5::Handle space(H5Screate_simple(2, dims, nullptr), H5Sclose);
    h5::Handle dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
    H5Pset_layout(dcpl, H5D_COMPACT);
    h5::Handle d(H5Dcreate2(file, "points", H5T_IEEE_F32LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT),
                 H5Dclose);
    const float values[12] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12};
    ASSERT_GE(H5Dwrite(d, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, values), 0);
    ASSERT_TRUE(write_one_line(file, 4));
  }
  const LineSet sound = read_line_set(path);
  ASSERT_EQ(sound.point_count(), 4u);
  EXPECT_EQ(sound.positions[11], 12.0f);
  // The layout message (version 3, class 0: compact) holds the size, 48 bytes, then the data.
  std::string bytes = read_text(path);
  const float first[2] = {1, 2};
  const size_t data = bytes.find(std::string(reinterpret_cast<const char*>(first), 8));
  ASSERT_NE(data, std::string::npos);
  ASSERT_GE(data, 4u);
  ASSERT_EQ(bytes.substr(data - 4, 4), std::string("\x03\x00\x30\x00", 4));
  bytes[data - 2] = 0;  // "stores 0 bytes"
  write_text(path, bytes);
  linebake::test::expect_refused_either_way(path,
                                            {"/points",
                                             "compact dataset whose shape claims 48 bytes, but it "
                                             "stores 0"});
}

// HDF5's scale-offset decoder sizes its output from the filter's parameters (the chunk's element
// count and the element size), not from the chunk: a fuzzed file whose count said 1,052,770,309
// made the reader ask for 4 GB, in-process, to decode a 20-byte chunk, and a decoder that gets
// it fills it. The walk and the reader refuse parameters that disagree with the chunk layout.
TEST(H5Probe, AScaleOffsetFilterMustDescribeItsChunk) {
  TempDir dir;
  const std::string path = dir.file("scaleoffset.h5");
  {
    h5::init();
    h5::Handle file(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose);
    const hsize_t dims[2] = {4, 3}, chunk[2] = {2, 3};
    h5::Handle space(H5Screate_simple(2, dims, nullptr), H5Sclose);
    h5::Handle dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
    H5Pset_chunk(dcpl, 2, chunk);
    H5Pset_scaleoffset(dcpl, H5Z_SO_FLOAT_DSCALE, 2);  // two decimal digits kept
    h5::Handle d(H5Dcreate2(file, "points", H5T_IEEE_F32LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT),
                 H5Dclose);
    const float values[12] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12.5f};
    ASSERT_GE(H5Dwrite(d, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, values), 0);
    ASSERT_TRUE(write_one_line(file, 4));
  }
  const LineSet sound = read_line_set(path);
  ASSERT_EQ(sound.point_count(), 4u);
  EXPECT_EQ(sound.positions[11], 12.5f);
  // The filter's parameters 2 to 4 (H5Zscaleoffset.c): 6 values a chunk, class 1 (float), 4 bytes
  // each; stored once, in the dataset's pipeline message. Say 2^30 values instead.
  std::string bytes = read_text(path);
  const uint32_t parameters[3] = {6, 1, 4};
  const std::string pattern(reinterpret_cast<const char*>(parameters), sizeof parameters);
  const size_t at = bytes.find(pattern);
  ASSERT_NE(at, std::string::npos);
  ASSERT_EQ(bytes.find(pattern, at + 1), std::string::npos);
  const uint32_t damaged = uint32_t{1} << 30;
  bytes.replace(at, 4, std::string(reinterpret_cast<const char*>(&damaged), 4));
  write_text(path, bytes);
  linebake::test::expect_refused_either_way(path,
                                            {"/points",
                                             "scale-offset filter's parameters say a chunk holds "
                                             "1073741824 values of 4 bytes, but its layout and "
                                             "type say 6 of 4"});
}

// A float type's bit fields come from the file, and HDF5's conversion copies them bit by bit: a
// fuzzed double whose exponent was said to sit at bits 54 to 64 made every read run one bit past
// its element (a SEGV past the last one, in-process). The walk and the reader refuse a number
// type whose fields leave its bytes.
TEST(H5Probe, ANumberTypeMustKeepItsBitsInsideItsBytes) {
  TempDir dir;
  const std::string path = dir.file("float.h5");
  {
    h5::init();
    h5::Handle file(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose);
    const hsize_t dims[2] = {4, 3};
    h5::Handle space(H5Screate_simple(2, dims, nullptr), H5Sclose);
    h5::Handle d(
        H5Dcreate2(file, "points", H5T_IEEE_F64LE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
        H5Dclose);
    const double values[12] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12};
    ASSERT_GE(H5Dwrite(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values), 0);
    ASSERT_TRUE(write_one_line(file, 4));
  }
  ASSERT_EQ(read_line_set(path).positions[11], 12.0f);
  // The datatype message's float properties (HDF5 file format, section IV.A.2.d): bit offset 0,
  // precision 64, exponent at bit 52 of 11 bits, mantissa at bit 0 of 52, bias 1023.
  std::string bytes = read_text(path);
  const std::string properties("\x00\x00\x40\x00\x34\x0b\x00\x34\xff\x03\x00\x00", 12);
  const size_t at = bytes.find(properties);
  ASSERT_NE(at, std::string::npos);
  ASSERT_EQ(bytes.find(properties, at + 1), std::string::npos);
  bytes[at + 4] = 54;  // the exponent at bits 54 to 64
  write_text(path, bytes);
  linebake::test::expect_refused_either_way(path, {"/points", "11 exponent bits at bit 54"});
}
