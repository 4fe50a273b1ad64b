#include "cache/cache.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/info.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/task_arena.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <ctime>
#include <memory>
#include <mutex>

#include "cache/chunk_reader.hpp"
#include "cache/group_copy.hpp"
#include "core/error.hpp"
#include "core/h5_probe.hpp"
#include "core/hash.hpp"
#include "core/interrupt.hpp"
#include "core/json_file.hpp"

namespace linebake {

using h5::Handle;

namespace {

// XXH3-128 of the dataset's bytes in 1 MiB blocks (BlockHasher); earlier caches carry the
// flat XXH3-128 as `xxh3_128`, still verified.
constexpr const char* kHashAttribute = "xxh3_128_blocks";
constexpr const char* kFlatHashAttribute = "xxh3_128";
constexpr const char* kFormatAttribute = "linebake_cache_format";
constexpr const char* kFormatVersion = "1";

template <class T>
hid_t native_type();
template <>
hid_t native_type<float>() {
  return H5T_NATIVE_FLOAT;
}
template <>
hid_t native_type<double>() {
  return H5T_NATIVE_DOUBLE;
}
template <>
hid_t native_type<uint8_t>() {
  return H5T_NATIVE_UINT8;
}
template <>
hid_t native_type<int16_t>() {
  return H5T_NATIVE_INT16;
}
template <>
hid_t native_type<uint16_t>() {
  return H5T_NATIVE_UINT16;
}
template <>
hid_t native_type<int32_t>() {
  return H5T_NATIVE_INT32;
}
template <>
hid_t native_type<uint32_t>() {
  return H5T_NATIVE_UINT32;
}
template <>
hid_t native_type<uint64_t>() {
  return H5T_NATIVE_UINT64;
}

// Little-endian file types, whatever the writing machine.
hid_t file_type(hid_t native) {
  if (H5Tequal(native, H5T_NATIVE_FLOAT) > 0) return H5T_IEEE_F32LE;
  if (H5Tequal(native, H5T_NATIVE_DOUBLE) > 0) return H5T_IEEE_F64LE;
  if (H5Tequal(native, H5T_NATIVE_UINT8) > 0) return H5T_STD_U8LE;
  if (H5Tequal(native, H5T_NATIVE_INT16) > 0) return H5T_STD_I16LE;
  if (H5Tequal(native, H5T_NATIVE_UINT16) > 0) return H5T_STD_U16LE;
  if (H5Tequal(native, H5T_NATIVE_INT32) > 0) return H5T_STD_I32LE;
  if (H5Tequal(native, H5T_NATIVE_UINT32) > 0) return H5T_STD_U32LE;
  return H5T_STD_U64LE;
}

void require_filter(unsigned id, const char* name, const char* package) {
  if (H5Zfilter_avail(id) <= 0)
    throw Error(std::string("compression ") + name + " needs the HDF5 filter plugin from " +
                package + " (not found; set HDF5_PLUGIN_PATH if it is elsewhere)");
}

}  // namespace

std::string utc_now_iso8601() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text;
}

nlohmann::json to_json(const Provenance& p) {
  nlohmann::json j = {{"step", p.step},
                      {"key", p.key},
                      {"input_hash", p.input_hash},
                      {"parameters", p.parameters},
                      {"stats", p.stats},
                      {"linebake_version", p.linebake_version},
                      {"created", p.created},
                      {"build",
                       {{"wall_s", p.build.wall_s},
                        {"cpu_s", p.build.cpu_s},
                        {"rss_before_bytes", p.build.rss_before},
                        {"peak_rss_bytes", p.build.peak_rss},
                        {"peak_is_step_local", p.build.peak_is_step_local},
                        {"threads", p.threads},
                        {"memory_budget_bytes", p.memory_budget},
                        {"spill_bytes", p.spill_bytes}}},
                      {"memory_bytes", p.memory_bytes},
                      {"disk_bytes", p.disk_bytes},
                      {"estimated_disk_bytes", p.estimated_disk_bytes},
                      {"compression", p.compression},
                      {"compression_level", p.compression_level}};
  // Only where the step shared its passes (caches before 2026-11-29 have no such field).
  if (!p.build.built_with.empty()) j["build"]["built_with"] = p.build.built_with;
  return j;
}

Provenance provenance_from_json(const nlohmann::json& j) {
  Provenance p;
  p.step = j.at("step");
  p.key = j.at("key");
  p.input_hash = j.at("input_hash");
  p.parameters = j.at("parameters");
  p.stats = j.value("stats", nlohmann::json::object());
  p.linebake_version = j.at("linebake_version");
  p.created = j.value("created", "");
  const auto& b = j.at("build");
  p.build.wall_s = b.at("wall_s");
  p.build.cpu_s = b.at("cpu_s");
  p.build.rss_before = b.at("rss_before_bytes");
  p.build.peak_rss = b.at("peak_rss_bytes");
  p.build.peak_is_step_local = b.at("peak_is_step_local");
  if (b.contains("built_with") && b["built_with"].is_array())
    for (const auto& step : b["built_with"])
      if (step.is_string()) p.build.built_with.push_back(step.get<std::string>());
  p.threads = b.value("threads", uint64_t{0});
  p.memory_budget = b.value("memory_budget_bytes", uint64_t{0});
  p.spill_bytes = b.value("spill_bytes", uint64_t{0});
  p.memory_bytes = j.at("memory_bytes");
  p.disk_bytes = j.at("disk_bytes");
  p.estimated_disk_bytes = j.value("estimated_disk_bytes", uint64_t{0});
  p.compression = j.value("compression", "");
  p.compression_level = j.value("compression_level", -1);
  return p;
}

// ---- writer ----

CacheWriter::CacheWriter(const std::string& path, Compression compression, int level)
    : file_(path), compression_(compression), level_(level) {
  Handle fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
  open(fapl);
}

