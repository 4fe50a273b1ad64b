#include "cache/chunk_codec.hpp"

#include <blosc.h>
#include <hdf5.h>
#include <lz4.h>
#include <zlib.h>

#include <algorithm>
#include <cstring>

#include "core/error.hpp"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace linebake {

Compression parse_compression(const std::string& name) {
  if (name == "none") return Compression::None;
  if (name == "deflate") return Compression::Deflate;
  if (name == "lz4") return Compression::Lz4;
  if (name == "blosc-zstd") return Compression::BloscZstd;
  throw Error("unknown compression '" + name + "' (none | deflate | lz4 | blosc-zstd)");
}

const char* to_string(Compression compression) {
  switch (compression) {
    case Compression::None:
      return "none";
    case Compression::Deflate:
      return "deflate";
    case Compression::Lz4:
      return "lz4";
    case Compression::BloscZstd:
      return "blosc-zstd";
  }
  return "none";
}

namespace {

// memcpy for buffers that may be empty: its pointers must not be null even for 0 bytes, and an
// empty vector's data() may be (UBSan).
void copy_bytes(void* out, const void* in, size_t bytes) {
  if (bytes > 0) std::memcpy(out, in, bytes);
}

void put_be32(char* at, uint32_t v) {
  for (int i = 0; i < 4; ++i) at[i] = char(v >> (24 - 8 * i));
}
void put_be64(char* at, uint64_t v) {
  for (int i = 0; i < 8; ++i) at[i] = char(v >> (56 - 8 * i));
}
uint32_t get_be32(const char* at) {
  uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v = v << 8 | uint8_t(at[i]);
  return v;
}
uint64_t get_be64(const char* at) {
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v = v << 8 | uint8_t(at[i]);
  return v;
}

// Elements [first, n) of the generic transposition: out[k * n + i] = in[i * size + k].
void shuffle_scalar(const uint8_t* in, size_t n, size_t size, size_t first, uint8_t* out) {
  for (size_t i = first; i < n; ++i)
    for (size_t k = 0; k < size; ++k) out[k * n + i] = in[i * size + k];
}
void unshuffle_scalar(const uint8_t* in, size_t n, size_t size, size_t first, uint8_t* out) {
  for (size_t i = first; i < n; ++i)
    for (size_t k = 0; k < size; ++k) out[i * size + k] = in[k * n + i];
}

#if defined(__SSE2__)
// 16 elements per step, transposed with byte unpacks (SSE2, part of every x86-64): three rounds
// of interleaving bring byte k of the 16 elements together, a 64-bit unpack finishes the rows.
size_t shuffle4_sse2(const uint8_t* in, size_t n, uint8_t* out) {
  const size_t blocks = n / 16;
  for (size_t b = 0; b < blocks; ++b) {
    const auto* src = reinterpret_cast<const __m128i*>(in + 64 * b);
    const __m128i v0 = _mm_loadu_si128(src), v1 = _mm_loadu_si128(src + 1);
    const __m128i v2 = _mm_loadu_si128(src + 2), v3 = _mm_loadu_si128(src + 3);
    const __m128i t0 = _mm_unpacklo_epi8(v0, v1), t1 = _mm_unpackhi_epi8(v0, v1);
    const __m128i t2 = _mm_unpacklo_epi8(v2, v3), t3 = _mm_unpackhi_epi8(v2, v3);
    const __m128i u0 = _mm_unpacklo_epi8(t0, t1), u1 = _mm_unpackhi_epi8(t0, t1);
    const __m128i u2 = _mm_unpacklo_epi8(t2, t3), u3 = _mm_unpackhi_epi8(t2, t3);
    const __m128i w0 = _mm_unpacklo_epi8(u0, u1), w1 = _mm_unpackhi_epi8(u0, u1);
    const __m128i w2 = _mm_unpacklo_epi8(u2, u3), w3 = _mm_unpackhi_epi8(u2, u3);
    uint8_t* dst = out + 16 * b;
    _mm_storeu_si128(reinterpret_cast<__m128i*>(dst), _mm_unpacklo_epi64(w0, w2));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(dst + n), _mm_unpackhi_epi64(w0, w2));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(dst + 2 * n), _mm_unpacklo_epi64(w1, w3));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(dst + 3 * n), _mm_unpackhi_epi64(w1, w3));
  }
  return 16 * blocks;
}

