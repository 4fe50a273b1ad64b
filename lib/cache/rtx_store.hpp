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
};

// Writes the blobs and the provenance; fills provenance.disk_bytes.
void store_rtx(CacheWriter& cache, const StoredRtx& rtx, Provenance provenance);
// InputError naming the group or dataset when the description or a blob is missing or damaged.
StoredRtx load_rtx(const CacheReader& cache);

// The source string of capsule BLAS (StoredRtx::source): the lines' content hash, the radius
// and the attribute.
std::string rtx_capsules_source(const std::string& lines_hash, float radius,
                                const std::string& attribute);

}  // namespace linebake
