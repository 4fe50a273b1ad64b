#pragma once
// The line set in the cache: group /lines (docs/cache.md).

#include <string>

#include "cache/cache.hpp"
#include "lines/line_set.hpp"

namespace linebake {

// XXH3-128 over every array and attribute name of a line set: the input hash of the assets
// built from it. Metadata is excluded.
std::string content_hash(const LineSet& lines);

// Bytes the line set's datasets take in memory.
uint64_t line_set_bytes(const LineSet& lines);

// Writes /lines with its metadata and provenance; fills provenance.disk_bytes.
void store_lines(CacheWriter& cache, const LineSet& lines, Provenance provenance);
LineSet load_lines(const CacheReader& cache);

}  // namespace linebake
