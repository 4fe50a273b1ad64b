// linebake-mpi: `bake` on MPI ranks, writing one cache through parallel HDF5 (docs/mpi.md).
// Run as `mpirun -np N linebake-mpi bake INPUT... -o CACHE`; the options are linebake bake's.
#include <malloc.h>
#include <mpi.h>

#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <string>

#include "cache/chunk_codec.hpp"
#include "cli_contract.hpp"
#include "commands.hpp"
#include "core/error.hpp"
#include "core/h5.hpp"
#include "core/interrupt.hpp"
#include "pipeline/bake_mpi.hpp"
#include "pipeline/mpi_ranks.hpp"

int main(int argc, char** argv) {
  using namespace linebake::cli;
  // HDF5's collective filtered writes allocate and free a buffer per chunk (1 MiB): above glibc's
  // mmap threshold each one is a fresh mapping, its pages faulted in and zeroed again. Kept in
  // the heap instead, they are reused (clouds at scale 0.25 on one rank: about 20 % faster).
  mallopt(M_MMAP_THRESHOLD, 64 << 20);
  mallopt(M_TRIM_THRESHOLD, 256 << 20);
  int provided = 0;
  // TBB's workers never call MPI: only the main thread does.
  MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  linebake::h5::init();
  // Debian's LZ4 and Blosc plugins link the serial HDF5: linebake's own codecs stand in.
  linebake::register_hdf5_filters();
  CLI::App app{"linebake-mpi " LINEBAKE_VERSION ": bake on MPI ranks into one cache",
               "linebake-mpi"};
  app.set_version_flag("--version", LINEBAKE_VERSION);
  app.require_subcommand(1);
  Command run = add_bake_with(
      app, [](const linebake::BakeOptions& o) { return linebake::bake_mpi(o, MPI_COMM_WORLD); },
      rank == 0,
      [](const std::function<void()>& step) { linebake::Ranks(MPI_COMM_WORLD).agree(step); });
  // Per rank here: the default is shared by the ranks on a node (bake_mpi).
  app.get_subcommand("bake")
      ->get_option("--memory-budget")
      ->description(
          "Resident memory each rank may use, e.g. 2G; unlimited (default: half of the node's "
          "physical memory, or of the cgroup's or ulimit -v's limit when less, shared by the "
          "ranks on the node)");
  speak_with_one_voice(app, "linebake-mpi");  // CLI11's "Run with --help ..." had followed
  int code = kOk;
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    code = rank == 0 ? app.exit(e) : (e.get_exit_code() == 0 ? 0 : 1);
    code = code == 0 ? kOk : kUsage;
    MPI_Finalize();
    return code;
  }
  linebake::install_interrupt_handlers();
  std::signal(SIGXFSZ, SIG_IGN);  // past `ulimit -f`: EFBIG, said and exit 3 (as linebake)
  // Every rank has the same error (bake_mpi agrees on it); rank 0 says it.
  const auto say = [&](const char* what) {
    if (rank == 0) std::cerr << "linebake-mpi: error: " + std::string(what) + "\n";
  };
  try {
    refuse_empty_values(app);  // as linebake's commands (every rank sees the same arguments)
    run();
  } catch (const linebake::CollectiveWriteFailed& e) {
    // Only this rank knows; the others may wait in the collective write for ever.
    // One write, so that the ranks' lines do not interleave (std::cerr writes each << at once).
    std::cerr << "linebake-mpi: error: " + std::string(e.what()) + "; stopping every rank\n";
    MPI_Abort(MPI_COMM_WORLD, e.exit_code());
  } catch (const linebake::Interrupted& e) {
    if (rank == 0)
      std::cerr << "linebake-mpi: " << e.what() << "; its temporary files are removed\n";
    code = 128 + e.signal();
  } catch (const linebake::UsageError& e) {
    say(e.what());
    code = kUsage;
  } catch (const linebake::InputError& e) {
    say(e.what());
    code = kInput;
  } catch (const linebake::OutputError& e) {
    say(e.what());
    code = kOutput;
  } catch (const std::exception& e) {
    say(e.what());
    code = kFailure;
  }
  MPI_Finalize();
  return code;
}
