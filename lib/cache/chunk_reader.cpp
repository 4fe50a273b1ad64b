#include "cache/chunk_reader.hpp"

#include <algorithm>
#include <cstring>
#include <new>
#include <string>
#include <vector>

#include "cache/chunk_codec.hpp"
#include "core/error.hpp"
#include "core/h5.hpp"

namespace linebake {
namespace {

using h5::Handle;

// The codec of the cache's pipeline [shuffle, codec, fletcher32], or false for any other.
bool cache_codec(hid_t dcpl, size_t element, ChunkCodec& codec) {
  if (H5Pget_nfilters(dcpl) != 3) return false;
  H5Z_filter_t ids[3];
  for (unsigned f = 0; f < 3; ++f) {
    unsigned flags = 0, config = 0;
    size_t values = 0;
    ids[f] = H5Pget_filter2(dcpl, f, &flags, &values, nullptr, 0, nullptr, &config);
  }
  if (ids[0] != H5Z_FILTER_SHUFFLE || ids[2] != H5Z_FILTER_FLETCHER32) return false;
  codec.element_size = element;
  if (ids[1] == H5Z_FILTER_DEFLATE)
    codec.compression = Compression::Deflate;
  else if (ids[1] == kLz4Filter)
    codec.compression = Compression::Lz4;
  else if (ids[1] == kBloscFilter)
    codec.compression = Compression::BloscZstd;
  else
    return false;
  return true;
}

}  // namespace

bool read_cache_rows(hid_t dataset, hid_t memory_type, uint64_t first, uint64_t count, void* out) {
  Handle dcpl(H5Dget_create_plist(dataset), H5Pclose);
  Handle type(H5Dget_type(dataset), H5Tclose);
  if (!dcpl.valid() || !type.valid() || H5Pget_layout(dcpl) != H5D_CHUNKED ||
      H5Tequal(type, memory_type) <= 0)
    return false;
  const std::vector<hsize_t> dims = h5::shape_of(dataset);
  hsize_t chunk[2] = {0, 0};
  const int rank = H5Pget_chunk(dcpl, 2, chunk);
  if (rank != static_cast<int>(dims.size()) || rank < 1 || rank > 2 || chunk[0] == 0) return false;
  if (rank == 2 && chunk[1] != dims[1]) return false;  // chunked along rows only
  // linebake's chunks hold at most the dataset's rows: a larger chunk is a damaged header that
  // would size the decode buffer.
  if (chunk[0] > std::max<hsize_t>(dims[0], 1)) return false;
  const size_t element = H5Tget_size(type);
  ChunkCodec codec;
  if (!cache_codec(dcpl, element, codec)) return false;
  const uint64_t columns = rank == 2 ? dims[1] : 1, row_bytes = columns * element;
  const uint64_t chunk_rows = chunk[0], chunk_bytes = chunk_rows * row_bytes;
  if (first + count > dims[0] || count == 0) return count == 0;

  std::vector<char> stored, raw, scratch;
  char* dst = static_cast<char*>(out);
  for (uint64_t c = first / chunk_rows; c * chunk_rows < first + count; ++c) {
    const std::string where = "chunk " + std::to_string(c);
    const hsize_t offset[2] = {c * chunk_rows, 0};
    hsize_t size = 0;
    if (H5Dget_chunk_storage_size(dataset, offset, &size) < 0 || size == 0)
      throw Error(where + ": not stored (" + h5::last_error() + ")");
    // A stored chunk is at most its raw size, the codec's framing and the checksum, unless the
    // codec expanded it, which decode_chunk refuses anyway.
    if (size > chunk_bytes + chunk_bytes / 16 + 1024)
      throw Error(where + ": " + std::to_string(size) + " bytes stored for " +
                  std::to_string(chunk_bytes) + " raw");
    stored.resize(size);
    uint32_t mask = 0;
    if (H5Dread_chunk(dataset, H5P_DEFAULT, offset, &mask, stored.data()) < 0)
      throw Error(where + ": cannot read (" + h5::last_error() + ")");
    try {
      decode_chunk(codec, mask, stored.data(), stored.size(), chunk_bytes, raw, scratch);
    } catch (const Error& e) {
      throw Error(where + ": " + e.what());
    }
    const uint64_t from = std::max(first, c * chunk_rows);
    const uint64_t to = std::min(first + count, (c + 1) * chunk_rows);
    std::memcpy(dst + (from - first) * row_bytes, raw.data() + (from - c * chunk_rows) * row_bytes,
                (to - from) * row_bytes);
  }
  return true;
}

bool read_cache_rows_strict(hid_t dataset, hid_t memory_type, uint64_t first, uint64_t count,
                            void* out) {
  if (count == 0) return true;
  try {
    if (read_cache_rows(dataset, memory_type, first, count, out)) return true;
  } catch (const std::bad_alloc&) {
    // A chunk's size is checked against its raw size above: this is the process's memory.
    throw BudgetExceeded("a chunk needs more memory than this process could allocate (ulimit -v, "
                         "the cgroup's limit, or the machine's memory)");
  } catch (const Error& e) {
    throw Error(std::string(e.what()) + " (the data is corrupt)");
  }
  Handle dcpl(H5Dget_create_plist(dataset), H5Pclose);
  if (!dcpl.valid() || H5Pget_layout(dcpl) == H5D_CHUNKED)
    throw Error("chunked or filtered differently from what linebake writes: the cache is damaged");
  return false;
}

}  // namespace linebake
