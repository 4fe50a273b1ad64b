#pragma once
// Rows of a cache dataset read chunk by chunk with H5Dread_chunk and decoded by linebake's own
// codec (cache/chunk_codec.hpp), not by HDF5's filter pipeline: HDF5 1.10.8 copies a chunk whose
// filters return fewer bytes than the chunk holds past the end of their buffer
// (H5VM_memcpyvv <- H5D__select_read, found by the cache fuzzer; docs/reliability.md). Our decoder
// checks the Fletcher-32 sum first and every size against the chunk's.

#include <hdf5.h>

#include <cstdint>

namespace linebake {

// Reads rows [first, first + count) of `dataset` into `out` when its storage is the cache's own
// (chunked along rows only, filters shuffle, deflate | LZ4 | Blosc, Fletcher-32, in that order,
// a stored type equal to `memory_type`). Returns false, having read nothing, for any other
// dataset: the caller reads it with H5Dread. Throws Error naming the chunk on a damaged one.
bool read_cache_rows(hid_t dataset, hid_t memory_type, uint64_t first, uint64_t count, void* out);

// For a dataset of a cache, where linebake chunks every compressed dataset the one way
// read_cache_rows decodes: as read_cache_rows, and an Error (the cache is damaged) for any other
// chunked dataset, whose HDF5 filtered read is not safe in 1.10.8; a chunk too large for memory
// is an Error too. False only for a contiguous dataset: the caller reads it with H5Dread.
bool read_cache_rows_strict(hid_t dataset, hid_t memory_type, uint64_t first, uint64_t count,
                            void* out);

// Rows [first, first + count) of a chunked dataset of any program, each chunk read raw with
// H5Dread_chunk, decoded by linebake (its filters, in any order, among shuffle, Fletcher-32 and at
// most one of deflate, LZ4 and Blosc; or none), its size checked against the chunk's at every
// step, and converted to `memory_type` by H5Tconvert, as H5Dread converts. A chunk never written
// reads as the dataset's fill value. HDF5 1.10.8's own filtered read copies a chunk's nominal
// size out of a shorter filter output (found by fuzz_hdf5 in a line file, as by the cache fuzzer
// in a cache). Returns false, having read nothing, for a contiguous or compact dataset, one of
// rank above 2, or one with a filter linebake does not decode (scale-offset, N-bit, szip, ...):
// the caller reads it with H5Dread. Throws Error naming the chunk on a damaged one.
bool read_rows_checked(hid_t dataset, hid_t memory_type, uint64_t first, uint64_t count, void* out);

}  // namespace linebake
