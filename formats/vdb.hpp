#pragma once
// OpenVDB export of the voxel line grid, as float grids that Blender, Houdini and the standard
// Python binding (pyopenvdb) read:
//   density              fog volume in [0, 1]: the length of the voxel's chords (the quantised
//                        straight pieces VRC renders) in voxel units, divided by the 99th
//                        percentile over the voxels that hold lines and clamped at 1, so that a
//                        renderer's default density multiplier shows it. The divisor is the
//                        file's `linebake_density_scale`.
//   attribute_density    with an attribute: the grid's stored density, polyline length in
//                        voxel units x the chord's mean attribute normalised to [0, 1].
//   line_count           distinct lines in the voxel (saturating at 255), as float.
//   attribute_chord_max  with an attribute: the largest attribute at the ends of the voxel's
//                        chords (where lines cross its faces or end in it), in data units;
//                        a polyline point inside the voxel does not count.
// Voxel (i, j, k) of the grid maps to OpenVDB index (i, j, k), and the linear transform puts
// each index at the world-space centre of its voxel: the data's own axes (docs/cli.md, "Axes").
// Blosc-compressed. OpenVDB itself is loaded on first use (formats/vdb_module.h says why).

#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "voxels/voxel_grid.hpp"

namespace linebake {

// What write_vdb hands to OpenVDB: the active voxels (those any line passes through) and one
// value array per grid over them (NaN: inactive in that grid).
struct VdbGrids {
  struct Grid {
    std::string name, description;
    bool fog_volume = false;
    std::vector<float> values;
  };
  double voxel_size = 1;
  std::array<double, 3> first_centre{};  // world position of index (0, 0, 0)
  std::vector<std::array<int32_t, 3>> active;
  std::vector<Grid> grids;
  float density_scale = 1;  // chord length (voxel units) that maps to density 1
};
VdbGrids vdb_grids(const VoxelGrid& grid);

// Throws OutputError when the file cannot be written or the OpenVDB module cannot be loaded.
void write_vdb(const std::string& path, const VoxelGrid& grid);

}  // namespace linebake