CacheWriter::CacheWriter(const std::string& path, Compression compression, int level,
                         ParallelWrite parallel)
    : file_(path, parallel.temp_path, parallel.owner),
      parallel_(std::move(parallel)),
      compression_(compression),
      level_(level) {
  Handle fapl(H5Pcopy(parallel_->fapl), H5Pclose);
  open(fapl);
}

void CacheWriter::open(hid_t fapl) {
  const std::string& path = file_.final_path();
  h5::init();
  if (compression_ == Compression::Lz4) require_filter(kLz4Filter, "lz4", "hdf5-filter-plugin");
  if (compression_ == Compression::BloscZstd)
    require_filter(kBloscFilter, "blosc-zstd", "hdf5-filter-plugin-blosc-serial");
  Handle fcpl(H5Pcreate(H5P_FILE_CREATE), H5Pclose);
  H5Pset_link_creation_order(fcpl, H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED);
  // No write times in the objects' headers: the datasets of the same input and options are the
  // same bytes, and so is the file but for the provenance.
  H5Pset_obj_track_times(fcpl, false);
  // Closing the file closes every object still open in it: an error path that leaves a dataset
  // open must not keep the file open until HDF5's shutdown at exit, which then flushes it to a
  // full disk (and crashes in 1.10).
  H5Pset_fclose_degree(fapl, H5F_CLOSE_STRONG);
  // The 1.10 file format: superblock v3, v2 object headers and the new chunk indices, each with a
  // Jenkins lookup3 checksum HDF5 verifies on read, so damaged metadata is an error, not a crash
  // of the library (docs/cache.md: readers need HDF5 1.10 or later).
  if (H5Pset_libver_bounds(fapl, H5F_LIBVER_V110, H5F_LIBVER_V110) < 0)
    throw OutputError(path, "cannot ask for the HDF5 1.10 file format (" + h5::last_error() + ")");
  // Page-aligned datasets from 4 KiB up, so uncompressed ones can be viewed in a mapping.
  H5Pset_alignment(fapl, 4096, 4096);
  // HDF5's metadata cache may grow to 32 MiB by default; chunk indices written in order need
  // far less, and the bake's memory budget counts every byte.
  H5AC_cache_config_t mdc{};
  mdc.version = H5AC__CURR_CACHE_CONFIG_VERSION;
  if (H5Pget_mdc_config(fapl, &mdc) >= 0) {
    mdc.max_size = std::min<size_t>(mdc.max_size, size_t{4} << 20);
    mdc.min_size = std::min(mdc.min_size, mdc.max_size);
    mdc.initial_size = std::min(mdc.initial_size, mdc.max_size);
    H5Pset_mdc_config(fapl, &mdc);
  }
  h5_ = Handle(H5Fcreate(file_.temp_path().c_str(), H5F_ACC_TRUNC, fcpl, fapl), H5Fclose);
  if (!h5_.valid()) throw OutputError(path, "cannot create (" + h5::last_error() + ")");
  write_attribute("/", kFormatAttribute, kFormatVersion);
  write_attribute("/", "linebake_version", LINEBAKE_VERSION);
}

CacheWriter::~CacheWriter() {
  if (!h5::LeaveOpenOnUnwind::now()) h5_.reset();
}

void CacheWriter::set_progress(ProgressFn progress, uint64_t total_bytes) {
  progress_ = std::move(progress);
  progress_total_ = total_bytes;
  progress_done_ = 0;
}

void CacheWriter::create_group(const std::string& group) {
  if (H5Lexists(h5_, group.c_str(), H5P_DEFAULT) > 0) return;
  // Members in creation order, no write times; the missing groups above it made the same way
  // here (HDF5's own intermediate groups carry write times).
  Handle gcpl(H5Pcreate(H5P_GROUP_CREATE), H5Pclose);
  H5Pset_link_creation_order(gcpl, H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED);
  H5Pset_obj_track_times(gcpl, false);
  for (size_t slash = group.find('/', 1);; slash = group.find('/', slash + 1)) {
    const std::string name = group.substr(0, slash);
    if (H5Lexists(h5_, name.c_str(), H5P_DEFAULT) <= 0) {
      Handle g(H5Gcreate2(h5_, name.c_str(), H5P_DEFAULT, gcpl, H5P_DEFAULT), H5Gclose);
      if (!g.valid())
        throw OutputError(path(), "cannot create group " + name + " (" + h5::last_error() + ")");
    }
    if (slash == std::string::npos) break;
  }
}