size_t unshuffle4_sse2(const uint8_t* in, size_t n, uint8_t* out) {
  const size_t blocks = n / 16;
  for (size_t b = 0; b < blocks; ++b) {
    const uint8_t* src = in + 16 * b;
    const __m128i o0 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(src));
    const __m128i o1 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(src + n));
    const __m128i o2 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(src + 2 * n));
    const __m128i o3 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(src + 3 * n));
    const __m128i p0 = _mm_unpacklo_epi8(o0, o1), p1 = _mm_unpackhi_epi8(o0, o1);
    const __m128i p2 = _mm_unpacklo_epi8(o2, o3), p3 = _mm_unpackhi_epi8(o2, o3);
    auto* dst = reinterpret_cast<__m128i*>(out + 64 * b);
    _mm_storeu_si128(dst, _mm_unpacklo_epi16(p0, p2));
    _mm_storeu_si128(dst + 1, _mm_unpackhi_epi16(p0, p2));
    _mm_storeu_si128(dst + 2, _mm_unpacklo_epi16(p1, p3));
    _mm_storeu_si128(dst + 3, _mm_unpackhi_epi16(p1, p3));
  }
  return 16 * blocks;
}

size_t shuffle2_sse2(const uint8_t* in, size_t n, uint8_t* out) {
  const size_t blocks = n / 16;
  for (size_t b = 0; b < blocks; ++b) {
    const auto* src = reinterpret_cast<const __m128i*>(in + 32 * b);
    const __m128i v0 = _mm_loadu_si128(src), v1 = _mm_loadu_si128(src + 1);
    const __m128i t0 = _mm_unpacklo_epi8(v0, v1), t1 = _mm_unpackhi_epi8(v0, v1);
    const __m128i u0 = _mm_unpacklo_epi8(t0, t1), u1 = _mm_unpackhi_epi8(t0, t1);
    const __m128i w0 = _mm_unpacklo_epi8(u0, u1), w1 = _mm_unpackhi_epi8(u0, u1);
    uint8_t* dst = out + 16 * b;
    _mm_storeu_si128(reinterpret_cast<__m128i*>(dst), _mm_unpacklo_epi8(w0, w1));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(dst + n), _mm_unpackhi_epi8(w0, w1));
  }
  return 16 * blocks;
}

size_t unshuffle2_sse2(const uint8_t* in, size_t n, uint8_t* out) {
  const size_t blocks = n / 16;
  for (size_t b = 0; b < blocks; ++b) {
    const uint8_t* src = in + 16 * b;
    const __m128i o0 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(src));
    const __m128i o1 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(src + n));
    auto* dst = reinterpret_cast<__m128i*>(out + 32 * b);
    _mm_storeu_si128(dst, _mm_unpacklo_epi8(o0, o1));
    _mm_storeu_si128(dst + 1, _mm_unpackhi_epi8(o0, o1));
  }
  return 16 * blocks;
}
#endif

// Which pipeline steps a chunk went through: shuffle (bit 0), codec (bit 1), fletcher32 (bit 2).
constexpr unsigned kShuffleBit = 1, kCodecBit = 2, kFletcherBit = 4;

void encode_codec(const ChunkCodec& codec, const char* in, size_t bytes, std::vector<char>& out) {
  switch (codec.compression) {
    case Compression::Lz4: {
      // One block: the plugin's default block size (1 GiB) exceeds any chunk of ours.
      if (bytes > size_t(LZ4_MAX_INPUT_SIZE)) throw Error("lz4: chunk too large");
      out.resize(16 + size_t(LZ4_compressBound(int(bytes))));
      put_be64(out.data(), bytes);
      put_be32(out.data() + 8, uint32_t(bytes));
      int stored =
          bytes ? LZ4_compress_default(in, out.data() + 16, int(bytes), int(out.size() - 16)) : 0;
      if (stored <= 0 || size_t(stored) >= bytes) {
        stored = int(bytes);
        std::memcpy(out.data() + 16, in, bytes);
      }
      put_be32(out.data() + 12, uint32_t(stored));
      out.resize(16 + size_t(stored));
      return;
    }
    case Compression::Deflate: {
      uLongf stored = compressBound(uLong(bytes));
      out.resize(stored);
      if (compress2(reinterpret_cast<Bytef*>(out.data()), &stored,
                    reinterpret_cast<const Bytef*>(in), uLong(bytes),
                    codec.deflate_level()) != Z_OK)
        throw Error("deflate: compression failed");
      out.resize(stored);
      return;
    }
    case Compression::BloscZstd: {
      out.resize(bytes + BLOSC_MAX_OVERHEAD);
      // HDF5's shuffle already ran, so Blosc's own is off (the plugin's cd_values say the same).
      const int stored = blosc_compress_ctx(codec.blosc_level(), BLOSC_NOSHUFFLE,
                                            std::clamp<size_t>(codec.element_size, 1, 255), bytes,
                                            in, out.data(), out.size(), "zstd", 0, 1);
      if (stored <= 0) throw Error("blosc-zstd: compression failed (is zstd in this Blosc?)");
      out.resize(size_t(stored));
      return;
    }
    case Compression::None:
      out.assign(in, in + bytes);
      return;
  }
}

