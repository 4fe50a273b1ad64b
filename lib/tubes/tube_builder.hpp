#pragma once
// Line set -> tube mesh (techniques.md section 10), multithreaded with byte-identical output
// for any thread count.

#include <array>
#include <cstdint>
#include <optional>
#include <string>

#include "core/progress.hpp"
#include "lines/line_set.hpp"
#include "tubes/tube_mesh.hpp"

namespace linebake {

struct TubeOptions {
  int sides = 3;  // ring vertices per point, 3..32
  // Tube radius; a fraction of the bounding-box diagonal unless radius_absolute.
  float radius = 0.001f;
  bool radius_absolute = false;
  // Per-point radius from an attribute: radius * value / max(value); values <= 0 or non-finite
  // give 1% of the radius so no ring collapses.
  std::string radius_attribute;
  bool caps = false;  // close each tube with a fan at both ends
  NormalEncoding normals = NormalEncoding::Float32;
  // Stored attribute: a vertex or line attribute by name; "" picks the first vertex attribute;
  // "none" stores none.
  std::string attribute;
  std::optional<std::array<float, 2>> attribute_range;  // default: the attribute's finite range
  uint64_t max_chunk_bytes = uint64_t{4} << 30;         // the paper's 4 GiB addressing limit
  uint64_t max_chunk_indices = 0xFFFFFFFFull;           // 32-bit indices
  // Points closer than this to the previous kept point are skipped (fraction of the diagonal).
  float min_point_distance = 1e-6f;
};

// The tube radius in world units: options.radius x the bounding-box diagonal, or as given.
float world_radius(const LineSet& lines, const TubeOptions& options);

// Throws linebake::Error for options out of range or a line too large for one chunk.
TubeMesh build_tubes(const LineSet& lines, const TubeOptions& options,
                     const ProgressFn& progress = {});

}  // namespace linebake
