#pragma once
// bake under MPI (linebake-mpi): the ranks split the input by whole files and line ranges, each
// reads, validates and builds only its share, and all write one cache through parallel HDF5.
// The datasets equal a serial bake's of the same inputs, whatever the rank count (docs/mpi.md).
//
// What it builds: /lines and the tube mesh. Voxels, Embree and rtx are refused with the way to
// add them (a serial bake of the same inputs into this cache reuses /lines and the tubes).

#include <mpi.h>

#include "core/error.hpp"
#include "pipeline/bake.hpp"

namespace linebake {

// Collective over `comm`. An error on any rank throws on every rank, naming the rank (InputError
// and OutputError keep their kind); nothing is left under the cache's name or beside it. Errors
// inside a collective write (a full disk) cannot be agreed on: that rank removes the temporary
// file and throws CollectiveWriteFailed.
BakeResult bake_mpi(const BakeOptions& options, MPI_Comm comm);

// Thrown on a rank whose part of a collective write failed, once it has removed the temporary
// file. The other ranks may be waiting in a collective that will never complete, so the caller
// must end the job (MPI_Abort with exit_code(): 3 for an output that could not be written,
// 128 + the signal for an interruption, 4 otherwise): nothing else stops them. The rank's HDF5
// handles were left open on the way (h5::LeaveOpenOnUnwind): closing them is collective.
class CollectiveWriteFailed : public Error {
 public:
  CollectiveWriteFailed(const std::string& message, int exit_code)
      : Error(message), exit_code_(exit_code) {}
  int exit_code() const { return exit_code_; }

 private:
  int exit_code_;
};

// The figures of one rank, as the provenance keeps them (stats.ranks).
struct RankFigures {
  int rank = 0;
  uint64_t lines = 0, points = 0;  // its share, as read (after validation)
  double read_s = 0, build_s = 0;  // its reading and its building and writing
  uint64_t bytes = 0;              // dataset bytes it wrote (uncompressed)
};

}  // namespace linebake