// The most each codec can expand its input, with room for headers: LZ4 255:1 (a match costs
// at least one byte per 255), deflate 1032:1 (zlib's technical notes), zstd about 2^17:1 (a
// run-length block of 128 KiB in 3 bytes of header and 1 of data). A stored chunk claiming more
// is damaged or hostile; it is refused before a buffer is sized from the claim.
uint64_t most_raw_bytes(Compression compression, size_t stored) {
  const uint64_t ratio = compression == Compression::Lz4         ? 255
                         : compression == Compression::Deflate   ? 1032
                         : compression == Compression::BloscZstd ? uint64_t{1} << 17
                                                                 : 1;
  return ratio * uint64_t(stored) + 1024;
}

}  // namespace

void decode_codec(const ChunkCodec& codec, const void* stored_bytes, size_t bytes, size_t raw_bytes,
                  std::vector<char>& out) {
  const char* in = static_cast<const char*>(stored_bytes);
  if (raw_bytes > most_raw_bytes(codec.compression, bytes))
    throw Error(std::string(to_string(codec.compression)) + ": a stored chunk of " +
                std::to_string(bytes) + " bytes cannot hold " + std::to_string(raw_bytes) +
                " raw bytes");
  out.resize(raw_bytes);
  switch (codec.compression) {
    case Compression::Lz4: {
      if (bytes < 12) throw Error("lz4: stored chunk shorter than its header");
      const uint64_t original = get_be64(in);
      uint64_t block = get_be32(in + 8);
      if (original != raw_bytes)
        throw Error("lz4: header says " + std::to_string(original) + " bytes, expected " +
                    std::to_string(raw_bytes));
      if (block == 0 && original > 0) throw Error("lz4: block size 0");
      size_t read = 12, written = 0;
      while (written < original) {
        const size_t this_block = size_t(std::min<uint64_t>(block, original - written));
        if (read + 4 > bytes) throw Error("lz4: stored chunk ends inside a block header");
        const size_t stored = get_be32(in + read);
        read += 4;
        if (stored > bytes - read) throw Error("lz4: block runs past the stored chunk");
        if (stored == this_block) {
          std::memcpy(out.data() + written, in + read, stored);
        } else {
          const int n =
              LZ4_decompress_safe(in + read, out.data() + written, int(stored), int(this_block));
          if (n != int(this_block)) throw Error("lz4: corrupt block");
        }
        read += stored;
        written += this_block;
      }
      return;
    }
    case Compression::Deflate: {
      uLongf n = uLongf(raw_bytes);
      if (uncompress(reinterpret_cast<Bytef*>(out.data()), &n, reinterpret_cast<const Bytef*>(in),
                     uLong(bytes)) != Z_OK ||
          n != raw_bytes)
        throw Error("deflate: corrupt stream");
      return;
    }
    case Compression::BloscZstd: {
      size_t nbytes = 0;
      if (bytes < BLOSC_MIN_HEADER_LENGTH || blosc_cbuffer_validate(in, bytes, &nbytes) < 0 ||
          nbytes != raw_bytes)
        throw Error("blosc: corrupt frame header");
      if (blosc_decompress_ctx(in, out.data(), raw_bytes, 1) != int(raw_bytes))
        throw Error("blosc: corrupt frame");
      return;
    }
    case Compression::None:
      if (bytes != raw_bytes) throw Error("stored chunk has the wrong size");
      copy_bytes(out.data(), in, bytes);
      return;
  }
}

void shuffle_bytes(const void* in_bytes, size_t bytes, size_t size, void* out_bytes) {
  const auto* in = static_cast<const uint8_t*>(in_bytes);
  auto* out = static_cast<uint8_t*>(out_bytes);
  const size_t n = size ? bytes / size : 0;
  if (size <= 1 || n <= 1) {  // as HDF5: nothing to shuffle
    copy_bytes(out, in, bytes);
    return;
  }
  size_t done = 0;
#if defined(__SSE2__)
  if (size == 4) done = shuffle4_sse2(in, n, out);
  if (size == 2) done = shuffle2_sse2(in, n, out);
#endif
  shuffle_scalar(in, n, size, done, out);
  std::memcpy(out + n * size, in + n * size, bytes - n * size);  // leftover bytes stay last
}

