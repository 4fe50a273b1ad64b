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
// each index at the world-space centre of its voxel: the data's own axes (docs/cli.md, "Axes"),
// the lines' origin (lines/origin.hpp) added in double.
// Blosc-compressed. OpenVDB itself is loaded on first use (formats/vdb_module.h says why).

#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "voxels/voxel_grid.hpp"

namespace linebake {

// What write_vdb reads at a time: the offsets of a block of `voxels`, then runs of its voxels
// whose `chords` fit (at least one voxel). bytes() bounds what their arrays take.
struct VdbPieces {
  uint64_t voxels = uint64_t{1} << 18, chords = uint64_t{1} << 20;
  uint64_t bytes() const { return voxels * (4 + 1 + 4 + 12 + 4 * 4) + chords * 8; }
};

// Loads the OpenVDB module and OpenVDB's registries (write_vdb would), so that a caller can
// measure its memory with them before it checks vdb_build_bytes against a budget. OutputError
// naming `output` where the module cannot be loaded.
void load_vdb(const std::string& output);
// Memory write_vdb takes for a grid (its description's resolution, attribute and occupied
// voxels), at most: OpenVDB's trees, which it needs whole to write the file, the chord lengths
// kept for the density scale, and the pieces.
uint64_t vdb_build_bytes(const VoxelGrid& description);

// Writes the grid read a piece at a time (a cache's, voxel_store.hpp: never whole in memory).
// Throws OutputError when the file cannot be written or the OpenVDB module cannot be loaded,
// InputError (from the pieces) where the grid's arrays are not sound; nothing is left then.
void write_vdb(const std::string& path, VoxelPieces& pieces, const VdbPieces& sizes = {},
               const std::array<double, 3>& origin = {0, 0, 0});
// The same for a grid in memory.
void write_vdb(const std::string& path, const VoxelGrid& grid,
               const std::array<double, 3>& origin = {0, 0, 0});

}  // namespace linebake