void CacheWriter::copy_group(const std::string& source_path, const std::string& group) {
  h5::probe(source_path, {group});
  Handle source(H5Fopen(source_path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!source.valid()) throw InputError(source_path, "", "cannot open to copy " + group);
  const size_t slash = group.find_last_of('/');
  if (slash > 0) create_group(group.substr(0, slash));
  copy_group_tree(source, source_path, h5_, path(), group);
}

void CacheWriter::write_attribute(const std::string& object, const std::string& name,
                                  const std::string& value) {
  Handle o(H5Oopen(h5_, object.c_str(), H5P_DEFAULT), H5Oclose);
  if (!o.valid() || !h5::write_string_attribute(o, name, value))
    throw OutputError(path(), "cannot write attribute " + name + " of " + object);
}

void CacheWriter::write_provenance(const std::string& group, const Provenance& provenance) {
  write_attribute(group, "provenance", json_text(to_json(provenance)));
}

// ---- streamed datasets ----

struct DatasetStream::State {
  CacheWriter* writer = nullptr;
  std::string name;
  Handle dataset;
  hid_t type = -1;
  size_t element = 0;
  int rank = 1;
  uint64_t rows = 0, columns = 1, row_bytes = 0;
  bool chunked = false;
  uint64_t chunk_rows = 0;
  ChunkCodec codec;
  uint64_t written = 0;       // rows appended so far
  std::vector<char> pending;  // rows of the chunk not yet full
  std::vector<char> tail;     // the dataset's last chunk, padded with zeros
  BlockHasher hash;
  bool closed = false;
  // Parallel writes: this rank's first row, its rows not yet written, and its piece of the hash.
  bool parallel = false;
  uint64_t first_row = 0, flushed = 0;
  std::vector<char> buffered;
  std::unique_ptr<BlockHasher> piece;

  uint64_t chunk_bytes() const { return chunk_rows * row_bytes; }
  [[noreturn]] void fail(const std::string& message) const {
    throw OutputError(writer->path(), "dataset " + name + ": " + message);
  }
  void write_contiguous(const char* data, uint64_t count);
  // Stages an append: full chunks become jobs pointing at the caller's rows, a head or tail
  // goes to the pending buffers. settle() updates those buffers once the jobs are written.
  struct Job {
    State* stream;
    uint64_t chunk;
    const char* data;
  };
  void prepare(const char* data, uint64_t rows, std::vector<Job>& jobs);
  void settle();
  bool pending_sent = false;
  uint64_t staged_left = 0;
};

namespace {

// Buffers of the chunks in flight, kept between calls so that chunks do not touch fresh pages,
// and shared by every writing thread: a call takes what it uses and gives it back, keeping at
// most its own count, so the buffers held are those of the calls running at once (a bake writes
// from one step at a time), not of every TBB thread that ever wrote (thread-local buffers had
// made a bake's peak vary by a few MiB on 2 cores, and could reach a thread count times as much
// on many).
class BufferPool {
 public:
  using Buffer = std::unique_ptr<std::vector<char>>;
  Buffer take() {
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      if (!free_.empty()) {
        Buffer buffer = std::move(free_.back());
        free_.pop_back();
        return buffer;
      }
    }
    return std::make_unique<std::vector<char>>();
  }
  void give(Buffer buffer, size_t keep) {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (free_.size() < keep) free_.push_back(std::move(buffer));
  }

 private:
  std::mutex mutex_;
  std::vector<Buffer> free_;
};

// An encoded chunk at its largest (a raw chunk, 1 MiB, and the codec's bound over it), and an
// encoding's shuffle buffer (a raw chunk): one of each per pipeline token at the most.
constexpr uint64_t kSlotBytes = (uint64_t{1} << 20) + (uint64_t{64} << 10);
constexpr uint64_t kScratchBytes = uint64_t{1} << 20;

uint64_t writer_threads() {
  return uint64_t(tbb::this_task_arena::max_concurrency());
}

// Twice the threads and one, or as many as `limit` bytes hold (at least 2).
size_t chunk_pipeline_tokens(uint64_t limit) {
  const size_t most = 2 * size_t(writer_threads()) + 1;
  if (limit >= chunks_in_flight_wanted_bytes()) return most;
  return std::clamp<size_t>(size_t(limit / (kSlotBytes + kScratchBytes)), size_t{2}, most);
}

}  // namespace

uint64_t chunks_in_flight_wanted_bytes() {
  // The encodings run on the threads: no more shuffle buffers than threads.
  return (2 * writer_threads() + 1) * kSlotBytes + writer_threads() * kScratchBytes;
}

namespace {

// Encodes the chunks on the TBB workers and stores them in order from one thread at a time
// (HDF5 is not thread-safe): a pipeline whose ordered last stage hashes and writes each chunk
// while the chunks behind it are encoded. Chunks of several datasets share one pipeline.
void write_chunks(const std::vector<DatasetStream::State::Job>& jobs) {
  if (jobs.empty()) return;
  uint64_t limit = UINT64_MAX;
  for (const auto& j : jobs) limit = std::min(limit, j.stream->writer->chunks_in_flight_limit());
  const size_t tokens = chunk_pipeline_tokens(limit);
  static BufferPool encoded, shuffles;
  struct Taken {
    std::vector<BufferPool::Buffer> slots;
    ~Taken() {
      for (auto& slot : slots) encoded.give(std::move(slot), slots.size());
    }
  } taken;
  for (size_t t = 0; t < tokens; ++t) taken.slots.push_back(encoded.take());
  std::vector<std::vector<char>*> slot_base(tokens);
  for (size_t t = 0; t < tokens; ++t) slot_base[t] = taken.slots[t].get();
  struct Item {
    size_t job;
    std::vector<char>* slot;
  };
  size_t next = 0;
  tbb::parallel_pipeline(
      tokens,
      tbb::make_filter<
          void, Item>(tbb::filter_mode::serial_in_order, [&](tbb::flow_control& control) -> Item {
        if (next == jobs.size()) {
          control.stop();
          return {};
        }
        const size_t job = next++;
        return {job, slot_base[job % tokens]};
      }) & tbb::make_filter<Item, Item>(tbb::filter_mode::parallel, [&](Item item) {
        const auto& j = jobs[item.job];
        BufferPool::Buffer shuffle = shuffles.take();
        encode_chunk(j.stream->codec, j.data, j.stream->chunk_bytes(), *item.slot, *shuffle);
        shuffles.give(std::move(shuffle), tokens);
        return item;
      }) & tbb::make_filter<Item, void>(tbb::filter_mode::serial_in_order, [&](Item item) {
        const auto& j = jobs[item.job];
        DatasetStream::State& s = *j.stream;
        // The hash covers the rows, not the zeros that pad the dataset's last chunk.
        const uint64_t first_row = j.chunk * s.chunk_rows;
        s.hash.update(j.data, std::min(s.chunk_rows, s.rows - first_row) * s.row_bytes);
        const hsize_t offset[2] = {first_row, 0};
        const std::vector<char>& out = *item.slot;
        h5::init();  // this stage runs on TBB's threads: HDF5's printing off on each
        if (H5Dwrite_chunk(s.dataset, H5P_DEFAULT, 0, offset, out.size(), out.data()) < 0)
          s.fail("cannot write chunk " + std::to_string(j.chunk) + " (" + h5::last_error() + ")");
        s.writer->add_progress(s.chunk_bytes());
      }));
}

}  // namespace

