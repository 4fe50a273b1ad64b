#pragma once
// glTF 2.0 export of the tube mesh, optionally Draco-compressed (KHR_draco_mesh_compression,
// encoded with libdraco), and of the raw lines. Written as .glb (one binary file, at most
// 4 GiB) or as .gltf (JSON) with its buffer in a .bin file beside it, which has no size limit.
//
// Axes: glTF's +y is up and importers convert from it (Blender turns it into its own +z). With
// GltfAxes::ZUp (the default) the data's +z is taken as up and written as glTF's +y, position
// (x, y, z) as (x, z, -y), so Blender shows the tubes in the data's own axes, where the VDB
// export (formats/vdb.hpp) puts its volume. GltfAxes::Raw writes the coordinates as stored.
//
// Per vertex, with an attribute: `_ATTRIBUTE` (UNSIGNED_SHORT normalised; the data range is in
// the mesh's extras), `TEXCOORD_0` = (attribute normalised to [0, 1], 0.5) for a viewer's own
// colour map, and `COLOR_0` from the given colour map. Tube chunks become one primitive each; the
// lines one indexed LINES primitive (glTF has no primitive restart), or one LINE_STRIP per
// polyline.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "lines/line_set.hpp"
#include "tubes/tube_mesh.hpp"

namespace linebake {

enum class GltfAxes { ZUp, Raw };

struct GltfOptions {
  bool draco = false;
  int draco_position_bits = 14;  // quantisation of positions (Draco's default is 11)
  int draco_normal_bits = 10;
  int draco_speed = 5;  // 0 (best compression) .. 10 (fastest)
  GltfAxes axes = GltfAxes::ZUp;
  // COLOR_0: 256 linear RGB colours, entry i for the attribute at i / 255 of colour_range (data
  // units; {0, 0}: the attribute's own range), clamped; empty: no COLOR_0.
  std::vector<std::array<uint8_t, 3>> colour_map;
  std::array<float, 2> colour_range{0, 0};
  bool line_strips = false;  // the lines as one LINE_STRIP per polyline
};

// Either may be null (but not both). The format from the extension: .glb, or .gltf with
// PATH-without-extension.bin. Throws OutputError when a file cannot be written or a GLB would
// exceed 4 GiB.
void write_gltf(const std::string& path, const TubeMesh* tubes, const LineSet* lines,
                const GltfOptions& options = {});

}  // namespace linebake
