#pragma once
// The fuzz targets' one helper: the fuzzer's bytes as a file (linebake's readers take paths, and
// HDF5 and NetCDF read only from files), and the rule every target checks. A reader may refuse
// its input only with linebake's own exceptions (an Error that names the file and the place);
// anything else escaping it (std::bad_alloc, std::out_of_range, a library's exception) is a
// finding, and so is every sanitizer report. libFuzzer stops on the abort and keeps the input.

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <fstream>
#include <string>
#include <typeinfo>

#include "core/error.hpp"
#include "core/isolated.hpp"

namespace linebake::fuzz {

// A file in /tmp named for this process, with the extension the reader dispatches on.
inline std::string input_path(const std::string& extension) {
  const char* dir = std::getenv("TMPDIR");
  return std::string(dir && *dir ? dir : "/tmp") + "/linebake-fuzz-" + std::to_string(getpid()) +
         "." + extension;
}

// At exit: how many inputs crashed libhdf5 or libnetcdf in the isolated child (core/isolated.hpp)
// and were refused cleanly; scripts/fuzz reports the count (docs/fuzzing.md).
struct ContainedCrashReport {
  ~ContainedCrashReport() {
    std::fprintf(stderr, "linebake fuzz: %llu library crashes contained\n",
                 static_cast<unsigned long long>(linebake::contained_crashes()));
  }
};
inline ContainedCrashReport contained_crash_report;

template <class F>
int with_input_file(const uint8_t* data, size_t size, const std::string& extension, F&& read) {
  const std::string path = input_path(extension);
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), std::streamsize(size));
  }
  try {
    read(path);
  } catch (const linebake::Error&) {
    // A clean refusal: what hostile input should get.
  } catch (const std::exception& e) {
    std::fprintf(stderr, "linebake fuzz: %s escaped the reader: %s\n", typeid(e).name(), e.what());
    std::abort();
  }
  return 0;
}

}  // namespace linebake::fuzz
