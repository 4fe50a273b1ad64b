#pragma once
// The cache's HDF5 filter pipeline, run by linebake itself so that chunks compress on every core:
// HDF5 applies filters on the one thread that calls H5Dwrite. Each step stores exactly what the
// HDF5 filter (or the registered plugin) of that name stores, so the chunks, written with
// H5Dwrite_chunk, read back through stock HDF5's ordinary filtered path (h5dump, h5py):
//   shuffle     HDF5's byte shuffle, H5Z_FILTER_SHUFFLE: byte k of every element, then byte k+1
//   deflate     a zlib stream (compress2), H5Z_FILTER_DEFLATE
//   lz4         filter 32004's framing: big-endian original size (8 bytes) and block size
//               (4 bytes), then per block its big-endian stored size and the LZ4 block, or the
//               raw block when LZ4 does not shrink it (stored size = block size)
//   blosc-zstd  one Blosc 1 frame with zstd, filter 32001
//   fletcher32  HDF5's Fletcher-32 of the filtered bytes, appended little endian,
//               H5Z_FILTER_FLETCHER32
// The pipeline order is the dataset's: shuffle, then the codec, then Fletcher-32.

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace linebake {

enum class Compression { None, Deflate, Lz4, BloscZstd };
Compression parse_compression(const std::string& name);  // none | deflate | lz4 | blosc-zstd
const char* to_string(Compression compression);

// Registered HDF5 filter ids of the plugins (The HDF Group's list of registered filters).
constexpr unsigned kLz4Filter = 32004;
constexpr unsigned kBloscFilter = 32001;
constexpr unsigned kBloscZstd = 5;  // Blosc's compressor code for zstd

struct ChunkCodec {
  Compression compression = Compression::Lz4;
  int level = -1;           // deflate 1-9 (default 4), blosc-zstd 1-9 (default 5); lz4 has none
  size_t element_size = 1;  // bytes per element: the shuffle's stride and Blosc's typesize

  int deflate_level() const { return level < 0 ? 4 : level; }
  int blosc_level() const { return level < 0 ? 5 : level; }
};

// Raw chunk -> the bytes HDF5 stores for it with every filter applied (filter mask 0). `out` is
// resized; `scratch` is working space kept by the caller so repeated calls allocate nothing.
void encode_chunk(const ChunkCodec& codec, const void* raw, size_t bytes, std::vector<char>& out,
                  std::vector<char>& scratch);

// Stored chunk -> raw bytes. `filter_mask` is H5Dread_chunk's: bit i set means filter i of the
// pipeline (shuffle, codec, fletcher32) was skipped when the chunk was written. Throws Error
// naming what failed (checksum, codec) on damaged bytes; the caller adds the file and dataset.
void decode_chunk(const ChunkCodec& codec, unsigned filter_mask, const void* stored, size_t bytes,
                  size_t raw_bytes, std::vector<char>& out, std::vector<char>& scratch);

// The building blocks, exposed for tests and for chunks of other programs' pipelines
// (cache/chunk_reader.hpp).
// One codec's stored bytes -> exactly `raw_bytes` (`out` resized); an Error for anything else,
// and before anything is sized when `bytes` cannot hold that many (most_raw_bytes).
void decode_codec(const ChunkCodec& codec, const void* stored, size_t bytes, size_t raw_bytes,
                  std::vector<char>& out);
// Checks the Fletcher-32 sum HDF5 appended to a stored chunk (either byte order, as HDF5
// accepts) and returns the size without it; an Error on a mismatch or a chunk under 4 bytes.
size_t check_fletcher32(const void* stored, size_t bytes);
// HDF5's shuffle and its Fletcher-32:
void shuffle_bytes(const void* in, size_t bytes, size_t element_size, void* out);
void unshuffle_bytes(const void* in, size_t bytes, size_t element_size, void* out);
// HDF5's H5_checksum_fletcher32: 16-bit big-endian words, sums folded to 16 bits.
uint32_t fletcher32(const void* data, size_t bytes);

}  // namespace linebake

namespace linebake {

// Registers linebake's own LZ4 (32004) and Blosc-zstd (32001) codecs as HDF5 filters, for both
// directions, in place of Debian's plugins: a process whose HDF5 cannot load those plugins uses
// them (linebake-mpi: the plugins link the serial HDF5, and parallel HDF5 compresses the chunks
// of a collective write itself). Chunks compress to what the plugins store. Safe to call twice.
void register_hdf5_filters();

}  // namespace linebake
