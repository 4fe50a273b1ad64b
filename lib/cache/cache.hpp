#pragma once
// The asset cache: one HDF5 file per data set holding the line set and every asset built from
// it, each in its own group with its provenance (docs/cache.md). Datasets carry an XXH3-128
// hash of their bytes, checked on load; compressed ones also carry HDF5's Fletcher32 checksum.
// Uncompressed datasets are contiguous and 4 KiB aligned, and load as views of a read-only
// mapping of the file (no copy).

#include <hdf5.h>

#include <cstdint>
#include <functional>
#include <initializer_list>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "cache/chunk_codec.hpp"
#include "core/array.hpp"
#include "core/atomic_file.hpp"
#include "core/h5.hpp"
#include "core/measure.hpp"
#include "core/progress.hpp"

namespace linebake {

// What a cached step was built from, with what, and what it cost.
struct Provenance {
  std::string step;        // "lines", "tubes", ...
  std::string key;         // hash of input_hash, parameters and the step's storage version
  std::string input_hash;  // content hash of the input (file bytes, or the line set's arrays)
  nlohmann::json parameters = nlohmann::json::object();
  nlohmann::json stats = nlohmann::json::object();  // step-specific counts
  std::string linebake_version = LINEBAKE_VERSION;
  std::string created;  // UTC, ISO 8601
  StepFigures build;
  uint64_t threads = 0;
  uint64_t memory_bytes = 0;  // the representation in memory
  uint64_t disk_bytes = 0;    // its datasets as stored
  std::string compression;
  int compression_level = -1;         // -1: the codec's default (and caches before 2026-11-30)
  uint64_t memory_budget = 0;         // the bake's budget (0: unlimited)
  uint64_t spill_bytes = 0;           // what the step wrote to temporary files beside the cache
  uint64_t estimated_disk_bytes = 0;  // what the bake expected disk_bytes to be (0: no estimate)
};
nlohmann::json to_json(const Provenance& provenance);
Provenance provenance_from_json(const nlohmann::json& json);
std::string utc_now_iso8601();

using h5::decode_link_name;
using h5::encode_link_name;

class CacheWriter;
class DatasetStream;

// A cache written by several processes at once: MPI ranks through parallel HDF5, set up by the
// caller (linebake-mpi), so that this library itself needs no MPI. Every rank makes the same
// calls in the same order with the same values. A dataset's rows are one contiguous range per
// rank, in rank order (DatasetStream::start_at); they are buffered and written by
// CacheWriter::write_round(), one collective H5Dwrite per dataset that has rows on any rank, in
// which HDF5 compresses the chunks. Dataset hashes combine every rank's piece (BlockHasher).
struct ParallelWrite {
  hid_t fapl = -1;        // file access with the MPI-IO driver (H5Pset_fapl_mpio)
  hid_t dxpl = -1;        // collective transfer (H5Pset_dxpl_mpio)
  std::string temp_path;  // the temporary file, the same on every rank
  bool owner = false;     // this rank renames it on commit (rank 0) or removes it on failure
  // The collectives, none of which sends a rank more than a few of its neighbours' pieces:
  // the byte-wise OR of every rank's bytes (all of one length), on every rank;
  std::function<void(std::string& bytes)> any;
  // the sum over the ranks, on every rank;
  std::function<uint64_t(uint64_t)> sum;
  // every rank's string joined in rank order by `join` (associative) up a tree of ranks,
  // `finish` applied to the whole on one rank, and its result on every rank (an Error thrown by
  // `finish` is thrown on every rank).
  using Join = std::function<std::string(const std::string& first, const std::string& second)>;
  using Finish = std::function<std::string(const std::string& whole)>;
  std::function<std::string(const std::string& mine, const Join& join, const Finish& finish)>
      reduce;
};

// One append of `rows` rows of `element`-byte values (see append_together).
struct StreamAppend {
  DatasetStream* stream;
  const void* data;
  size_t element;
  uint64_t rows;
};
// Appends to several datasets at once: their chunks are encoded in one pipeline, so the writes
// of one dataset overlap the encoding of the next (a tube chunk's four arrays, for one).
void append_together(std::span<const StreamAppend> appends);
// Memory the compressed chunks of one append_together in flight take at the most, whatever the
// data, with as many pipeline tokens as the threads use (twice the TBB threads and one): per
// token an encoded chunk (up to 1 MiB and the codec's bound), and a shuffle buffer (1 MiB) per
// thread. A writer's chunks_in_flight_limit may hold fewer tokens (at least 2).
uint64_t chunks_in_flight_wanted_bytes();
inline void append_together(std::initializer_list<StreamAppend> appends) {
  append_together(std::span<const StreamAppend>(appends.begin(), appends.size()));
}
template <class T>
StreamAppend rows_of(DatasetStream& stream, const T* data, uint64_t rows) {
  return {&stream, data, sizeof(T), rows};
}

// One dataset of the cache, written front to back in rows: how every dataset of a bake is
// written, so no stage needs its whole output in memory. Compressed datasets are chunked
// (about 1 MiB per chunk); each full chunk of the appended rows is encoded on the TBB workers
// (chunk_codec.hpp) and stored with H5Dwrite_chunk in chunk order, while the rows of a chunk not
// yet full wait in a buffer. Uncompressed datasets are contiguous and written in place. The
// dataset's XXH3-128 hash is computed as the rows arrive. The bytes stored do not depend on how
// the rows are split across append calls, nor on the thread count.
class DatasetStream {
 public:
  DatasetStream(DatasetStream&&) noexcept;
  DatasetStream& operator=(DatasetStream&&) noexcept;
  ~DatasetStream();

