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

/* One of the file's grids. */
typedef struct {
  const char* name;
  const char* description; /* OpenVDB's "description" grid metadata */
  int fog_volume;          /* GRID_FOG_VOLUME, else GRID_UNKNOWN */
} LinebakeVdbGrid;

typedef struct {
  const char* key;
  const char* string_value; /* a string, or NULL for a number */
  double number;
  int integer; /* with a number: stored as Int64Metadata, else DoubleMetadata */
} LinebakeVdbMeta;

/* The grids of a file, built a piece at a time (so that the caller need not hold the values of
 * every voxel at once), then written. Index (i, j, k) maps to world (first_centre + voxel_size
 * (i, j, k)). Each function returns 0, or 1 with a message in `error` (2 where memory ran out);
 * no exception crosses. */
typedef struct LinebakeVdbBuild LinebakeVdbBuild;
typedef struct {
  /* OpenVDB's registries (begin does it too): to be done before the caller measures its memory. */
  int (*initialize)(char* error, size_t error_size);
  /* The empty grids; *build is NULL on failure. */
  int (*begin)(double voxel_size, const double first_centre[3], const LinebakeVdbGrid* grids,
               uint32_t grid_count, LinebakeVdbBuild** build, char* error, size_t error_size);
  /* Sets `count` voxels ijk[3 i .. 3 i + 2] of every grid: values[g][i] (a NaN leaves that voxel
   * inactive in grid g). */
  int (*add)(LinebakeVdbBuild* build, uint64_t count, const int32_t* ijk,
             const float* const* values, char* error, size_t error_size);
  /* Grid g's active values v become min(1, v / scale). */
  int (*rescale)(LinebakeVdbBuild* build, uint32_t grid, float scale, char* error,
                 size_t error_size);
  /* Writes the grids to `path` (Blosc, active mask) with the file's metadata and sets
   * *expected_bytes to the size the file must have (the same grids serialised into a counting
   * stream: OpenVDB does not check its stream, so a full disk would leave a short file without
   * an error). */
  int (*write)(LinebakeVdbBuild* build, const char* path, const LinebakeVdbMeta* meta,
               uint32_t meta_count, uint64_t* expected_bytes, char* error, size_t error_size);
  void (*end)(LinebakeVdbBuild* build);
} LinebakeVdbModule;

/* The module's functions: `linebake_vdb_module_v2()` returns them. */
typedef const LinebakeVdbModule* (*LinebakeVdbModuleFn)(void);
#define LINEBAKE_VDB_MODULE_SYMBOL "linebake_vdb_module_v2"

#ifdef __cplusplus
}
#endif
