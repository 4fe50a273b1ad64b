#pragma once
// bake under MPI (linebake-mpi): the ranks split the input by whole files and line ranges, each
// reads, validates and builds only its share, and all write one cache through parallel HDF5.
// The datasets equal a serial bake's of the same inputs, whatever the rank count (docs/mpi.md).
//
// What it builds: /lines and the tube mesh. Voxels, Embree and rtx are refused with the way to
// add them (a serial bake of the same inputs into this cache reuses /lines and the tubes).

#include <mpi.h>

#include "pipeline/bake.hpp"

namespace linebake {

// Collective over `comm`. An error on any rank throws on every rank, naming the rank (InputError
// and OutputError keep their kind); nothing is left under the cache's name or beside it. Errors
// inside a collective write (a full disk) cannot be agreed on: that rank removes the temporary
// file and aborts the job (MPI_Abort).
BakeResult bake_mpi(const BakeOptions& options, MPI_Comm comm);

// The figures of one rank, as the provenance keeps them (stats.ranks).
struct RankFigures {
  int rank = 0;
  uint64_t lines = 0, points = 0;  // its share, as read (after validation)
  double read_s = 0, build_s = 0;  // its reading and its building and writing
  uint64_t bytes = 0;              // dataset bytes it wrote (uncompressed)
};

}  // namespace linebake
