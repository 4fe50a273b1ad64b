#pragma once
// OpenVDB export of the voxel line grid: float grid `density` (what Blender shows), int32 grid
// `line_count` and, when the grid carries an attribute, float grid `attribute_max` (in data
// units). Voxel (i, j, k) of the grid maps to OpenVDB index (i, j, k) with a linear transform
// whose voxel centres are the grid's world-space voxel centres. Blosc-compressed.

#include <string>

#include "voxels/voxel_grid.hpp"

namespace linebake {

// Throws OutputError when the file cannot be written.
void write_vdb(const std::string& path, const VoxelGrid& grid);

}  // namespace linebake
