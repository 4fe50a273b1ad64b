// BlockHasher against a direct computation with xxHash, and pieces combined in any split.
#include <gtest/gtest.h>
#include <xxhash.h>

#include <algorithm>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "core/hash.hpp"

namespace linebake {
namespace {

// The definition, written out: XXH3-128 of each 1 MiB block (canonical bytes), then of those.
std::string expected_block_hash(const std::string& bytes) {
  std::string digests;
  const size_t block = size_t{1} << 20;
  for (size_t at = 0; at < bytes.size(); at += block) {
    XXH128_canonical_t c;
    XXH128_canonicalFromHash(&c,
                             XXH3_128bits(bytes.data() + at, std::min(block, bytes.size() - at)));
    digests.append(reinterpret_cast<const char*>(c.digest), 16);
  }
  const XXH128_hash_t h = XXH3_128bits(digests.data(), digests.size());
  char text[33];
  std::snprintf(text, sizeof text, "%016llx%016llx", (unsigned long long)h.high64,
                (unsigned long long)h.low64);
  return text;
}

std::string random_bytes(size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::string s(n, '\0');
  for (char& c : s) c = char(rng());
  return s;
}

TEST(BlockHasher, MatchesTheDefinitionWhateverTheUpdates) {
  const size_t MiB = size_t{1} << 20;
  for (size_t n : {size_t{0}, size_t{1}, MiB - 1, MiB, MiB + 1, 3 * MiB + 12345}) {
    const std::string bytes = random_bytes(n, unsigned(n));
    const std::string expected = expected_block_hash(bytes);
    EXPECT_EQ(BlockHasher().update(bytes.data(), bytes.size()).hex(), expected) << n;
    // In odd-sized updates (12-byte rows, chunks that straddle blocks).
    BlockHasher h;
    for (size_t at = 0; at < n;) {
      const size_t take = std::min<size_t>(n - at, 87381 * 12 + (at % 7));
      h.update(bytes.data() + at, take);
      at += take;
    }
    EXPECT_EQ(h.hex(), expected) << n;
  }
  // Not the flat hash: a reader cannot confuse the two attributes' values.
  const std::string two = random_bytes(2 * MiB, 9);
  EXPECT_NE(BlockHasher().update(two.data(), two.size()).hex(), hash_bytes(two.data(), two.size()));
}

TEST(BlockHasher, PiecesCombineToTheWholeStreamsHash) {
  const size_t MiB = size_t{1} << 20;
  const std::string bytes = random_bytes(5 * MiB + 777, 3);
  const std::string expected = expected_block_hash(bytes);
  // Cuts inside blocks, on boundaries, pieces shorter than a block, and an empty piece.
  const std::vector<std::vector<size_t>> splits = {
      {0, bytes.size()},
      {0, 100, bytes.size()},
      {0, MiB, 2 * MiB, bytes.size()},
      {0, MiB / 2, MiB / 2 + 10, MiB / 2 + 10, 3 * MiB + 5, bytes.size()},
      {0, 1, 2, 3, 4 * MiB - 1, bytes.size()}};
  for (const auto& cuts : splits) {
    std::vector<std::string> pieces;
    for (size_t i = 0; i + 1 < cuts.size(); ++i) {
      BlockHasher piece(BlockHasher::Piece{cuts[i]});
      piece.update(bytes.data() + cuts[i], cuts[i + 1] - cuts[i]);
      EXPECT_EQ(piece.bytes(), cuts[i + 1] - cuts[i]);
      pieces.push_back(piece.piece());
    }
    std::reverse(pieces.begin(), pieces.end());  // any order
    EXPECT_EQ(combine_block_hashes(pieces), expected) << cuts.size();
  }
  // A gap is an error, not a wrong hash.
  BlockHasher a(BlockHasher::Piece{0}), b(BlockHasher::Piece{10});
  a.update(bytes.data(), 5);
  b.update(bytes.data() + 10, 5);
  EXPECT_THROW(combine_block_hashes({a.piece(), b.piece()}), Error);
}

// Pieces told the stream's length hash its short last block at once: the same hash, and the
// piece that ends the stream keeps none of its bytes raw (MPI ranks keep thousands of pieces).
TEST(BlockHasher, APieceThatEndsTheStreamKeepsNoRawBytes) {
  const size_t MiB = size_t{1} << 20;
  for (const size_t length : {size_t{1000}, 3 * MiB + 777, 2 * MiB}) {
    const std::string bytes = random_bytes(length, 9);
    const std::string expected = expected_block_hash(bytes);
    for (const std::vector<size_t>& cuts : std::vector<std::vector<size_t>>{
             {0, length}, {0, length / 3, length}, {0, length - 1, length}, {0, 7, length}}) {
      std::vector<std::string> pieces;
      size_t raw_in_last = 0;
      for (size_t i = 0; i + 1 < cuts.size(); ++i) {
        BlockHasher piece(BlockHasher::Piece{cuts[i], length});
        // In two updates: the stream's end is seen on the second.
        const size_t half = (cuts[i + 1] - cuts[i]) / 2;
        piece.update(bytes.data() + cuts[i], half);
        piece.update(bytes.data() + cuts[i] + half, cuts[i + 1] - cuts[i] - half);
        pieces.push_back(piece.piece());
        if (i + 2 == cuts.size() && cuts[i] % MiB == 0) raw_in_last = pieces.back().size();
      }
      EXPECT_EQ(combine_block_hashes(pieces), expected) << length << " " << cuts.size();
      std::reverse(pieces.begin(), pieces.end());
      EXPECT_EQ(combine_block_hashes(pieces), expected) << length << " " << cuts.size();
      // A last piece from a block boundary: its offsets, digests and no raw bytes.
      if (raw_in_last) {
        EXPECT_LT(raw_in_last, 64 + 16 * (length / MiB + 1)) << length;
      }
    }
  }
  // Nothing may follow a piece that ended the stream.
  BlockHasher whole(BlockHasher::Piece{0, 100}), more(BlockHasher::Piece{100});
  const std::string bytes = random_bytes(110, 2);
  whole.update(bytes.data(), 100);
  more.update(bytes.data() + 100, 10);
  EXPECT_THROW(combine_block_hashes({whole.piece(), more.piece()}), Error);
}

}  // namespace
}  // namespace linebake