void DatasetStream::State::write_contiguous(const char* data, uint64_t count) {
  h5::init();  // may run on TBB's threads (tubes and voxels write together): HDF5's printing off
  const hsize_t start[2] = {written, 0}, extent[2] = {count, columns};
  Handle file_space(H5Dget_space(dataset), H5Sclose);
  H5Sselect_hyperslab(file_space, H5S_SELECT_SET, start, nullptr, extent, nullptr);
  Handle memory_space(H5Screate_simple(rank, extent, nullptr), H5Sclose);
  if (H5Dwrite(dataset, type, memory_space, file_space, H5P_DEFAULT, data) < 0)
    fail("cannot write (" + h5::last_error() + ")");
  writer->add_progress(count * row_bytes);
}

DatasetStream::DatasetStream(std::unique_ptr<State> state) : state_(std::move(state)) {}
DatasetStream::DatasetStream(DatasetStream&&) noexcept = default;
DatasetStream& DatasetStream::operator=(DatasetStream&&) noexcept = default;
DatasetStream::~DatasetStream() {
  if (state_ && state_->parallel && !state_->closed) {  // an error path: forget it
    auto& list = state_->writer->open_;
    list.erase(std::remove(list.begin(), list.end(), state_.get()), list.end());
  }
}

const std::string& DatasetStream::name() const {
  return state_->name;
}
uint64_t DatasetStream::rows() const {
  return state_->rows;
}
uint64_t DatasetStream::rows_written() const {
  return state_->written;
}

void DatasetStream::State::prepare(const char* p, uint64_t count, std::vector<Job>& jobs) {
  // Full chunks are encoded straight from the caller's rows; only a chunk's head or tail that
  // arrives in another call is staged. HDF5 stores edge chunks whole, filled with zeros.
  uint64_t left = count;
  pending_sent = false;
  if (!pending.empty()) {
    const uint64_t have = pending.size() / row_bytes;
    const uint64_t take = std::min(left, chunk_rows - have);
    pending.insert(pending.end(), p, p + take * row_bytes);
    p += take * row_bytes;
    left -= take;
    written += take;
    if (have + take == chunk_rows || written == rows) {
      pending.resize(chunk_bytes(), 0);
      jobs.push_back({this, (written - 1) / chunk_rows, pending.data()});
      pending_sent = true;
    }
  }
  while (left >= chunk_rows) {
    jobs.push_back({this, written / chunk_rows, p});
    p += chunk_bytes();
    left -= chunk_rows;
    written += chunk_rows;
  }
  staged_left = left;
  if (left > 0) {  // the pending buffer is empty or already sent: stage into the other one
    tail.assign(p, p + left * row_bytes);
    written += left;
    if (written == rows) {
      tail.resize(chunk_bytes(), 0);
      jobs.push_back({this, (written - 1) / chunk_rows, tail.data()});
    }
  }
}

void DatasetStream::State::settle() {
  if (pending_sent) pending.clear();
  if (staged_left > 0) {
    if (written == rows)
      tail.clear();
    else
      pending.swap(tail);
  }
  pending_sent = false;
  staged_left = 0;
}

void DatasetStream::check_append(size_t element, uint64_t rows) const {
  const State& s = *state_;
  if (s.closed) s.fail("append after close");
  if (element != s.element) s.fail("appended values of the wrong type");
  if (rows > s.rows - s.first_row - s.written)
    s.fail(std::to_string(s.first_row + s.written + rows) + " rows, more than the " +
           std::to_string(s.rows) + " it was created with");
}

void DatasetStream::append_raw(const void* data, size_t element, uint64_t rows) {
  append_together({{this, data, element, rows}});
}

void append_together(std::span<const StreamAppend> appends) {
  throw_if_interrupted();  // a safe point: every chunk before it is written, none half
  std::vector<DatasetStream::State::Job> jobs;
  for (const StreamAppend& a : appends) {
    a.stream->check_append(a.element, a.rows);
    DatasetStream::State& s = *a.stream->state_;
    if (a.rows == 0) continue;
    const char* p = static_cast<const char*>(a.data);
    if (s.parallel) {
      if (!s.piece)
        s.piece = std::make_unique<BlockHasher>(BlockHasher::Piece{0, s.rows * s.row_bytes});
      s.piece->update(p, a.rows * s.row_bytes);
      s.buffered.insert(s.buffered.end(), p, p + a.rows * s.row_bytes);
      s.written += a.rows;
      continue;
    }
    if (!s.chunked) {
      s.hash.update(p, a.rows * s.row_bytes);
      s.write_contiguous(p, a.rows);
      s.written += a.rows;
      continue;
    }
    s.prepare(p, a.rows, jobs);
  }
  write_chunks(jobs);
  for (const StreamAppend& a : appends)
    if (a.rows && a.stream->state_->chunked && !a.stream->state_->parallel)
      a.stream->state_->settle();
}

void DatasetStream::start_at(uint64_t row) {
  State& s = *state_;
  if (!s.parallel) s.fail("start_at on a dataset that is not written in parallel");
  if (s.written || s.piece) s.fail("start_at after the first append");
  if (row > s.rows) s.fail("starts past its " + std::to_string(s.rows) + " rows");
  s.first_row = row;
  s.piece =
      std::make_unique<BlockHasher>(BlockHasher::Piece{row * s.row_bytes, s.rows * s.row_bytes});
}