  template <class T>
  void append(const T* data, uint64_t rows) {
    append_raw(data, sizeof(T), rows);
  }
  // Writes the last partial chunk and the hash; OutputError unless every row arrived. Returns the
  // bytes the dataset takes on disk.
  uint64_t close();
  const std::string& name() const;
  uint64_t rows() const;
  uint64_t rows_written() const;
  // Parallel writes (ParallelWrite): the first row of this rank's range, before its first
  // append.
  void start_at(uint64_t row);

  struct State;

 private:
  friend class CacheWriter;
  friend void append_together(std::span<const StreamAppend> appends);
  void check_append(size_t element, uint64_t rows) const;
  explicit DatasetStream(std::unique_ptr<State> state);
  void append_raw(const void* data, size_t element, uint64_t rows);
  std::unique_ptr<State> state_;
};

class CacheWriter {
 public:
  // Creates the file under a temporary name beside `path`; commit() renames it.
  CacheWriter(const std::string& path, Compression compression, int level = -1);
  // The same file on every rank of a parallel write; collective.
  CacheWriter(const std::string& path, Compression compression, int level, ParallelWrite parallel);
  ~CacheWriter();
  CacheWriter(const CacheWriter&) = delete;
  CacheWriter& operator=(const CacheWriter&) = delete;

  const std::string& path() const { return file_.final_path(); }
  const std::string& temp_path() const { return file_.temp_path(); }
  // Bytes the compressed chunks in flight of this writer's appends may take (a memory budget's
  // share; unlimited by default): the encoding pipeline takes as many tokens as fit.
  void limit_chunks_in_flight(uint64_t bytes) { chunks_limit_ = bytes; }
  uint64_t chunks_in_flight_limit() const { return chunks_limit_; }
  // HDF5's last error, and under MPI what the file system says of a failed write of `attempted`
  // bytes (write_failure_cause): MPI-IO passes no errno up.
  std::string parallel_write_error(uint64_t attempted) const;
  Compression compression() const { return compression_; }
  // Total bytes the caller is going to write, for progress; 0: unknown.
  void set_progress(ProgressFn progress, uint64_t total_bytes);
  // Counts written bytes towards that progress (the datasets' streams call it).
  void add_progress(uint64_t bytes);

