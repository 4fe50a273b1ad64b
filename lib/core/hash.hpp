#pragma once
// Content hashes for provenance and integrity: XXH3-128 (xxHash), printed as 32 hex digits.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace linebake {

class Hasher {
 public:
  Hasher();
  ~Hasher();
  Hasher(const Hasher&) = delete;
  Hasher& operator=(const Hasher&) = delete;
  Hasher& update(const void* data, size_t bytes);
  Hasher& update(std::string_view text);  // length-prefixed, so "ab"+"c" != "a"+"bc"
  Hasher& update(uint64_t value);
  std::string hex() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

std::string hash_bytes(const void* data, size_t bytes);
// Hash of a file's bytes; throws InputError if it cannot be read.
std::string hash_file(const std::string& path);

}  // namespace linebake

namespace linebake {

// XXH3-128 of a byte stream cut into 1 MiB blocks: the XXH3-128 of the blocks' XXH3-128 digests
// (canonical, big-endian) in order, the last block as long as it is. Unlike a flat hash, pieces
// of the stream can be hashed apart, by threads or MPI ranks, and combined: a piece keeps its
// whole blocks' digests and, raw, the bytes of the blocks it shares with its neighbours.
class BlockHasher {
 public:
  static constexpr uint64_t kBlockBytes = uint64_t{1} << 20;
  // A whole stream.
  BlockHasher();
  // A piece of a stream that starts at `first_byte`, to be combined with the others.
  struct Piece {
    uint64_t first_byte = 0;
    // The whole stream's length where known: a piece that reaches it hashes its last block
    // (shared with no later piece) at once instead of keeping its bytes raw until piece().
    uint64_t stream_bytes = UINT64_MAX;
  };
  explicit BlockHasher(Piece piece);
  ~BlockHasher();
  BlockHasher(const BlockHasher&) = delete;
  BlockHasher& operator=(const BlockHasher&) = delete;
  BlockHasher& update(const void* data, size_t bytes);
  uint64_t bytes() const { return next_ - first_; }
  // The whole stream's hash; the piece must start at byte 0.
  std::string hex() const;
  // This piece, serialised for combine_block_hashes (on another rank, say).
  std::string piece() const;

 private:
  void finish_block();
  uint64_t first_ = 0, next_ = 0;  // stream offsets of the first byte and the next one
  bool piece_ = false;
  std::string head_;           // bytes before the piece's first block boundary
  std::string digests_;        // 16 bytes per whole block after that boundary
  std::string tail_;           // bytes of the block in progress (not yet whole)
  uint64_t end_ = UINT64_MAX;  // the stream's length, where known
  std::string last_;           // the digest of the stream's last block, short of a whole one
  struct State;
  std::unique_ptr<State> block_;  // the block in progress, hashed as it arrives
};

// The hash of a stream from its pieces (BlockHasher::piece), given in any order; they must
// cover the stream from byte 0 without gaps or overlaps (InputError otherwise).
std::string combine_block_hashes(const std::vector<std::string>& pieces);
// The same in steps, for a reduction over a tree of ranks: adjacent pieces joined into one
// piece (associative: ((a b) c) = (a (b c))), and the hash of a piece that is the whole stream.
std::string join_block_hash_pieces(const std::vector<std::string>& pieces);
std::string finish_block_hash(const std::string& piece);

}  // namespace linebake