uint64_t DatasetStream::close() {
  State& s = *state_;
  if (s.closed) s.fail("closed twice");
  std::string hash;
  if (s.parallel) {
    // Collective: the ranks' row counts add up, their pieces of the hash join up a tree.
    if (!s.buffered.empty()) s.fail("closed with rows not yet written (write_round)");
    if (!s.piece) s.piece = std::make_unique<BlockHasher>(BlockHasher::Piece{0});
    const ParallelWrite& p = *s.writer->parallel_;
    const uint64_t total = p.sum(s.written);
    if (total != s.rows)
      s.fail("the ranks wrote " + std::to_string(total) + " of " + std::to_string(s.rows) +
             " rows");
    try {
      hash = p.reduce(
          s.piece->piece(),
          [](const std::string& a, const std::string& b) {
            return join_block_hash_pieces({a, b});
          },
          [](const std::string& whole) { return finish_block_hash(whole); });
    } catch (const Error& e) {
      s.fail(std::string("the ranks' rows do not join: ") + e.what());
    }
    auto& list = s.writer->open_;
    list.erase(std::remove(list.begin(), list.end(), &s), list.end());
  } else {
    if (s.written != s.rows)
      s.fail("only " + std::to_string(s.written) + " of " + std::to_string(s.rows) +
             " rows were written");
    hash = s.hash.hex();
  }
  if (!h5::write_string_attribute(s.dataset, kHashAttribute, hash)) s.fail("cannot write its hash");
  s.closed = true;
  const uint64_t stored = H5Dget_storage_size(s.dataset);
  s.dataset.reset();
  return stored;
}

template <class T>
DatasetStream CacheWriter::stream(const std::string& dataset, uint64_t rows, uint64_t columns) {
  return open_stream(dataset, native_type<T>(), sizeof(T), rows, columns);
}

DatasetStream CacheWriter::open_stream(const std::string& dataset, hid_t type, size_t element,
                                       uint64_t rows, uint64_t columns) {
  const size_t slash = dataset.find_last_of('/');
  if (slash > 0) create_group(dataset.substr(0, slash));
  auto s = std::make_unique<DatasetStream::State>();
  s->writer = this;
  s->name = dataset;
  s->type = type;
  s->element = element;
  s->rank = columns ? 2 : 1;
  s->rows = rows;
  s->columns = columns ? columns : 1;
  s->row_bytes = element * s->columns;
  const hsize_t dims[2] = {rows, s->columns};
  Handle space(H5Screate_simple(s->rank, dims, nullptr), H5Sclose);
  Handle dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
  H5Pset_obj_track_times(dcpl, false);
  s->chunked = compression_ != Compression::None && rows > 0;
  if (s->chunked) {
    // About 1 MiB per chunk: large enough for the codecs, small enough for HDF5's chunk cache.
    s->chunk_rows = std::clamp<hsize_t>((1 << 20) / s->row_bytes, 1, rows);
    const hsize_t chunk[2] = {s->chunk_rows, s->columns};
    s->codec = {compression_, level_, element};
    H5Pset_chunk(dcpl, s->rank, chunk);
    H5Pset_shuffle(dcpl);
    if (compression_ == Compression::Deflate) {
      H5Pset_deflate(dcpl, unsigned(s->codec.deflate_level()));
    } else if (compression_ == Compression::Lz4) {
      H5Pset_filter(dcpl, kLz4Filter, H5Z_FLAG_MANDATORY, 0, nullptr);
    } else {
      // Blosc's own shuffle is off: HDF5's shuffle above already did it.
      const unsigned cd[7] = {0, 0, 0, 0, unsigned(s->codec.blosc_level()), 0, kBloscZstd};
      H5Pset_filter(dcpl, kBloscFilter, H5Z_FLAG_MANDATORY, 7, cd);
    }
    H5Pset_fletcher32(dcpl);
  } else {
    H5Pset_layout(dcpl, H5D_CONTIGUOUS);
    H5Pset_alloc_time(dcpl, H5D_ALLOC_TIME_EARLY);
  }
  if (parallel_) H5Pset_fill_time(dcpl, H5D_FILL_TIME_NEVER);  // every row is written
  s->dataset = Handle(
      H5Dcreate2(h5_, dataset.c_str(), file_type(type), space, H5P_DEFAULT, dcpl, H5P_DEFAULT),
      H5Dclose);
  if (!s->dataset.valid())
    throw OutputError(path(), "cannot create dataset " + dataset + " (" + h5::last_error() + ")");
  if (parallel_) {
    s->parallel = true;
    open_.push_back(s.get());
  }
  return DatasetStream(std::move(s));
}

void CacheWriter::add_progress(uint64_t bytes) {
  progress_done_ += bytes;
  if (progress_) progress_(progress_done_, progress_total_);
}

bool CacheWriter::has_group(const std::string& group) const {
  size_t at = 0;
  while ((at = group.find('/', at + 1)) != std::string::npos)
    if (H5Lexists(h5_, group.substr(0, at).c_str(), H5P_DEFAULT) <= 0) return false;
  return H5Lexists(h5_, group.c_str(), H5P_DEFAULT) > 0;
}

void CacheWriter::flush() {
  if (H5Fflush(h5_, H5F_SCOPE_GLOBAL) < 0) throw OutputError(path(), "cannot flush");
}

void CacheWriter::write_round() {
  if (!parallel_) return;
  throw_if_interrupted();
  // Which datasets have rows on any rank: a collective write for those only.
  std::string any(open_.size(), '\0');
  for (size_t i = 0; i < open_.size(); ++i) any[i] = char(!open_[i]->buffered.empty());
  parallel_->any(any);
  for (size_t i = 0; i < open_.size(); ++i) {
    // A dataset this rank sent nothing this round is most likely done with here (a tube chunk
    // left behind): its buffer goes, so only the datasets in use hold one.
    if (open_[i]->buffered.empty()) std::vector<char>().swap(open_[i]->buffered);
    if (!any[i]) continue;
    DatasetStream::State& s = *open_[i];
    const uint64_t rows = s.buffered.size() / s.row_bytes;
    Handle file_space(H5Dget_space(s.dataset), H5Sclose);
    const hsize_t start[2] = {s.first_row + s.flushed, 0}, extent[2] = {rows, s.columns};
    const hsize_t one[2] = {1, s.columns};
    Handle memory_space(H5Screate_simple(s.rank, rows ? extent : one, nullptr), H5Sclose);
    char nothing = 0;
    if (rows) {
      H5Sselect_hyperslab(file_space, H5S_SELECT_SET, start, nullptr, extent, nullptr);
    } else {
      H5Sselect_none(file_space);
      H5Sselect_none(memory_space);
    }
    if (H5Dwrite(s.dataset, s.type, memory_space, file_space, parallel_->dxpl,
                 rows ? s.buffered.data() : &nothing) < 0)
      s.fail("cannot write rows " + std::to_string(start[0]) + ".." +
             std::to_string(start[0] + rows) + " (" + parallel_write_error(rows * s.row_bytes) +
             ")");
    s.flushed += rows;
    add_progress(rows * s.row_bytes);
    s.buffered.clear();
  }
}

