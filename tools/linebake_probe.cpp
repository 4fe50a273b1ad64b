// linebake-probe: walks a foreign file's metadata in a fresh process, for a linebake process
// with threads (core/isolated.hpp, check_in_isolation): a child forked from one inherits the
// locks its other threads held at the fork (HDF5's global lock, while another thread is in
// HDF5: Python threads reading files at once) and can stall on them until its time limit.
//
//   linebake-probe MEMORY_BYTES SECONDS PARENT_PID hdf5 PATH [OBJECT...]
//   linebake-probe MEMORY_BYTES SECONDS PARENT_PID netcdf PATH
//
// It writes kIsolatedHandshake on descriptor 3 and then replies there as a forked child does
// (serve_isolated): 'R' when the walk passed, 'E' and the message when it failed, 'M' when it ran
// out of its MEMORY_BYTES; a crash ends it with its signal. It dies with the thread that started
// it (or at once, if that was gone before it could ask), and a second after its SECONDS in any
// case. Not meant to be run by hand.

#include <sys/prctl.h>
#include <unistd.h>

#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "core/h5.hpp"
#include "core/h5_probe.hpp"
#include "core/isolated.hpp"
#include "formats/formats.hpp"

int main(int argc, char** argv) {
  prctl(PR_SET_PDEATHSIG, SIGKILL);  // a parent killed outright takes its walk along
  if (argc < 6) {
    std::fprintf(stderr,
                 "usage: linebake-probe MEMORY_BYTES SECONDS PARENT_PID hdf5|netcdf PATH "
                 "[OBJECT...]\n");
    return 2;
  }
  if (getppid() != static_cast<pid_t>(std::strtol(argv[3], nullptr, 10)))
    return 2;  // the parent went before the request above was made
  alarm(static_cast<unsigned>(std::ceil(std::strtod(argv[2], nullptr))) + 1u);
  linebake::IsolationLimits limits;
  limits.memory_bytes = std::strtoull(argv[1], nullptr, 10);
  const std::string library = argv[4], path = argv[5];
  const std::vector<std::string> objects(argv + 6, argv + argc);
  if (library != "hdf5" && library != "netcdf") {
    std::fprintf(stderr, "linebake-probe: unknown library %s\n", library.c_str());
    return 2;
  }
  linebake::h5::init();  // HDF5's own printing off; NetCDF-4 files are HDF5 underneath
  // Said once the arguments are understood: what fails before this is no verdict on the file.
  const int reply = linebake::kIsolatedReplyFd;
  const std::string& hello = linebake::kIsolatedHandshake;
  if (::write(reply, hello.data(), hello.size()) != static_cast<ssize_t>(hello.size()))
    return 2;  // started by hand, without the descriptor
  linebake::serve_isolated(
      reply,
      [&] {
        if (library == "hdf5")
          linebake::h5::walk_metadata(path, objects);
        else
          linebake::formats::walk_netcdf_metadata(path);
        return std::string("ok");
      },
      limits);
}