namespace linebake {
namespace {

TEST(BlockHasher, JoiningPiecesInAnyGroupingGivesTheSameHash) {
  const size_t MiB = size_t{1} << 20;
  const std::string bytes = random_bytes(4 * MiB + 99, 5);
  const std::string expected = expected_block_hash(bytes);
  // Eight pieces, some shorter than a block, joined pairwise as a binomial tree does, and in
  // another grouping.
  const std::vector<size_t> cuts = {0,           10,          MiB / 3,     MiB / 3 + 1, 2 * MiB,
                                    2 * MiB + 7, 3 * MiB - 5, 4 * MiB + 1, bytes.size()};
  std::vector<std::string> pieces;
  for (size_t i = 0; i + 1 < cuts.size(); ++i) {
    BlockHasher p(BlockHasher::Piece{cuts[i]});
    p.update(bytes.data() + cuts[i], cuts[i + 1] - cuts[i]);
    pieces.push_back(p.piece());
  }
  std::vector<std::string> level = pieces;
  while (level.size() > 1) {
    std::vector<std::string> next;
    for (size_t i = 0; i < level.size(); i += 2)
      next.push_back(i + 1 < level.size() ? join_block_hash_pieces({level[i], level[i + 1]})
                                          : level[i]);
    level = next;
  }
  EXPECT_EQ(finish_block_hash(level[0]), expected);
  const std::string left = join_block_hash_pieces({pieces[0], pieces[1], pieces[2]});
  const std::string right = join_block_hash_pieces({pieces[3], pieces[4], pieces[5], pieces[6]});
  EXPECT_EQ(finish_block_hash(join_block_hash_pieces({left, right, pieces[7]})), expected);
  // A joined piece that does not start the stream cannot be finished.
  EXPECT_THROW(finish_block_hash(right), Error);
}

}  // namespace
}  // namespace linebake
