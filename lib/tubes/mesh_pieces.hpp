#pragma once
// A triangle mesh cut into pieces that share no vertex: each piece's triangles use only its own
// range of vertices, so it can be encoded apart (Draco's encoder holds about 14 times the mesh
// it is given) with its indices rebased to its first vertex. A tube mesh cuts between lines.

#include <cstdint>
#include <span>
#include <vector>

namespace linebake {

struct MeshPiece {
  uint64_t first_triangle = 0, triangles = 0;
  uint64_t first_vertex = 0, vertices = 0;
};

// Pieces of triangles [0, indices.size() / 3) and vertices [0, vertex_count), in order, covering
// both: each as many vertices as fit `max_vertices`, or more where no cut comes sooner (a cut
// falls only where no later triangle uses a vertex below it). None without triangles. Error
// where a triangle uses a vertex past vertex_count.
std::vector<MeshPiece> independent_pieces(std::span<const uint32_t> indices, uint64_t vertex_count,
                                          uint64_t max_vertices);

}  // namespace linebake
