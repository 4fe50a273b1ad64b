#pragma once
// Embree's prepared curve buffers in the cache: group /assets/embree (docs/cache.md). Embree
// BVHs cannot be serialised, so the cache keeps what a rebuild needs, and the provenance keeps
// what the build cost (prepare and commit time, BVH bytes from Embree's memory monitor).

#include <optional>
#include <string>
#include <vector>

#include "accel/embree_scene.hpp"
#include "cache/cache.hpp"

namespace linebake {

constexpr const char* kEmbreeGroup = "/assets/embree";

struct StoredCurves {
  EmbreeGeometry geometry = EmbreeGeometry::LinearCurve;
  float radius = 0;
  std::string attribute;
  std::vector<PreparedCurves> parts;
};

// Writes the buffers and the provenance; fills provenance.disk_bytes.
void store_embree(CacheWriter& cache, const StoredCurves& curves, Provenance provenance);
StoredCurves load_embree(const CacheReader& cache);

// Where one rank's lines start in a parallel cache (linebake-mpi): its first line, the part
// that holds it, and the points and segments of that part before it.
struct CurvePiece {
  uint64_t first_line = 0;
  size_t part = 0;
  uint64_t points_before = 0, segments_before = 0;
};

// Writes the buffers part by part as a streamed bake prepares them from its batches of lines.
// In a parallel cache every part's datasets are created up front, each rank writes its lines'
// rows from `piece` on, and close() is collective.
class EmbreeStoreWriter {
 public:
  EmbreeStoreWriter(CacheWriter& cache, std::vector<CurvePart> parts, EmbreeGeometry geometry,
                    float radius, std::string attribute, CurvePiece piece = {});
  // The batch's lines; they continue the previous batch's.
  void append(const LineSet& batch);
  // Writes the description and the provenance (disk_bytes filled in).
  void close(Provenance provenance);
  // Bytes of the buffers in memory, as a scene would hold them.
  uint64_t buffer_bytes() const { return buffer_bytes_; }
  // The parts planned: their count, and the segments (Embree's primitives) over all of them.
  size_t part_count() const { return parts_.size(); }
  uint64_t segments() const;

 private:
  struct PartStreams {
    std::optional<DatasetStream> vertices, indices, flags;
  };
  void open_part(size_t part);
  uint64_t close_part(size_t part);  // its disk bytes
  CacheWriter& cache_;
  std::vector<CurvePart> parts_;
  EmbreeGeometry geometry_;
  float radius_;
  std::string attribute_;
  size_t part_ = 0;  // the part being written
  bool open_ = false;
  uint64_t part_points_ = 0, part_segments_ = 0;  // written into the open part
  uint64_t line_ = 0;                             // the next line
  std::vector<PartStreams> streams_;              // by part: the open one (all of them in parallel)
  std::vector<float> vertex_buffer_;
  std::vector<uint32_t> index_buffer_;
  std::vector<uint8_t> flag_buffer_;
  uint64_t disk_ = 0, buffer_bytes_ = 0;
};

}  // namespace linebake
