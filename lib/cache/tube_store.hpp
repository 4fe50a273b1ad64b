#pragma once
// The tube mesh in the cache: group /assets/tubes, one subgroup per chunk (docs/cache.md).

#include <memory>

#include "cache/cache.hpp"
#include "tubes/tube_builder.hpp"
#include "tubes/tube_mesh.hpp"

namespace linebake {

constexpr const char* kTubesGroup = "/assets/tubes";

// Writes the mesh and its provenance; fills provenance.disk_bytes and memory_bytes.
void store_tubes(CacheWriter& cache, const TubeMesh& mesh, Provenance provenance);

// Writes a streamed tube build (TubeStreamBuilder) straight into the cache, chunk by chunk: the
// builder writes into staging buffers, which are appended to the chunk's datasets.
class TubeStoreSink : public TubeSink {
 public:
  // `mesh`: the builder's description (which arrays the chunks have).
  TubeStoreSink(CacheWriter& cache, const TubeMesh& mesh);
  // Parallel writes (ParallelWrite): the chunks' datasets are made collectively as the ranks reach
  // them (open_chunks) and closed once no rank will write to them (close_finished), on every rank
  // alike; this rank's rows begin in chunk `first_chunk` after the `first_vertices` and
  // `first_indices` of the lines before its own (the lower ranks'). `last_chunk`: the chunk of its
  // last line.
  TubeStoreSink(CacheWriter& cache, const TubeMesh& mesh, const std::vector<TubeChunkPlan>& plan,
                size_t first_chunk, uint64_t first_vertices, uint64_t first_indices,
                size_t last_chunk);
  ~TubeStoreSink() override;
  void begin_chunk(size_t chunk, const TubeChunkPlan& plan) override;
  TubeOutput reserve(size_t chunk, uint64_t vertices, uint64_t indices) override;
  void written(size_t chunk) override;
  void end_chunk(size_t chunk) override;
  // Parallel writes: the chunk that holds line `line` (of the whole set).
  size_t chunk_of_line(uint64_t line) const;
  // Parallel writes, collective: makes every chunk in the ranks' ranges that is not made yet, in
  // chunk order. `ranges`: each rank's first and last chunk of its next batch (first > last: none).
  void open_chunks(const std::vector<uint64_t>& ranges);
  // Parallel writes: the lowest chunk this rank may still write rows to (it writes its chunks in
  // order: those before it are done here), and the chunk of its last line.
  size_t frontier() const;
  size_t last_chunk() const;
  // Parallel writes, collective, after write_round: closes the open chunks no rank will write to
  // again. `ranks`: each rank's frontier (UINT64_MAX once it has built all its lines) and last
  // chunk. Thousands of small chunks' datasets had all been open at once (6,263 chunks: 457 MiB
  // a rank before a row was written).
  void close_finished(const std::vector<uint64_t>& ranks);
  // After the last chunk: the mesh description and the provenance (disk and memory bytes filled
  // in from what was written).
  void close(const TubeMesh& description, Provenance provenance);
  // Bytes of the staging buffers at their largest.
  uint64_t staging_bytes() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};
// Loads the mesh; uncompressed chunks are views of the mapped file.
TubeMesh load_tubes(const CacheReader& cache);
// The mesh's description (sides, radius, normal encoding, attribute, each chunk's lines) with
// its chunks' arrays empty; load_tube_chunk reads one chunk, so that a consumer which uploads or
// reduces a chunk at a time never holds the whole mesh.
TubeMesh load_tube_description(const CacheReader& cache);
TubeChunk load_tube_chunk(const CacheReader& cache, const TubeMesh& description, size_t index);
// What load_tube_chunk holds for chunk `index`, from its datasets' shapes (reading none), so
// that a consumer can check it against a memory budget first.
uint64_t tube_chunk_bytes(const CacheReader& cache, const TubeMesh& description, size_t index);
// Chunk `index`'s vertices and triangles, from its datasets' shapes.
TubeCounts tube_chunk_counts(const CacheReader& cache, size_t index);
// compute_bounds of the mesh, reading its positions `rows_per_read` vertices (12 MiB by
// default) at a time.
Bounds load_tube_bounds(const CacheReader& cache, uint64_t rows_per_read = uint64_t{1} << 20);
// The mesh's vertices and triangles from its datasets' shapes, reading none of them.
TubeCounts load_tube_counts(const CacheReader& cache);

}  // namespace linebake
