#pragma once
// Vulkan acceleration structures over the cached assets (technique `rtx`, the paper's RTX
// column): one BLAS per chunk, over the tube mesh's triangles (default; the paper found them
// about 2x faster to trace than analytic tubes) or over capsule AABBs intersected analytically
// (shaders/rtx_capsules.rint), then one TLAS instancing them. The build is measured like the
// paper's Table 1: pre-build (worst-case) size, scratch, compacted size, GPU time; BLAS can be
// serialised for the cache and loaded back on a compatible device instead of rebuilt.

#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "accel/capsule_segments.hpp"
#include "render/vulkan/context.hpp"
#include "tubes/tube_mesh.hpp"

namespace linebake::vk {

enum class RtGeometry { Triangles, Capsules };
RtGeometry parse_rt_geometry(const std::string& name);  // triangles | capsules
const char* to_string(RtGeometry geometry);

struct BlasFigures {
  uint64_t primitives = 0;        // triangles or capsules
  uint64_t build_bytes = 0;       // pre-build accelerationStructureSize (worst case)
  uint64_t scratch_bytes = 0;     // pre-build buildScratchSize
  uint64_t compacted_bytes = 0;   // after compaction (= build_bytes without it)
  uint64_t serialized_bytes = 0;  // filled by serialize()
};

struct RtBuildFigures {
  RtGeometry geometry = RtGeometry::Triangles;
  bool compaction = true;
  bool loaded = false;  // from serialised BLAS instead of built
  double seconds = 0;   // wall: BLAS builds (or loads), compaction and the TLAS
  double upload_s = 0;  // geometry to device-local memory
  double gpu_blas_ms = 0, gpu_compact_ms = 0, gpu_tlas_ms = 0;  // GPU timestamps
  uint64_t geometry_bytes = 0;  // build inputs and shading data on the device
  uint64_t blas_bytes = 0;      // resident BLAS (compacted when on)
  uint64_t scratch_bytes = 0;   // one scratch buffer, reused by every BLAS build
  uint64_t tlas_bytes = 0, tlas_scratch_bytes = 0, instance_bytes = 0;
  // Device memory at the worst moment of the build: geometry, every uncompacted BLAS, the
  // compacted copies and the scratch (the paper's "2-3x the representation" for RTX).
  uint64_t peak_bytes = 0;
  std::vector<BlasFigures> blas;
  uint64_t resident_bytes() const {
    return geometry_bytes + blas_bytes + tlas_bytes + instance_bytes;
  }
};
nlohmann::json to_json(const RtBuildFigures& figures);

class RtScene {
 public:
  // Upload the geometry (device local) and the chunk table the hit shaders read. The context
  // must have ray tracing enabled; the mesh / capsules must outlive the scene.
  RtScene(Context& context, const TubeMesh& mesh);
  RtScene(Context& context, const CapsuleSegments& capsules);
  RtScene(const RtScene&) = delete;
  RtScene& operator=(const RtScene&) = delete;
  ~RtScene();

  // Builds one BLAS per chunk (compacting them on request) and the TLAS.
  void build(bool compaction);
  // Loads one serialised BLAS per chunk and builds the TLAS. Returns why the blobs cannot be
  // used (wrong count, another driver, the device's compatibility query, a bad header); the scene
  // is then unchanged and build() is the fallback.
  std::optional<std::string> load(const std::vector<std::vector<uint8_t>>& blobs);
  // One blob per BLAS (vkCmdCopyAccelerationStructureToMemoryKHR); fills serialized_bytes.
  std::vector<std::vector<uint8_t>> serialize();

  bool built() const;
  const RtBuildFigures& figures() const;
  RtGeometry geometry() const;
  VkAccelerationStructureKHR tlas() const;
  const Buffer& chunk_table() const;
  std::array<float, 2> attribute_range() const;  // decode range of stored attributes
  float capsule_radius() const;                  // 0 for triangles
  bool has_attribute() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace linebake::vk