std::string CacheWriter::parallel_write_error(uint64_t attempted) const {
  std::string message = h5::last_error();
  // MPI-IO says "file write failed" and no more (Open MPI prints errno itself, to stderr).
  if (parallel_)
    if (const std::string cause = write_failure_cause(temp_path(), attempted); !cause.empty())
      message += ": " + cause;
  return message;
}

void CacheWriter::commit() {
  if (H5Fflush(h5_, H5F_SCOPE_GLOBAL) < 0)
    throw OutputError(path(),
                      "cannot write: " + parallel_write_error(0) + " (" + temp_path() + ")");
  // Closing writes what HDF5 still holds; a failure here is a failed write, not a cache.
  const hid_t id = h5_.release();
  if (H5Fclose(id) < 0)
    throw OutputError(path(),
                      "cannot write: " + parallel_write_error(0) + " (" + temp_path() + ")");
  file_.commit();
}

template DatasetStream CacheWriter::stream<float>(const std::string&, uint64_t, uint64_t);
template DatasetStream CacheWriter::stream<double>(const std::string&, uint64_t, uint64_t);
template DatasetStream CacheWriter::stream<uint8_t>(const std::string&, uint64_t, uint64_t);
template DatasetStream CacheWriter::stream<int16_t>(const std::string&, uint64_t, uint64_t);
template DatasetStream CacheWriter::stream<uint16_t>(const std::string&, uint64_t, uint64_t);
template DatasetStream CacheWriter::stream<int32_t>(const std::string&, uint64_t, uint64_t);
template DatasetStream CacheWriter::stream<uint32_t>(const std::string&, uint64_t, uint64_t);
template DatasetStream CacheWriter::stream<uint64_t>(const std::string&, uint64_t, uint64_t);

// ---- reader ----

bool is_linebake_cache(const std::string& path) {
  h5::init();
  if (H5Fis_hdf5(path.c_str()) <= 0) return false;
  // Only what this opens (the superblock, the root's attributes): a damaged cache is then read,
  // refused and rebuilt by bake, and a line file is not judged by objects it never reads.
  h5::probe(path, {});
  Handle file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  return file.valid() && H5Aexists(file, kFormatAttribute) > 0;
}

CacheReader::CacheReader(const std::string& path, bool verify) : path_(path), verify_(verify) {
  h5::init();
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) throw InputError(path, "", "no such cache file");
  file_size_ = static_cast<uint64_t>(st.st_size);
  if (H5Fis_hdf5(path.c_str()) <= 0)
    throw InputError(path, "", "not an HDF5 file (or its superblock is damaged)");
  // Caches come from other machines and rotting disks; HDF5 1.10 crashes on some damaged
  // metadata, so the whole file is walked first in a child process (docs/reliability.md).
  h5::probe(path);
  h5_ = Handle(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!h5_.valid())
    throw InputError(
        path, "", "cannot open the cache: " + h5::last_error() + " (truncated or damaged file?)");
  std::string format;
  if (!h5::read_string_attribute(h5_, kFormatAttribute, format))
    throw InputError(path, "",
                     "an HDF5 file but not a linebake cache (no " + std::string(kFormatAttribute) +
                         " attribute)");
  if (format != kFormatVersion)
    throw InputError(path, "",
                     "cache format " + format + " is not supported (this linebake reads " +
                         kFormatVersion + ")");
  // The whole file, read-only: uncompressed datasets are handed out as views into it.
  const int fd = ::open(path.c_str(), O_RDONLY);
  if (fd >= 0 && file_size_ > 0) {
    void* p = mmap(nullptr, file_size_, PROT_READ, MAP_SHARED, fd, 0);
    if (p != MAP_FAILED) {
      const uint64_t size = file_size_;
      mapping_ = std::shared_ptr<const void>(
          p, [size](const void* q) { munmap(const_cast<void*>(q), size); });
    }
  }
  if (fd >= 0) ::close(fd);
}

namespace {

// A view's owner: it keeps the mapping alive and, when the last copy of the view goes, drops the
// view's whole pages from the process's resident set (MADV_DONTNEED on a shared read-only file
// mapping: the page cache keeps them, and another view over them faults them back in). Without
// it every array read through views stays in the process's RSS for the reader's life, and the
// memory budget, which counts RSS, would count a mesh already uploaded and let go.
std::shared_ptr<const void> mapped_view(const std::shared_ptr<const void>& mapping, uint64_t offset,
                                        uint64_t bytes) {
  const auto* base = static_cast<const unsigned char*>(mapping.get());
  const uint64_t page = uint64_t(sysconf(_SC_PAGESIZE));
  const uint64_t first = (offset + page - 1) / page * page, end = (offset + bytes) / page * page;
  return std::shared_ptr<const void>(base + offset, [mapping, base, first, end](const void*) {
    if (end > first) madvise(const_cast<unsigned char*>(base) + first, end - first, MADV_DONTNEED);
  });
}

}  // namespace

CacheReader::~CacheReader() = default;

// Every read starts here, stored_bytes or read_direct: a reader opened on one thread may be
// used on another (Python's), whose HDF5 printing h5::init turns off.
bool CacheReader::exists(const std::string& object) const {
  h5::init();
  return h5::path_exists(h5_, object);
}