void unshuffle_bytes(const void* in_bytes, size_t bytes, size_t size, void* out_bytes) {
  const auto* in = static_cast<const uint8_t*>(in_bytes);
  auto* out = static_cast<uint8_t*>(out_bytes);
  const size_t n = size ? bytes / size : 0;
  if (size <= 1 || n <= 1) {
    copy_bytes(out, in, bytes);
    return;
  }
  size_t done = 0;
#if defined(__SSE2__)
  if (size == 4) done = unshuffle4_sse2(in, n, out);
  if (size == 2) done = unshuffle2_sse2(in, n, out);
#endif
  unshuffle_scalar(in, n, size, done, out);
  std::memcpy(out + n * size, in + n * size, bytes - n * size);
}

// HDF5 folds both sums to 16 bits every 360 words; the folds keep each sum's value modulo 65535
// and never turn a positive sum into 0. So the result is the exact sums modulo 65535, written
// 0xffff instead of 0 once any word was non-zero: the same value, computed here with 64-bit sums
// reduced every 2^16 words, which leaves the inner loop two dependent adds per word.
uint32_t fletcher32(const void* data, size_t bytes) {
  const auto* p = static_cast<const uint8_t*>(data);
  size_t words = bytes / 2;
  uint64_t sum1 = 0, sum2 = 0, any = 0;
  while (words) {
    const size_t n = std::min<size_t>(words, size_t{1} << 16);
    words -= n;
    for (size_t i = 0; i < n; ++i, p += 2) {
      const uint32_t word = uint32_t(p[0]) << 8 | p[1];
      any |= word;
      sum1 += word;
      sum2 += sum1;
    }
    sum1 %= 65535;
    sum2 %= 65535;
  }
  if (bytes % 2) {
    const uint32_t word = uint32_t(*p) << 8;
    any |= word;
    sum1 += word;
    sum2 += sum1;
    sum1 %= 65535;
    sum2 %= 65535;
  }
  if (!any) return 0;
  const uint32_t s1 = sum1 ? uint32_t(sum1) : 0xffff, s2 = sum2 ? uint32_t(sum2) : 0xffff;
  return s2 << 16 | s1;
}

void encode_chunk(const ChunkCodec& codec, const void* raw, size_t bytes, std::vector<char>& out,
                  std::vector<char>& scratch) {
  if (codec.compression == Compression::None) {
    out.assign(static_cast<const char*>(raw), static_cast<const char*>(raw) + bytes);
    return;
  }
  scratch.resize(bytes);
  shuffle_bytes(raw, bytes, codec.element_size, scratch.data());
  encode_codec(codec, scratch.data(), bytes, out);
  const uint32_t sum = fletcher32(out.data(), out.size());
  const size_t at = out.size();
  out.resize(at + 4);
  for (int i = 0; i < 4; ++i) out[at + size_t(i)] = char(sum >> (8 * i));  // little endian
}

size_t check_fletcher32(const void* stored_bytes, size_t bytes) {
  const char* stored = static_cast<const char*>(stored_bytes);
  if (bytes < 4) throw Error("stored chunk shorter than its checksum");
  const size_t payload = bytes - 4;
  uint32_t expected = 0;
  for (int i = 0; i < 4; ++i) expected |= uint32_t(uint8_t(stored[payload + size_t(i)])) << (8 * i);
  const uint32_t sum = fletcher32(stored, payload);
  // HDF5 before 1.6.3 stored the checksum byte-reversed; HDF5 accepts both, so do we.
  const uint32_t reversed =
      (sum & 0xff) << 24 | (sum & 0xff00) << 8 | (sum >> 8 & 0xff00) | sum >> 24;
  if (expected != sum && expected != reversed)
    throw Error("Fletcher-32 checksum mismatch: the stored chunk is corrupt");
  return payload;
}

void decode_chunk(const ChunkCodec& codec, unsigned filter_mask, const void* stored_bytes,
                  size_t bytes, size_t raw_bytes, std::vector<char>& out,
                  std::vector<char>& scratch) {
  const char* stored = static_cast<const char*>(stored_bytes);
  if (codec.compression == Compression::None) {
    decode_codec(codec, stored, bytes, raw_bytes, out);
    return;
  }
  const size_t payload = filter_mask & kFletcherBit ? bytes : check_fletcher32(stored, bytes);
  const char* data = stored;
  if (!(filter_mask & kCodecBit)) {
    decode_codec(codec, stored, payload, raw_bytes, scratch);
    data = scratch.data();
  } else if (payload != raw_bytes) {
    throw Error("stored chunk has the wrong size");
  }
  out.resize(raw_bytes);
  if (!(filter_mask & kShuffleBit))
    unshuffle_bytes(data, raw_bytes, codec.element_size, out.data());
  else
    copy_bytes(out.data(), data, raw_bytes);
}

}  // namespace linebake

