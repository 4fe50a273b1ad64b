#pragma once
// The line set in the cache: group /lines (docs/cache.md), written whole or batch by batch.

#include <map>
#include <memory>
#include <string>

#include "cache/cache.hpp"
#include "core/hash.hpp"
#include "lines/line_set.hpp"

namespace linebake {

// XXH3-128 over every array and attribute name of a line set: the input hash of the assets
// built from it. Metadata is excluded. Each array is hashed on its own and the digests are
// hashed together with the names and counts, so the hash can be computed batch by batch.
// Where one rank's lines start in the whole line set (parallel writes, ParallelWrite): its
// first line and point, and whether it holds the very start (the offsets' leading 0).
struct LinePiece {
  uint64_t first_line = 0, first_point = 0;
  bool first = true;
  bool shared = false;  // one of several: hashes keep what they share with their neighbours
};

class LineContentHash {
 public:
  explicit LineContentHash(const LineSet& header, const LinePiece& piece = {});
  // One rank's share, serialised. join() and finish() make the whole set's hash from every
  // rank's up a tree of ranks: two adjacent pieces joined (the first's lines before the
  // second's), and the hash of the joined whole.
  std::string piece() const;
  static std::string join(const std::string& first, const std::string& second);
  static std::string finish(const LineSet& header, const std::string& whole);
  ~LineContentHash();
  void add(const LineSet& batch);
  std::string hex() const;

 private:
  std::vector<std::string> names_;  // "positions", "line_offsets", then the attributes
  std::vector<std::unique_ptr<BlockHasher>> arrays_;
  std::vector<uint64_t> counts_;
  uint64_t points_ = 0;
  static std::string hex_of(const std::vector<std::string>& names, size_t vertex_attributes,
                            const std::vector<uint64_t>& counts,
                            const std::vector<std::string>& array_hashes);
  size_t vertex_attributes_ = 0;
};
std::string content_hash(const LineSet& lines);

// Bytes the line set's datasets take in memory.
uint64_t line_set_bytes(const LineSet& lines);

// The figures of a line set that later steps need without reading it again (bounds, attribute
// ranges, counts), as kept in the /lines provenance `stats`.
nlohmann::json to_json(const LineSetStats& stats);
// Throws InputError naming the cache when the JSON lacks a field.
LineSetStats line_stats_from_json(const nlohmann::json& json, const std::string& cache);
// Grows `bounds` by the points of `dataset`, N x 3 floats (/lines/points, a tube chunk's
// positions), read `rows_per_read` rows at a time rather than whole. Throws InputError naming
// the dataset when it is not N x 3.
void include_dataset_points(Bounds& bounds, const CacheReader& cache, const std::string& dataset,
                            uint64_t rows_per_read = uint64_t{1} << 20);

// /lines written batch by batch; the datasets are created with the sizes in `stats`.
class LineStoreWriter {
 public:
  // `stats`: the whole set's; `piece`: where this rank's lines start (parallel writes).
  LineStoreWriter(CacheWriter& cache, const LineSet& header, const LineSetStats& stats,
                  const LinePiece& piece = {});
  void append(const LineSet& batch);
  // Writes the metadata and the provenance, with disk_bytes and memory_bytes filled in.
  void close(const std::map<std::string, std::string>& metadata, Provenance provenance);

 private:
  CacheWriter& cache_;
  LineSetStats stats_;
  DatasetStream points_, offsets_;
  std::vector<DatasetStream> attributes_, line_attributes_;
  uint64_t points_written_ = 0;
  std::vector<uint64_t> offsets_buffer_;
};

// Writes /lines with its metadata and provenance; fills provenance.disk_bytes.
void store_lines(CacheWriter& cache, const LineSet& lines, Provenance provenance);
LineSet load_lines(const CacheReader& cache);
// The lines' metadata alone (their origin, lines/origin.hpp, is what exports need of it).
std::map<std::string, std::string> load_line_metadata(const CacheReader& cache);

}  // namespace linebake