std::vector<std::string> CacheReader::members(const std::string& group) const {
  return exists(group) ? h5::group_members(h5_, group) : std::vector<std::string>{};
}

std::optional<std::string> CacheReader::attribute(const std::string& object,
                                                  const std::string& name) const {
  if (!exists(object)) return std::nullopt;
  Handle o(H5Oopen(h5_, object.c_str(), H5P_DEFAULT), H5Oclose);
  std::string value;
  if (!o.valid() || !h5::read_string_attribute(o, name, value)) return std::nullopt;
  return value;
}

std::optional<Provenance> CacheReader::provenance(const std::string& group) const {
  const auto text = attribute(group, "provenance");
  if (!text) return std::nullopt;
  try {
    return provenance_from_json(nlohmann::json::parse(*text));
  } catch (const std::exception& e) {
    throw InputError(path_, "group " + group, std::string("unreadable provenance: ") + e.what());
  }
}

uint64_t CacheReader::stored_bytes(const std::string& dataset) const {
  h5::init();
  Handle d(H5Dopen2(h5_, dataset.c_str(), H5P_DEFAULT), H5Dclose);
  return d.valid() ? H5Dget_storage_size(d) : 0;
}

template <class T>
Array<T> CacheReader::read(const std::string& dataset, size_t expected) const {
  Array<unsigned char> raw = read_raw(dataset, native_type<T>(), sizeof(T), expected);
  return Array<T>(raw.owner(), reinterpret_cast<const T*>(raw.data()), raw.size() / sizeof(T));
}

bool CacheReader::read_direct(hid_t dataset, hid_t type, uint64_t first, uint64_t count, void* out,
                              const std::string& where) const {
  h5::init();
  try {
    return read_cache_rows_strict(dataset, type, first, count, out);
  } catch (const BudgetExceeded& e) {
    throw BudgetExceeded(path_ + ": " + where + ": " + e.what());
  } catch (const Error& e) {
    throw InputError(path_, where, e.what());
  }
}

Array<unsigned char> CacheReader::read_raw(const std::string& dataset, hid_t type, size_t element,
                                           size_t expected) const {
  const std::string where = "dataset " + dataset;
  if (!exists(dataset)) throw InputError(path_, where, "missing");
  Handle d(H5Dopen2(h5_, dataset.c_str(), H5P_DEFAULT), H5Dclose);
  if (!d.valid()) throw InputError(path_, where, "cannot open: " + h5::last_error());
  h5::check_claimed_size(path_, d, dataset);
  uint64_t count = 1;
  for (hsize_t n : h5::shape_of(d)) count *= n;
  if (expected != SIZE_MAX && count != expected)
    throw InputError(path_, where,
                     std::to_string(count) + " values, expected " + std::to_string(expected));
  Handle stored_type(H5Dget_type(d), H5Tclose);
  if (H5Tget_size(stored_type) != element || H5Tget_class(stored_type) != H5Tget_class(type))
    throw InputError(path_, where, "stored with an unexpected type");
  const uint64_t bytes = count * element;

  Array<unsigned char> out;
  Handle dcpl(H5Dget_create_plist(d), H5Pclose);
  const haddr_t offset = H5Dget_offset(d);
  const bool viewable = mapping_ && H5Pget_layout(dcpl) == H5D_CONTIGUOUS &&
                        H5Pget_nfilters(dcpl) == 0 && offset != HADDR_UNDEF && offset % 64 == 0 &&
                        H5Tequal(stored_type, file_type(type)) > 0 &&
                        H5Tequal(file_type(type), type) > 0;  // little-endian host
  if (viewable) {
    if (offset + bytes > file_size_)
      throw InputError(path_, where,
                       "the file is truncated (data ends at byte " +
                           std::to_string(offset + bytes) + ", file has " +
                           std::to_string(file_size_) + ")");
    out = Array<unsigned char>(mapped_view(mapping_, offset, bytes),
                               static_cast<const unsigned char*>(mapping_.get()) + offset, bytes);
  } else {
    try {
      out = Array<unsigned char>(bytes);
    } catch (const std::bad_alloc&) {
      // A dataset the cache's own counts vouch for: too big for this process, not bad input.
      throw BudgetExceeded(path_ + ": " + where + ": needs " + std::to_string(bytes) +
                           " bytes of memory, more than this process could allocate (ulimit -v, "
                           "the cgroup's limit, or the machine's memory)");
    }
    const std::vector<hsize_t> dims = h5::shape_of(d);
    if (bytes && !read_direct(d, type, 0, dims.empty() ? 1 : dims[0], out.data(), where) &&
        H5Dread(d, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()) < 0)
      throw InputError(path_, where,
                       "cannot read: " + h5::last_error() + " (corrupt or truncated data)");
  }
  if (verify_) {
    std::string stored;
    std::string computed;
    if (h5::read_string_attribute(d, kHashAttribute, stored))
      computed = BlockHasher().update(out.data(), out.size()).hex();
    else if (h5::read_string_attribute(d, kFlatHashAttribute, stored))
      computed = hash_bytes(out.data(), out.size());
    else
      throw InputError(path_, where, "no stored hash to verify against");
    if (stored != computed)
      throw InputError(path_, where, "checksum mismatch: the data is corrupt");
  }
  return out;
}

struct CacheReader::RowsCheck::State {
  std::string path, where, stored;
  uint64_t row_bytes = 0, rows = 0, next = 0;
  std::unique_ptr<BlockHasher> blocks;  // kHashAttribute
  std::unique_ptr<Hasher> flat;         // kFlatHashAttribute
};

CacheReader::RowsCheck::RowsCheck() = default;
CacheReader::RowsCheck::RowsCheck(RowsCheck&&) noexcept = default;
CacheReader::RowsCheck::~RowsCheck() = default;

