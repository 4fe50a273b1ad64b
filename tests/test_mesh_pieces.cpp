// Mesh pieces that share no vertex (tubes/mesh_pieces.hpp), against hand-built meshes and a
// brute-force check of every piece.

#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "core/error.hpp"
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

// Against a second method on random meshes of strips, gaps and triangles that reach back: the
// cuts by their definition (every vertex before below every vertex after, tested pair by pair),
// then the greedy choice over them (the furthest cut within the limit, or the first past it).
TEST(MeshPieces, MatchBruteForceOnRandomMeshes) {
  std::mt19937 random(7);
  const auto draw = [&](uint32_t n) { return uint32_t(random() % n); };
  for (int round = 0; round < 300; ++round) {
    std::vector<uint32_t> indices;
    uint32_t base = 0;
    const uint32_t strips = 1 + draw(12);
    for (uint32_t s = 0; s < strips; ++s) {
      const uint32_t size = 3 + draw(6);
      for (uint32_t t = 0; t + 2 < size; ++t)
        indices.insert(indices.end(), {base + t, base + t + 1, base + t + 2});
      if (draw(5) == 0 && base > 0) indices.insert(indices.end(), {draw(base), base, base + 1});
      base += size + (draw(3) == 0 ? 2 : 0);  // unused vertices between strips at times
    }
    const uint64_t vertices = base + draw(3), limit = 1 + draw(20);
    const uint64_t triangles = indices.size() / 3;
    std::vector<std::pair<uint64_t, uint64_t>> cuts;  // (triangle, first vertex after)
    for (uint64_t t = 1; t < triangles; ++t) {
      uint32_t before = 0, after = UINT32_MAX;
      for (uint64_t u = 0; u < 3 * t; ++u) before = std::max(before, indices[u]);
      for (uint64_t u = 3 * t; u < indices.size(); ++u) after = std::min(after, indices[u]);
      if (after > before) cuts.emplace_back(t, uint64_t(before) + 1);
    }
    Shape expected;
    uint64_t t0 = 0, v0 = 0;
    for (size_t c = 0;;) {
      size_t best = cuts.size();  // the furthest cut within the limit
      for (size_t k = c; k < cuts.size() && cuts[k].second - v0 <= limit; ++k) best = k;
      if (best == cuts.size()) {
        if (c == cuts.size()) break;  // no cut left: the rest is one piece
        best = c;                     // none within: the first past it
      } else if (vertices - v0 <= limit) {
        break;  // the rest fits
      }
      expected.emplace_back(cuts[best].first - t0, cuts[best].second - v0);
      t0 = cuts[best].first, v0 = cuts[best].second, c = best + 1;
    }
    expected.emplace_back(triangles - t0, vertices - v0);
    const std::vector<MeshPiece> pieces = independent_pieces(indices, vertices, limit);
    expect_sound(pieces, indices, vertices);
    EXPECT_EQ(shape(pieces), expected) << "round " << round << ", limit " << limit;
  }
}

TEST(MeshPieces, ATriangleUsingAVertexPastTheCountIsAnError) {
  EXPECT_THROW(independent_pieces(std::vector<uint32_t>{0, 1, 5}, 5, 4), Error);
}

}  // namespace
}  // namespace linebake
