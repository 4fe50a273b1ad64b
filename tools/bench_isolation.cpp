#include "bench_isolation.hpp"

#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "cli_contract.hpp"
#include "core/error.hpp"
#include "core/h5.hpp"
#include "core/h5_probe.hpp"
#include "core/isolated.hpp"
#include "core/json_file.hpp"
#include "core/memory_budget.hpp"

namespace linebake::cli {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

struct Dataset {
  std::string name;
  uint64_t bytes = 0;
};

// Every dataset of the file with a fixed-size type, and its size in memory.
std::vector<Dataset> datasets_of(const std::string& path) {
  h5::Handle file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!file.valid()) throw InputError(path, "", "cannot open as HDF5");
  std::vector<Dataset> list;
  auto each = [](hid_t root, const char* name, const H5O_info_t* info, void* data) -> herr_t {
    if (info->type != H5O_TYPE_DATASET) return 0;
    h5::Handle d(H5Dopen2(root, name, H5P_DEFAULT), H5Dclose);
    h5::Handle type(H5Dget_type(d), H5Tclose);
    if (H5Tis_variable_str(type) > 0 || H5Tdetect_class(type, H5T_VLEN) > 0) return 0;
    uint64_t bytes = H5Tget_size(type);
    for (hsize_t n : h5::shape_of(d)) bytes *= n;
    try {  // nothing may unwind through HDF5's C frames
      static_cast<std::vector<Dataset>*>(data)->push_back({std::string("/") + name, bytes});
    } catch (...) {
      return -1;
    }
    return 0;
  };
  H5Ovisit2(file, H5_INDEX_NAME, H5_ITER_INC, each, &list, H5O_INFO_BASIC);
  return list;
}

// Reads every dataset whole into `out` (back to back), as stored: the data a reader decodes.
void read_data(const std::string& path, const std::vector<Dataset>& list, char* out) {
  h5::Handle file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  for (const Dataset& d : list) {
    h5::Handle dataset(H5Dopen2(file, d.name.c_str(), H5P_DEFAULT), H5Dclose);
    h5::Handle type(H5Dget_type(dataset), H5Tclose);
    if (d.bytes && H5Dread(dataset, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, out) < 0)
      throw InputError(path, "dataset " + d.name, "cannot read: " + h5::last_error());
    out += d.bytes;
  }
}

uint64_t touch(const char* data, uint64_t bytes) {
  uint64_t sum = 0;
  for (uint64_t i = 0; i < bytes; i += 4096) sum += static_cast<unsigned char>(data[i]);
  return sum;
}

struct Figures {
  double walk_in_process = 0, probe = 0, read = 0, read_in_child = 0;
  uint64_t data_bytes = 0, file_bytes = 0;
};

Figures measure(const std::string& path, int repeat) {
  Figures f;
  f.file_bytes = std::filesystem::file_size(path);
  const std::vector<Dataset> list = datasets_of(path);
  for (const Dataset& d : list) f.data_bytes += d.bytes;
  std::vector<double> walk, probe, read, child;
  for (int r = 0; r < repeat; ++r) {
    auto t = Clock::now();
    h5::walk_metadata(path, {"/"});
    walk.push_back(seconds_since(t));

    t = Clock::now();
    const IsolatedOutcome outcome = run_isolated([&] {
      h5::walk_metadata(path, {"/"});
      return std::string("ok");
    });
    if (outcome.kind != IsolatedOutcome::Kind::Finished)
      throw InputError(path, "", "the isolated walk " + outcome.describe({}));
    probe.push_back(seconds_since(t));

    // In-process: the data read into private memory, then touched.
    t = Clock::now();
    {
      std::vector<char> buffer(f.data_bytes + 1);
      read_data(path, list, buffer.data());
      (void)touch(buffer.data(), f.data_bytes);
    }
    read.push_back(seconds_since(t));

    // The alternative: the child reads into a memfd, the parent maps it (no copy) and touches it.
    t = Clock::now();
    {
      const int fd = memfd_create("linebake-isolated-data", MFD_CLOEXEC);
      if (fd < 0) throw Error(std::string("memfd: ") + std::strerror(errno));
      const std::shared_ptr<void> close_fd(nullptr, [fd](void*) { close(fd); });
      if (ftruncate(fd, static_cast<off_t>(f.data_bytes + 1)) != 0)
        throw Error(std::string("memfd: ") + std::strerror(errno));
      const IsolatedOutcome o = run_isolated(
          [&] {
            void* p = mmap(nullptr, f.data_bytes + 1, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
            if (p == MAP_FAILED) throw std::runtime_error("mmap failed");
            read_data(path, list, static_cast<char*>(p));
            return std::string("ok");
          },
          {120, f.data_bytes + (uint64_t{1} << 30)});
      if (o.kind != IsolatedOutcome::Kind::Finished)
        throw InputError(path, "", "the isolated read " + o.describe({}));
      void* p = mmap(nullptr, f.data_bytes + 1, PROT_READ, MAP_SHARED, fd, 0);
      if (p == MAP_FAILED) throw Error("mmap of the memfd failed");
      (void)touch(static_cast<const char*>(p), f.data_bytes);
      munmap(p, f.data_bytes + 1);
    }
    child.push_back(seconds_since(t));
  }
  f.walk_in_process = median(walk);
  f.probe = median(probe);
  f.read = median(read);
  f.read_in_child = median(child);
  return f;
}

}  // namespace

void bench_isolation(const BenchIsolationArgs& args) {
  h5::init();
  // Resident memory the fork must copy the page tables of, as a large bake has.
  const uint64_t resident_bytes = parse_size(args.resident);
  std::vector<char> resident(resident_bytes);
  for (uint64_t i = 0; i < resident_bytes; i += 4096) resident[i] = 1;
  nlohmann::json out = nlohmann::json::array();
  for (const std::string& path : args.files) {
    const Figures f = measure(path, args.repeat);
    out.push_back({{"file", path},
                   {"file_bytes", f.file_bytes},
                   {"data_bytes", f.data_bytes},
                   {"resident_bytes", resident_bytes},
                   {"walk_in_process_s", f.walk_in_process},
                   {"isolated_walk_s", f.probe},
                   {"read_s", f.read},
                   {"read_in_child_shared_memory_s", f.read_in_child}});
    if (args.json) continue;
    std::cout << path << " (" << format_bytes(f.file_bytes) << ", " << format_bytes(f.data_bytes)
              << " of data; parent resident " << format_bytes(resident_bytes) << "), median of "
              << args.repeat << ":\n"
              << std::fixed << std::setprecision(4)
              << "  metadata walk, in-process:        " << f.walk_in_process << " s\n"
              << "  metadata walk, isolated (fork):   " << f.probe << " s (" << std::setprecision(1)
              << 100 * f.probe / f.read << " % of reading the data)\n"
              << std::setprecision(4) << "  data read, in-process:            " << f.read << " s\n"
              << "  data read in the child, memfd:    " << f.read_in_child << " s ("
              << std::setprecision(2) << f.read_in_child / f.read << "x)\n";
  }
  if (args.json) std::cout << json_text(out, 2) << "\n";
}

}  // namespace linebake::cli
