#pragma once
// glTF 2.0 binary (.glb) export of the tube mesh, optionally Draco-compressed
// (KHR_draco_mesh_compression, encoded with libdraco), and of the raw lines as LINE_STRIP
// primitives. Tube chunks become separate primitives; the stored attribute goes out as
// `_ATTRIBUTE` (UNSIGNED_SHORT, normalized) with its data range in the mesh's extras.

#include <string>

#include "lines/line_set.hpp"
#include "tubes/tube_mesh.hpp"

namespace linebake {

struct GltfOptions {
  bool draco = false;
  int draco_position_bits = 14;  // quantisation of positions (Draco's default is 11)
  int draco_normal_bits = 10;
  int draco_speed = 5;  // 0 (best compression) .. 10 (fastest)
};

// Either may be null (but not both). Throws OutputError when the file cannot be written or the
// content exceeds what GLB can address (4 GiB in total).
void write_glb(const std::string& path, const TubeMesh* tubes, const LineSet* lines,
               const GltfOptions& options = {});

}  // namespace linebake
