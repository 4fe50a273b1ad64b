#include "tubes/mesh_pieces.hpp"

#include <algorithm>
#include <cstdint>
#include <string>

#include "core/error.hpp"

namespace linebake {

std::vector<MeshPiece> independent_pieces(std::span<const uint32_t> indices, uint64_t vertex_count,
                                          uint64_t max_vertices) {
  const uint64_t triangles = indices.size() / 3;
  std::vector<MeshPiece> pieces;
  if (triangles == 0) return pieces;
  const auto least = [&](uint64_t t) {
    return std::min({indices[3 * t], indices[3 * t + 1], indices[3 * t + 2]});
  };
  const auto most = [&](uint64_t t) {
    return std::max({indices[3 * t], indices[3 * t + 1], indices[3 * t + 2]});
  };
  // Where a cut may fall: before triangle t, whose vertices all lie past every vertex of the
  // triangles before it (the first vertex after them: `end`), then kept where no later triangle
  // reaches below that either.
  struct Cut {
    uint64_t triangle, end;
  };
  std::vector<Cut> cuts;
  uint64_t end = uint64_t(most(0)) + 1;
  for (uint64_t t = 1; t < triangles; ++t) {
    if (least(t) >= end) cuts.push_back({t, end});
    end = std::max(end, uint64_t(most(t)) + 1);
  }
  if (end > vertex_count)
    throw Error("independent_pieces: a triangle uses vertex " + std::to_string(end - 1) + " of " +
                std::to_string(vertex_count));
  uint64_t below = UINT64_MAX;  // the least vertex of the triangles from t on
  size_t kept = cuts.size();
  std::vector<bool> sound(cuts.size());
  for (uint64_t t = triangles; t-- > 0 && kept > 0;) {
    below = std::min<uint64_t>(below, least(t));
    if (cuts[kept - 1].triangle == t) sound[kept - 1] = below >= cuts[kept - 1].end, --kept;
  }
  // Greedy: each piece ends at the last sound cut within max_vertices of its start, or at the
  // first one past it where none is within.
  MeshPiece piece;
  const auto close = [&](uint64_t triangle, uint64_t vertex) {
    piece.triangles = triangle - piece.first_triangle;
    piece.vertices = vertex - piece.first_vertex;
    pieces.push_back(piece);
    piece = {triangle, 0, vertex, 0};
  };
  const Cut* pending = nullptr;  // the last sound cut within reach of the open piece
  for (size_t c = 0; c < cuts.size(); ++c) {
    if (!sound[c]) continue;
    if (cuts[c].end - piece.first_vertex <= max_vertices) {
      pending = &cuts[c];
      continue;
    }
    if (pending) {
      close(pending->triangle, pending->end);
      pending = nullptr;
      if (cuts[c].end - piece.first_vertex <= max_vertices) {
        pending = &cuts[c];
        continue;
      }
    }
    close(cuts[c].triangle, cuts[c].end);
  }
  if (pending && vertex_count - piece.first_vertex > max_vertices)
    close(pending->triangle, pending->end);
  close(triangles, std::max(vertex_count, piece.first_vertex));
  return pieces;
}

}  // namespace linebake
