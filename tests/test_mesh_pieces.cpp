// Mesh pieces that share no vertex (tubes/mesh_pieces.hpp), against hand-built meshes and a
// brute-force check of every piece.

#include <gtest/gtest.h>

#include <vector>

#include "tubes/mesh_pieces.hpp"

namespace linebake {
namespace {

// Three strips of 4 vertices and 2 triangles each: 0-3, 4-7, 8-11.
std::vector<uint32_t> three_strips() {
  std::vector<uint32_t> indices;
  for (uint32_t s = 0; s < 3; ++s)
    indices.insert(indices.end(), {4 * s, 4 * s + 1, 4 * s + 2, 4 * s + 2, 4 * s + 1, 4 * s + 3});
  return indices;
}

// Contiguous, covering, and no triangle using a vertex outside its piece.
void expect_sound(const std::vector<MeshPiece>& pieces, const std::vector<uint32_t>& indices,
                  uint64_t vertices) {
  uint64_t triangle = 0, vertex = 0;
  for (const MeshPiece& p : pieces) {
    EXPECT_EQ(p.first_triangle, triangle);
    EXPECT_EQ(p.first_vertex, vertex);
    for (uint64_t t = p.first_triangle; t < p.first_triangle + p.triangles; ++t)
      for (int k = 0; k < 3; ++k) {
        EXPECT_GE(indices[3 * t + k], p.first_vertex);
        EXPECT_LT(indices[3 * t + k], p.first_vertex + p.vertices);
      }
    triangle += p.triangles, vertex += p.vertices;
  }
  EXPECT_EQ(triangle, indices.size() / 3);
  EXPECT_EQ(vertex, vertices);
}

std::vector<std::pair<uint64_t, uint64_t>> shape(const std::vector<MeshPiece>& pieces) {
  std::vector<std::pair<uint64_t, uint64_t>> out;
  for (const MeshPiece& p : pieces) out.emplace_back(p.triangles, p.vertices);
  return out;
}

using Shape = std::vector<std::pair<uint64_t, uint64_t>>;

TEST(MeshPieces, CutBetweenStripsUpToTheLimit) {
  const std::vector<uint32_t> indices = three_strips();
  for (const uint64_t limit : {1, 4, 5, 7, 8, 11, 12, 100}) {
    const std::vector<MeshPiece> pieces = independent_pieces(indices, 12, limit);
    expect_sound(pieces, indices, 12);
    const Shape expected = limit < 8    ? Shape{{2, 4}, {2, 4}, {2, 4}}
                           : limit < 12 ? Shape{{4, 8}, {2, 4}}
                                        : Shape{{6, 12}};
    EXPECT_EQ(shape(pieces), expected) << limit;
  }
}

// A triangle at the end that reaches back to vertex 0 (a cap emitted last) leaves no cut before
// it; unused vertices after the last triangle go to the last piece.
TEST(MeshPieces, NoCutWhereALaterTriangleReachesBack) {
  std::vector<uint32_t> indices = three_strips();
  indices.insert(indices.end(), {0, 5, 9});
  EXPECT_EQ(shape(independent_pieces(indices, 12, 4)), (Shape{{7, 12}}));
  indices = three_strips();
  indices.insert(indices.end(), {4, 10, 11});  // joins the second and third strips
  const std::vector<MeshPiece> pieces = independent_pieces(indices, 15, 4);
  expect_sound(pieces, indices, 15);
  EXPECT_EQ(shape(pieces), (Shape{{2, 4}, {5, 11}}));
  EXPECT_TRUE(independent_pieces({}, 10, 4).empty());
}

}  // namespace
}  // namespace linebake
