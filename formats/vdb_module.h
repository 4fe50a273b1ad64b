#pragma once
/* The C interface between linebake and liblinebake_vdb.so, the module that links OpenVDB.
 *
 * Why a module: Debian's libopenvdb is linked with BIND_NOW, so every process that links it
 * resolves its ~57,000 symbols at start-up, about 50 ms on a 2-core EPYC VM, half of what a
 * `linebake info` costs in all. Only `export --vdb` needs OpenVDB; formats/vdb.cpp loads the
 * module with dlopen() the first time it writes a VDB. Plain C data crosses the boundary, and
 * no exception does. */

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* One grid over the file's active voxels: values[i] belongs to voxel ijk[3 i .. 3 i + 2]; a NaN
 * leaves that voxel inactive in this grid. */
typedef struct {
  const char* name;
  const char* description; /* OpenVDB's "description" grid metadata */
  int fog_volume;          /* GRID_FOG_VOLUME, else GRID_UNKNOWN */
  const float* values;
} LinebakeVdbGrid;

typedef struct {
  const char* key;
  const char* string_value; /* a string, or NULL for a number */
  double number;
  int integer; /* with a number: stored as Int64Metadata, else DoubleMetadata */
} LinebakeVdbMeta;

typedef struct {
  /* Index (i, j, k) maps to world (first_centre + voxel_size (i, j, k)). */
  double voxel_size;
  double first_centre[3];
  uint64_t active_count;
  const int32_t* ijk;
  const LinebakeVdbGrid* grids;
  uint32_t grid_count;
  const LinebakeVdbMeta* meta;
  uint32_t meta_count;
} LinebakeVdbFile;

/* Writes `file` to `path` (Blosc, active mask). On success returns 0 and sets *expected_bytes to
 * the size the file must have (the same grids serialised into a counting stream: OpenVDB does
 * not check its stream, so a full disk would leave a short file without an error). On failure
 * returns 1 with a message in `error`. */
typedef int (*LinebakeVdbWrite)(const char* path, const LinebakeVdbFile* file,
                                uint64_t* expected_bytes, char* error, size_t error_size);
#define LINEBAKE_VDB_WRITE_SYMBOL "linebake_vdb_write_v1"

#ifdef __cplusplus
}
#endif