  void create_group(const std::string& group);
  // Copies a group, as stored, from another cache file (an asset that did not change).
  void copy_group(const std::string& source_path, const std::string& group);
  // A 1-D (columns = 0) or 2-D dataset of `rows` x `columns` of T, to be appended row by row.
  template <class T>
  DatasetStream stream(const std::string& dataset, uint64_t rows, uint64_t columns = 0);
  // A whole dataset at once. Returns the bytes it takes on disk.
  template <class T>
  uint64_t write(const std::string& dataset, const T* data, uint64_t rows, uint64_t columns = 0) {
    DatasetStream s = stream<T>(dataset, rows, columns);
    s.append(data, rows);
    return s.close();
  }
  void write_attribute(const std::string& object, const std::string& name,
                       const std::string& value);
  void write_provenance(const std::string& group, const Provenance& provenance);
  bool has_group(const std::string& group) const;
  // Writes what HDF5 holds in memory to the temporary file, so it can be read while open.
  void flush();
  // Parallel writes: every dataset's buffered rows, collectively (see ParallelWrite).
  void write_round();
  bool parallel() const { return parallel_.has_value(); }
  // Dataset bytes written so far (before compression), by this process.
  uint64_t bytes_written() const { return progress_done_; }
  void commit();

 private:
  friend class DatasetStream;
  DatasetStream open_stream(const std::string& dataset, hid_t type, size_t element, uint64_t rows,
                            uint64_t columns);
  void open(hid_t fapl);
  uint64_t chunks_limit_ = UINT64_MAX;
  AtomicFile file_;
  std::optional<ParallelWrite> parallel_;
  std::vector<DatasetStream::State*> open_;  // parallel: datasets not yet closed, in order
  h5::Handle h5_;
  Compression compression_;
  int level_;
  ProgressFn progress_;
  uint64_t progress_total_ = 0, progress_done_ = 0;
};

// True when `path` is an HDF5 file with linebake's cache attribute at its root (any version).
bool is_linebake_cache(const std::string& path);

class CacheReader {
 public:
  // Opens a cache; InputError if it is missing, not HDF5, truncated or not a linebake cache.
  // With verify, every dataset read is checked against its stored hash.
  explicit CacheReader(const std::string& path, bool verify = true);
  ~CacheReader();

  const std::string& path() const { return path_; }
  bool exists(const std::string& object) const;
  std::vector<std::string> members(const std::string& group) const;
  std::optional<std::string> attribute(const std::string& object, const std::string& name) const;
  std::optional<Provenance> provenance(const std::string& group) const;
  // Names of the assets stored under /assets.
  std::vector<std::string> assets() const { return members("/assets"); }

  // Reads a dataset of T with the expected element count (SIZE_MAX: any). Zero-copy where the
  // dataset is stored contiguous and uncompressed. InputError naming the dataset on a missing
  // dataset, a wrong size, a failed checksum or a read error.
  template <class T>
  Array<T> read(const std::string& dataset, size_t expected = SIZE_MAX) const;
  // Rows [first, first + count) of a dataset of T into `out` (count x columns values), for
  // readers that go through a large dataset in pieces. Verifies nothing: the whole-dataset hash
  // needs every row (a caller that reads them all in order can hash them itself).
  template <class T>
  void read_rows(const std::string& dataset, uint64_t first, uint64_t count, T* out) const;
  // Checks a dataset read in pieces (read_rows) against its stored hash: add() each piece's
  // rows in order from row 0 (rows given before are skipped, so pieces may overlap), then
  // finish(), which throws InputError naming the dataset unless every row came and their bytes
  // hash to what was stored. Checks nothing where the reader does not verify.
  class RowsCheck {
   public:
    RowsCheck(RowsCheck&&) noexcept;
    ~RowsCheck();
    void add(uint64_t first, uint64_t rows, const void* data);
    void finish() const;

   private:
    friend class CacheReader;
    RowsCheck();
    struct State;
    std::unique_ptr<State> state_;
  };
  RowsCheck rows_check(const std::string& dataset) const;
  // Shape of a dataset (rows, and columns for 2-D ones); InputError when missing.
  std::vector<uint64_t> shape(const std::string& dataset) const;
  // Elements stored in the dataset (rows x columns).
  uint64_t stored_bytes(const std::string& dataset) const;

 private:
  Array<unsigned char> read_raw(const std::string& dataset, hid_t type, size_t element,
                                size_t expected) const;
  // Rows through linebake's chunk decoder (cache/chunk_reader.hpp); false: use H5Dread.
  bool read_direct(hid_t dataset, hid_t type, uint64_t first, uint64_t count, void* out,
                   const std::string& where) const;
  std::string path_;
  bool verify_;
  h5::Handle h5_;
  std::shared_ptr<const void> mapping_;
  uint64_t file_size_ = 0;
};

}  // namespace linebake
