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

// A dataset's pipeline as linebake decodes it: the filters in write order and the one codec's
// settings.
struct Pipeline {
  std::vector<H5Z_filter_t> ids;
  ChunkCodec codec_of;
};

bool decodable_pipeline(hid_t dcpl, size_t element, Pipeline& pipeline) {
  const int filters = H5Pget_nfilters(dcpl);
  if (filters < 0) return false;
  pipeline.codec_of.element_size = element;
  bool has_codec = false;
  for (int f = 0; f < filters; ++f) {
    unsigned flags = 0, config = 0;
    size_t values = 0;
    const H5Z_filter_t id =
        H5Pget_filter2(dcpl, unsigned(f), &flags, &values, nullptr, 0, nullptr, &config);
    const bool codec = id == H5Z_FILTER_DEFLATE || id == H5Z_filter_t(kLz4Filter) ||
                       id == H5Z_filter_t(kBloscFilter);
    if (!codec && id != H5Z_FILTER_SHUFFLE && id != H5Z_FILTER_FLETCHER32) return false;
    if (codec) {
      if (has_codec) return false;  // two codecs: the size between them is unknown
      has_codec = true;
      pipeline.codec_of.compression = id == H5Z_FILTER_DEFLATE         ? Compression::Deflate
                                      : id == H5Z_filter_t(kLz4Filter) ? Compression::Lz4
                                                                       : Compression::BloscZstd;
    }
    pipeline.ids.push_back(id);
  }
  return true;
}

// Undoes the pipeline on one stored chunk, last filter first; `raw_bytes` is the chunk's nominal
// size. Bit f of `mask` (H5Dread_chunk's) means filter f was skipped when the chunk was written.
void decode_pipeline(const Pipeline& pipeline, unsigned mask, std::vector<char>& data,
                     size_t raw_bytes, std::vector<char>& scratch) {
  for (int f = int(pipeline.ids.size()) - 1; f >= 0; --f) {
    if (mask & (1u << f)) continue;
    const H5Z_filter_t id = pipeline.ids[size_t(f)];
    if (id == H5Z_FILTER_FLETCHER32) {
      data.resize(check_fletcher32(data.data(), data.size()));
    } else if (id == H5Z_FILTER_SHUFFLE) {
      scratch.resize(data.size());
      unshuffle_bytes(data.data(), data.size(), pipeline.codec_of.element_size, scratch.data());
      data.swap(scratch);
    } else {
      // What the codec gave on write: the raw chunk and the checksums of sums before it.
      size_t expected = raw_bytes;
      for (int g = 0; g < f; ++g)
        if (pipeline.ids[size_t(g)] == H5Z_FILTER_FLETCHER32 && !(mask & (1u << g))) expected += 4;
      decode_codec(pipeline.codec_of, data.data(), data.size(), expected, scratch);
      data.swap(scratch);
    }
  }
  if (data.size() != raw_bytes)
    throw Error("decodes to " + std::to_string(data.size()) + " bytes, but a chunk holds " +
                std::to_string(raw_bytes));
}

}  // namespace