void CacheReader::RowsCheck::add(uint64_t first, uint64_t rows, const void* data) {
  State* s = state_.get();
  if (!s || first + rows <= s->next) return;
  if (first > s->next)
    throw Error("internal error: rows " + std::to_string(s->next) + ".." + std::to_string(first) +
                " of " + s->where + " skipped before they were checked");
  const auto* bytes = static_cast<const unsigned char*>(data) + (s->next - first) * s->row_bytes;
  const uint64_t count = (first + rows - s->next) * s->row_bytes;
  if (s->blocks) s->blocks->update(bytes, count);
  if (s->flat) s->flat->update(bytes, count);
  s->next = first + rows;
}

void CacheReader::RowsCheck::finish() const {
  const State* s = state_.get();
  if (!s) return;
  if (s->next != s->rows)
    throw Error("internal error: " + std::to_string(s->next) + " of the " +
                std::to_string(s->rows) + " rows of " + s->where + " checked");
  const std::string computed = s->blocks ? s->blocks->hex() : s->flat->hex();
  if (computed != s->stored)
    throw InputError(s->path, s->where, "checksum mismatch: the data is corrupt");
}

CacheReader::RowsCheck CacheReader::rows_check(const std::string& dataset) const {
  RowsCheck check;
  if (!verify_) return check;
  const std::string where = "dataset " + dataset;
  if (!exists(dataset)) throw InputError(path_, where, "missing");
  Handle d(H5Dopen2(h5_, dataset.c_str(), H5P_DEFAULT), H5Dclose);
  if (!d.valid()) throw InputError(path_, where, "cannot open: " + h5::last_error());
  auto s = std::make_unique<RowsCheck::State>();
  s->path = path_, s->where = where;
  const std::vector<hsize_t> dims = h5::shape_of(d);
  Handle stored_type(H5Dget_type(d), H5Tclose);
  s->rows = dims.empty() ? 1 : dims[0];
  s->row_bytes = H5Tget_size(stored_type) * (dims.size() == 2 ? dims[1] : 1);
  if (h5::read_string_attribute(d, kHashAttribute, s->stored))
    s->blocks = std::make_unique<BlockHasher>();
  else if (h5::read_string_attribute(d, kFlatHashAttribute, s->stored))
    s->flat = std::make_unique<Hasher>();
  else
    throw InputError(path_, where, "no stored hash to verify against");
  check.state_ = std::move(s);
  return check;
}

std::vector<uint64_t> CacheReader::shape(const std::string& dataset) const {
  if (!exists(dataset)) throw InputError(path_, "dataset " + dataset, "missing");
  Handle d(H5Dopen2(h5_, dataset.c_str(), H5P_DEFAULT), H5Dclose);
  if (!d.valid()) throw InputError(path_, "dataset " + dataset, "cannot open: " + h5::last_error());
  h5::check_claimed_size(path_, d, dataset);
  const std::vector<hsize_t> dims = h5::shape_of(d);
  return {dims.begin(), dims.end()};
}

template <class T>
void CacheReader::read_rows(const std::string& dataset, uint64_t first, uint64_t count,
                            T* out) const {
  const std::string where = "dataset " + dataset;
  if (!exists(dataset)) throw InputError(path_, where, "missing");
  // A chunk cache large enough that a chunk cut by one slab is still there for the next.
  Handle dapl(H5Pcreate(H5P_DATASET_ACCESS), H5Pclose);
  H5Pset_chunk_cache(dapl, 521, size_t{16} << 20, 1.0);
  Handle d(H5Dopen2(h5_, dataset.c_str(), dapl), H5Dclose);
  if (!d.valid()) throw InputError(path_, where, "cannot open: " + h5::last_error());
  const std::vector<hsize_t> dims = h5::shape_of(d);
  if (dims.empty() || dims.size() > 2 || first + count > dims[0])
    throw InputError(path_, where,
                     "rows " + std::to_string(first) + ".." + std::to_string(first + count) +
                         " are past its shape");
  Handle stored_type(H5Dget_type(d), H5Tclose);
  if (H5Tget_size(stored_type) != sizeof(T) ||
      H5Tget_class(stored_type) != H5Tget_class(native_type<T>()))
    throw InputError(path_, where, "stored with an unexpected type");
  if (count == 0) return;
  const hsize_t start[2] = {first, 0}, extent[2] = {count, dims.size() == 2 ? dims[1] : 1};
  Handle file_space(H5Dget_space(d), H5Sclose);
  H5Sselect_hyperslab(file_space, H5S_SELECT_SET, start, nullptr, extent, nullptr);
  Handle memory_space(H5Screate_simple(int(dims.size()), extent, nullptr), H5Sclose);
  if (!read_direct(d, native_type<T>(), first, count, out, where) &&
      H5Dread(d, native_type<T>(), memory_space, file_space, H5P_DEFAULT, out) < 0)
    throw InputError(path_, where,
                     "cannot read rows " + std::to_string(first) + ".." +
                         std::to_string(first + count) + ": " + h5::last_error() +
                         " (corrupt or truncated data)");
}

template void CacheReader::read_rows(const std::string&, uint64_t, uint64_t, float*) const;
template void CacheReader::read_rows(const std::string&, uint64_t, uint64_t, uint32_t*) const;
template void CacheReader::read_rows(const std::string&, uint64_t, uint64_t, uint64_t*) const;
template void CacheReader::read_rows(const std::string&, uint64_t, uint64_t, uint8_t*) const;

template Array<float> CacheReader::read(const std::string&, size_t) const;
template Array<double> CacheReader::read(const std::string&, size_t) const;
template Array<uint8_t> CacheReader::read(const std::string&, size_t) const;
template Array<int16_t> CacheReader::read(const std::string&, size_t) const;
template Array<uint16_t> CacheReader::read(const std::string&, size_t) const;
template Array<int32_t> CacheReader::read(const std::string&, size_t) const;
template Array<uint32_t> CacheReader::read(const std::string&, size_t) const;
template Array<uint64_t> CacheReader::read(const std::string&, size_t) const;

}  // namespace linebake