// ---- as HDF5 filters ----

namespace linebake {
namespace {

// One direction of one codec on HDF5's buffer: replaces *buf with the result. 0 on failure, as
// HDF5 expects (it then reports the filter as failed).
size_t run_filter(Compression compression, unsigned flags, size_t cd_nelmts,
                  const unsigned cd_values[], size_t nbytes, size_t* buf_size, void** buf) {
  try {
    ChunkCodec codec{compression, -1, 1};
    if (compression == Compression::BloscZstd) {
      if (cd_nelmts > 2 && cd_values[2]) codec.element_size = cd_values[2];
      if (cd_nelmts > 4) codec.level = int(cd_values[4]);
    }
    std::vector<char> out;
    const char* in = static_cast<const char*>(*buf);
    if (flags & H5Z_FLAG_REVERSE) {
      size_t raw = 0;
      if (compression == Compression::Lz4) {
        if (nbytes < 12) return 0;
        raw = size_t(get_be64(in));
      } else {
        size_t cbytes = 0, blocksize = 0;
        if (nbytes < BLOSC_MIN_HEADER_LENGTH) return 0;
        blosc_cbuffer_sizes(in, &raw, &cbytes, &blocksize);
      }
      decode_codec(codec, in, nbytes, raw, out);
    } else {
      encode_codec(codec, in, nbytes, out);
    }
    void* result = H5allocate_memory(out.size(), false);
    if (!result) return 0;
    if (!out.empty()) std::memcpy(result, out.data(), out.size());
    H5free_memory(*buf);
    *buf = result;
    *buf_size = out.size();
    return out.size();
  } catch (const std::exception&) {
    return 0;
  }
}

size_t lz4_filter(unsigned flags, size_t n, const unsigned cd[], size_t nbytes, size_t* size,
                  void** buf) {
  return run_filter(Compression::Lz4, flags, n, cd, nbytes, size, buf);
}

size_t blosc_filter(unsigned flags, size_t n, const unsigned cd[], size_t nbytes, size_t* size,
                    void** buf) {
  return run_filter(Compression::BloscZstd, flags, n, cd, nbytes, size, buf);
}

// As the Blosc plugin does: the element size and chunk bytes go into cd_values 2 and 3.
herr_t blosc_set_local(hid_t dcpl, hid_t type, hid_t) {
  unsigned flags = 0, cd[7] = {};
  size_t n = 7;
  if (H5Pget_filter_by_id2(dcpl, kBloscFilter, &flags, &n, cd, 0, nullptr, nullptr) < 0) return -1;
  if (n < 4) n = 4;
  hsize_t chunk[32];
  const int rank = H5Pget_chunk(dcpl, 32, chunk);
  if (rank < 0) return -1;
  const size_t typesize = H5Tget_size(type);
  hsize_t bytes = typesize;
  for (int i = 0; i < rank; ++i) bytes *= chunk[i];
  cd[0] = 2;  // the plugin's filter revision
  cd[1] = 2;  // Blosc format version
  cd[2] = unsigned(typesize);
  cd[3] = unsigned(bytes);
  return H5Pmodify_filter(dcpl, kBloscFilter, flags, n, cd);
}

}  // namespace

void register_hdf5_filters() {
  static const H5Z_class2_t lz4{
      H5Z_CLASS_T_VERS, H5Z_filter_t(kLz4Filter), 1, 1, "lz4 (linebake)", nullptr, nullptr,
      lz4_filter};
  static const H5Z_class2_t blosc{H5Z_CLASS_T_VERS,
                                  H5Z_filter_t(kBloscFilter),
                                  1,
                                  1,
                                  "blosc (linebake)",
                                  nullptr,
                                  blosc_set_local,
                                  blosc_filter};
  // Registered over whatever is there: asking H5Zfilter_avail first would load the plugin.
  if (H5Zregister(&lz4) < 0) throw Error("cannot register the LZ4 filter with HDF5");
  if (H5Zregister(&blosc) < 0) throw Error("cannot register the Blosc filter with HDF5");
}

}  // namespace linebake