bool read_rows_checked(hid_t dataset, hid_t memory_type, uint64_t first, uint64_t count,
                       void* out) {
  Handle dcpl(H5Dget_create_plist(dataset), H5Pclose);
  Handle type(H5Dget_type(dataset), H5Tclose);
  if (!dcpl.valid() || !type.valid() || H5Pget_layout(dcpl) != H5D_CHUNKED) return false;
  const std::vector<hsize_t> dims = h5::shape_of(dataset);
  hsize_t chunk[2] = {0, 0};
  const int rank = H5Pget_chunk(dcpl, 2, chunk);
  if (rank != int(dims.size()) || rank < 1 || rank > 2 || chunk[0] == 0 ||
      (rank == 2 && chunk[1] == 0))
    return false;
  const size_t element = H5Tget_size(type), memory_element = H5Tget_size(memory_type);
  Pipeline pipeline;
  if (element == 0 || memory_element == 0 || !decodable_pipeline(dcpl, element, pipeline))
    return false;
  if (count == 0) return true;
  const uint64_t columns = rank == 2 ? dims[1] : 1, chunk_columns = rank == 2 ? chunk[1] : 1;
  if (first + count > dims[0])
    throw Error("rows " + std::to_string(first) + ".." + std::to_string(first + count) +
                " past the dataset's " + std::to_string(dims[0]));
  const uint64_t elements = chunk[0] * chunk_columns;
  // h5::damaged_storage and the walk keep a chunk within what HDF5 itself accepts (< 4 GiB).
  const uint64_t raw_bytes = elements * element;
  const uint64_t wide = std::max(element, memory_element);

  // The fill value a chunk never written reads as, in the memory type (0 where undefined).
  std::vector<char> fill(memory_element, 0);
  H5D_fill_value_t defined = H5D_FILL_VALUE_UNDEFINED;
  if (H5Pfill_value_defined(dcpl, &defined) >= 0 && defined != H5D_FILL_VALUE_UNDEFINED &&
      H5Pget_fill_value(dcpl, memory_type, fill.data()) < 0)
    std::fill(fill.begin(), fill.end(), 0);

  std::vector<char> data, scratch;
  char* dst = static_cast<char*>(out);
  const uint64_t last = first + count;
  for (uint64_t r0 = first / chunk[0] * chunk[0]; r0 < last; r0 += chunk[0]) {
    for (uint64_t c0 = 0; c0 < columns; c0 += chunk_columns) {
      const hsize_t offset[2] = {r0, c0};
      const auto where = [&] {
        return "the chunk at row " + std::to_string(r0) +
               (rank == 2 ? ", column " + std::to_string(c0) : std::string());
      };
      const uint64_t from = std::max(first, r0), to = std::min<uint64_t>(last, r0 + chunk[0]);
      const uint64_t c1 = std::min<uint64_t>(columns, c0 + chunk_columns);
      // The chunk's place in the index: none for a chunk never written.
      unsigned index_mask = 0;
      haddr_t address = HADDR_UNDEF;
      hsize_t stored = 0;
      if (H5Dget_chunk_info_by_coord(dataset, offset, &index_mask, &address, &stored) < 0)
        throw Error(where() + ": unreadable chunk index (" + h5::last_error() + ")");
      if (address == HADDR_UNDEF) stored = 0;
      if (stored == 0) {  // never written
        for (uint64_t r = from; r < to; ++r)
          for (uint64_t c = c0; c < c1; ++c)
            std::memcpy(dst + ((r - first) * columns + c) * memory_element, fill.data(),
                        memory_element);
        continue;
      }
      // A stored chunk is at most its raw size, a codec's framing and checksums, unless the
      // codec expanded it (HDF5 keeps such a chunk unfiltered instead).
      if (stored > raw_bytes + raw_bytes / 16 + 1024)
        throw Error(where() + ": " + std::to_string(stored) + " bytes stored for " +
                    std::to_string(raw_bytes) + " raw");
      data.resize(stored);
      uint32_t mask = 0;
      if (H5Dread_chunk(dataset, H5P_DEFAULT, offset, &mask, data.data()) < 0)
        throw Error(where() + ": cannot read (" + h5::last_error() + ")");
      try {
        decode_pipeline(pipeline, mask, data, raw_bytes, scratch);
      } catch (const Error& e) {
        throw Error(where() + ": " + e.what());
      }
      // HDF5's conversion, in place in a buffer wide enough for either type (numbers need no
      // background buffer).
      data.resize(elements * wide);
      if (H5Tconvert(type, memory_type, elements, data.data(), nullptr, H5P_DEFAULT) < 0)
        throw Error(where() + ": cannot convert its values (" + h5::last_error() + ")");
      for (uint64_t r = from; r < to; ++r)
        std::memcpy(dst + ((r - first) * columns + c0) * memory_element,
                    data.data() + ((r - r0) * chunk_columns) * memory_element,
                    (c1 - c0) * memory_element);
    }
  }
  return true;
}

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
    throw BudgetExceeded(
        "a chunk needs more memory than this process could allocate (ulimit -v, "
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
