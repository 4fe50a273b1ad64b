#include "core/hash.hpp"

#include <xxhash.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <vector>

#include "core/error.hpp"

namespace linebake {

struct Hasher::State {
  XXH3_state_t* state = XXH3_createState();
  ~State() { XXH3_freeState(state); }
};

Hasher::Hasher() : state_(std::make_unique<State>()) {
  XXH3_128bits_reset(state_->state);
}
Hasher::~Hasher() = default;

Hasher& Hasher::update(const void* data, size_t bytes) {
  XXH3_128bits_update(state_->state, data, bytes);
  return *this;
}

Hasher& Hasher::update(std::string_view text) {
  update(uint64_t{text.size()});
  return update(text.data(), text.size());
}

Hasher& Hasher::update(uint64_t value) {
  return update(&value, sizeof value);
}

static std::string to_hex(XXH128_hash_t h) {
  char text[33];
  std::snprintf(text, sizeof text, "%016llx%016llx", static_cast<unsigned long long>(h.high64),
                static_cast<unsigned long long>(h.low64));
  return text;
}

std::string Hasher::hex() const {
  return to_hex(XXH3_128bits_digest(state_->state));
}

std::string hash_bytes(const void* data, size_t bytes) {
  return to_hex(XXH3_128bits(data, bytes));
}

std::string hash_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "", "cannot open");
  Hasher hasher;
  constexpr size_t kBuffer = size_t{1} << 18;
  const std::unique_ptr<char[]> buffer(new char[kBuffer]);  // not zeroed: it is read into
  while (in) {
    in.read(buffer.get(), static_cast<std::streamsize>(kBuffer));
    hasher.update(buffer.get(), static_cast<size_t>(in.gcount()));
  }
  if (in.bad()) throw InputError(path, "", "read error");
  return hasher.hex();
}

}  // namespace linebake

