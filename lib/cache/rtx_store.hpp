#pragma once
// Serialised Vulkan BLAS in the cache: group /assets/rtx (docs/cache.md). The blobs only load on
// the driver that wrote them (its UUID is in every blob's header and in the group's description);
// the provenance keeps what the build cost on that device.

#include <cstdint>
#include <string>
#include <vector>

#include "cache/cache.hpp"

namespace linebake {

constexpr const char* kRtxGroup = "/assets/rtx";

struct StoredRtx {
  std::string geometry;  // triangles | capsules
  bool compaction = true;
  // What the BLAS were built from: the tube step's provenance key (triangles), or the line set's
  // content hash with the capsule radius and attribute (capsules). A render uses the blobs only
  // when its own source string is equal.
  std::string source;
  std::string device, driver, driver_uuid;  // the device that built them; UUID as 32 hex digits
  std::vector<std::vector<uint8_t>> blobs;  // one per BLAS (chunk), as serialised
  // From the cache's datasets, before the blobs are read (load_rtx_description): how many, and
  // the bytes of all and of the largest.
  size_t blas = 0;
  uint64_t blob_bytes = 0, largest_blob_bytes = 0;
};

// Writes the blobs and the provenance; fills provenance.disk_bytes.
void store_rtx(CacheWriter& cache, const StoredRtx& rtx, Provenance provenance);
// InputError naming the group or dataset when the description or a blob is missing or damaged.
StoredRtx load_rtx(const CacheReader& cache);
// The description and the blobs' sizes, without the blobs (which can take gigabytes of host
// memory to read: a render reads them only when it will use them, and when they fit).
StoredRtx load_rtx_description(const CacheReader& cache);
// Reads a description's blobs into it (at most its blob_bytes and one blob more in memory).
void load_rtx_blobs(const CacheReader& cache, StoredRtx& rtx);

// The source string of capsule BLAS (StoredRtx::source): the lines' content hash, the radius
// and the attribute.
std::string rtx_capsules_source(const std::string& lines_hash, float radius,
                                const std::string& attribute);

}  // namespace linebake
