#pragma once
// Line set -> tube mesh (techniques.md section 10), multithreaded with byte-identical output
// for any thread count, whole (build_tubes) or batch by batch (TubeStreamBuilder) with the same
// bytes.

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/progress.hpp"
#include "lines/line_set.hpp"
#include "tubes/tube_mesh.hpp"

namespace linebake {

struct TubeOptions {
  int sides = 3;  // ring vertices per point, 3..32
  // Tube radius; a fraction of the bounding-box diagonal unless radius_absolute.
  float radius = 0.001f;
  bool radius_absolute = false;
  // Per-point radius from an attribute: radius * value / max(value); values <= 0 or non-finite
  // give 1% of the radius so no ring collapses.
  std::string radius_attribute;
  bool caps = false;  // close each tube with a fan at both ends
  NormalEncoding normals = NormalEncoding::Float32;
  // Stored attribute: a vertex or line attribute by name; "" picks the first vertex attribute;
  // "none" stores none.
  std::string attribute;
  std::optional<std::array<float, 2>> attribute_range;  // default: the attribute's finite range
  uint64_t max_chunk_bytes = uint64_t{4} << 30;         // the paper's 4 GiB addressing limit
  uint64_t max_chunk_indices = 0xFFFFFFFFull;           // 32-bit indices
  // Points closer than this to the previous kept point are skipped (fraction of the diagonal).
  float min_point_distance = 1e-6f;
};

// The tube radius in world units: options.radius x the bounding-box diagonal, or as given.
float world_radius(const LineSet& lines, const TubeOptions& options);
float world_radius(const Bounds& bounds, const TubeOptions& options);

// Throws linebake::Error for options out of range or a line too large for one chunk.
TubeMesh build_tubes(const LineSet& lines, const TubeOptions& options,
                     const ProgressFn& progress = {});

// Lines [first_line, first_line + line_count) make one chunk of `vertices` and `indices`.
struct TubeChunkPlan {
  uint64_t first_line = 0, line_count = 0, vertices = 0, indices = 0;
};

// Where the next `vertices` vertices and `indices` indices of a chunk are to be written; the
// arrays a chunk does not have (normals or normals_oct, attribute) are null.
struct TubeOutput {
  float* positions = nullptr;
  float* normals = nullptr;
  int16_t* normals_oct = nullptr;
  uint16_t* attribute = nullptr;
  uint32_t* indices = nullptr;
};

// Receives a streamed build's mesh chunk by chunk, each chunk front to back.
class TubeSink {
 public:
  virtual ~TubeSink() = default;
  virtual void begin_chunk(size_t chunk, const TubeChunkPlan& plan) = 0;
  // Memory for the chunk's next vertices and indices, valid until written().
  virtual TubeOutput reserve(size_t chunk, uint64_t vertices, uint64_t indices) = 0;
  // The reserved memory holds the data.
  virtual void written(size_t chunk) = 0;
  virtual void end_chunk(size_t chunk) = 0;
};

// The tube build over a line set given batch by batch (lines/line_reader.hpp), in two passes
// over the same batches: plan() decides which points take part and where the chunks end,
// build() makes the rings and triangles. The global choices (radius, attribute range) come
// from the line set's statistics, so the mesh equals build_tubes' for any batches.
class TubeStreamBuilder {
 public:
  TubeStreamBuilder(const LineSet& header, const LineSetStats& stats, const TubeOptions& options);
  ~TubeStreamBuilder();
  void plan(const LineSet& batch);
  // plan() in two halves, for a line set split over processes (MPI ranks): each counts the
  // points its lines keep, then one process plans the whole set from all the counts, in line
  // order, with the points the counts leave out; the others adopt its plan (adopt_plan).
  std::vector<uint64_t> kept_points(const LineSet& batch) const;
  void plan_kept(const std::vector<uint64_t>& kept, uint64_t points_skipped);
  // Where a line's vertices and indices start: its chunk, and the vertices and indices of that
  // chunk's lines before it (after finish_plan()).
  struct Position {
    size_t chunk = 0;
    uint64_t vertices = 0, indices = 0;
  };
  Position position_of(uint64_t line) const;
  // Instead of planning: the plan one process made (finish_plan() there, with the whole set's
  // dropped lines and skipped points), and the kept points of this process's lines only, from
  // `first_line`, whose build() starts at `start` (position_of(first_line) there). Only the
  // planning process holds 8 bytes per line of the whole set.
  void adopt_plan(std::vector<TubeChunkPlan> chunks, uint64_t total_lines, uint64_t lines_dropped,
                  uint64_t points_skipped, std::vector<uint64_t> kept, uint64_t first_line,
                  const Position& start);
  // After the last plan(): the chunks. Throws Error when no line has two distinct points.
  const std::vector<TubeChunkPlan>& finish_plan();
  void build(const LineSet& batch, TubeSink& sink);
  // The mesh without its chunks: sides, radius, attribute, dropped lines, skipped points.
  const TubeMesh& description() const;
  // Vertex and index bytes of the lines in a batch (what build() asks the sink for).
  uint64_t output_bytes(uint64_t first_line, uint64_t line_count) const;
  uint64_t vertex_bytes() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace linebake