namespace linebake {

namespace {

void put_digest(std::string& out, XXH128_hash_t h) {
  XXH128_canonical_t c;
  XXH128_canonicalFromHash(&c, h);
  out.append(reinterpret_cast<const char*>(c.digest), sizeof c.digest);
}

void put_u64(std::string& out, uint64_t v) {
  out.append(reinterpret_cast<const char*>(&v), sizeof v);
}

uint64_t get_u64(const std::string& in, size_t& at) {
  if (at + 8 > in.size()) throw Error("block hash piece is truncated");
  uint64_t v;
  std::memcpy(&v, in.data() + at, 8);
  at += 8;
  return v;
}

std::string get_bytes(const std::string& in, size_t& at) {
  const uint64_t n = get_u64(in, at);
  if (n > in.size() - at) throw Error("block hash piece is truncated");
  std::string s = in.substr(at, n);
  at += n;
  return s;
}

}  // namespace

struct BlockHasher::State {
  XXH3_state_t* state = XXH3_createState();
  ~State() { XXH3_freeState(state); }
};

BlockHasher::BlockHasher() : block_(std::make_unique<State>()) {
  XXH3_128bits_reset(block_->state);
}

BlockHasher::BlockHasher(Piece piece) : BlockHasher() {
  first_ = next_ = piece.first_byte;
  end_ = piece.stream_bytes;
  piece_ = true;
}
BlockHasher::~BlockHasher() = default;

void BlockHasher::finish_block() {
  put_digest(digests_, XXH3_128bits_digest(block_->state));
  XXH3_128bits_reset(block_->state);
  tail_.clear();
}

BlockHasher& BlockHasher::update(const void* data, size_t bytes) {
  const char* p = static_cast<const char*>(data);
  while (bytes > 0) {
    const uint64_t in_block = next_ % kBlockBytes;
    const size_t take = size_t(std::min<uint64_t>(bytes, kBlockBytes - in_block));
    // Before the piece's first boundary the block is shared with the piece before: kept raw.
    const bool head = first_ % kBlockBytes != 0 && next_ / kBlockBytes == first_ / kBlockBytes;
    if (head) {
      head_.append(p, take);
    } else {
      XXH3_128bits_update(block_->state, p, take);
      // A block not yet whole may be the next piece's too: kept raw until it is whole.
      if (piece_ && (in_block + take < kBlockBytes || !tail_.empty())) tail_.append(p, take);
    }
    next_ += take;
    p += take;
    bytes -= take;
    if (!head && next_ % kBlockBytes == 0) finish_block();
  }
  // The stream's last block, short of a whole one, ends here: no later piece shares it (a
  // stream of many small datasets had kept every one raw: 1.4 GiB a rank under MPI).
  if (piece_ && next_ == end_ && !tail_.empty()) {
    put_digest(last_, XXH3_128bits_digest(block_->state));
    tail_.clear();
    tail_.shrink_to_fit();
  }
  return *this;
}

std::string BlockHasher::piece() const {
  std::string out;
  put_u64(out, first_);
  put_u64(out, head_.size());
  out += head_;
  put_u64(out, digests_.size());
  out += digests_;
  put_u64(out, tail_.size());
  out += tail_;
  put_u64(out, last_.size());
  out += last_;
  return out;
}

std::string BlockHasher::hex() const {
  if (first_ != 0) throw Error("BlockHasher::hex: the piece does not start the stream");
  std::string digests = digests_;
  if (next_ % kBlockBytes != 0) put_digest(digests, XXH3_128bits_digest(block_->state));
  return to_hex(XXH3_128bits(digests.data(), digests.size()));
}

namespace {

struct ParsedPiece {
  uint64_t first = 0;
  std::string head, digests, tail;
  std::string last;  // the stream's short last block's digest: the piece ends the stream
};

ParsedPiece parse_piece(const std::string& text) {
  size_t at = 0;
  ParsedPiece p;
  p.first = get_u64(text, at);
  p.head = get_bytes(text, at);
  p.digests = get_bytes(text, at);
  p.tail = get_bytes(text, at);
  p.last = get_bytes(text, at);
  if (p.digests.size() % 16 || (p.last.size() != 0 && p.last.size() != 16) ||
      (!p.last.empty() && !p.tail.empty()))
    throw Error("block hash piece is damaged");
  return p;
}

std::string serialise(const ParsedPiece& p) {
  std::string out;
  put_u64(out, p.first);
  put_u64(out, p.head.size());
  out += p.head;
  put_u64(out, p.digests.size());
  out += p.digests;
  put_u64(out, p.tail.size());
  out += p.tail;
  put_u64(out, p.last.size());
  out += p.last;
  return out;
}

}  // namespace

std::string join_block_hash_pieces(const std::vector<std::string>& pieces) {
  std::vector<ParsedPiece> parsed;
  for (const std::string& text : pieces) {
    ParsedPiece p = parse_piece(text);
    if (!p.head.empty() || !p.digests.empty() || !p.tail.empty() || !p.last.empty())
      parsed.push_back(std::move(p));
  }
  std::sort(parsed.begin(), parsed.end(),
            [](const ParsedPiece& a, const ParsedPiece& b) { return a.first < b.first; });
  ParsedPiece out;
  if (parsed.empty()) return serialise(out);
  out.first = parsed.front().first;
  const uint64_t B = BlockHasher::kBlockBytes;
  std::string block;  // raw bytes since the last block boundary
  uint64_t at = out.first;
  const auto add_raw = [&](const std::string& bytes) {
    for (size_t i = 0; i < bytes.size();) {
      const size_t take = std::min<size_t>(bytes.size() - i, B - at % B);
      block.append(bytes, i, take);
      i += take;
      at += take;
      if (at % B != 0) continue;
      if (block.size() == B)  // a whole block: its digest
        put_digest(out.digests, XXH3_128bits(block.data(), block.size()));
      else  // the end of a block that began before the joined pieces: theirs to share
        out.head = block;
      block.clear();
    }
  };
  for (const ParsedPiece& p : parsed) {
    if (!out.last.empty()) throw Error("a block hash piece follows the stream's end");
    if (p.first != at)
      throw Error("block hash pieces leave a gap or overlap at byte " + std::to_string(at));
    add_raw(p.head);
    if (!p.digests.empty()) {
      if (!block.empty() || at % B != 0) throw Error("block hash piece is not aligned");
      out.digests += p.digests;
      at += p.digests.size() / 16 * B;
    }
    add_raw(p.tail);
    if (!p.last.empty()) {
      if (!block.empty() || at % B != 0) throw Error("block hash piece is not aligned");
      out.last = p.last;
    }
  }
  out.tail = block;
  return serialise(out);
}

std::string finish_block_hash(const std::string& piece) {
  const ParsedPiece p = parse_piece(piece);
  if (p.first != 0 || !p.head.empty())
    throw Error("block hash pieces do not start at byte 0 (byte " + std::to_string(p.first) + ")");
  std::string digests = p.digests;
  if (!p.tail.empty()) put_digest(digests, XXH3_128bits(p.tail.data(), p.tail.size()));
  digests += p.last;
  return to_hex(XXH3_128bits(digests.data(), digests.size()));
}

std::string combine_block_hashes(const std::vector<std::string>& pieces) {
  return finish_block_hash(join_block_hash_pieces(pieces));
}

}  // namespace linebake
