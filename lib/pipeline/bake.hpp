#pragma once
// bake: input -> line set -> assets, into one cache file. A step whose input and parameters
// are unchanged (same provenance key) is reused from the existing cache, not rebuilt.
//
// The bake streams: the input is read once in batches of whole lines, kept in a spill file, and
// read from there by the passes that write /lines and plan the tube chunks, then build every
// asset batch by batch straight into the cache. Memory is bounded by a budget (the whole
// process's resident memory); the cache's bytes do not depend on it, nor on the thread count.

#include <string>
#include <vector>

#include "accel/embree_scene.hpp"
#include "cache/cache.hpp"
#include "cache/embree_store.hpp"
#include "formats/registry.hpp"
#include "lines/validate.hpp"
#include "tubes/tube_builder.hpp"
#include "voxels/voxelizer.hpp"

namespace linebake {

// The smallest span (bounding-box diagonal) of lines that tubes and Embree's curves are built
// over: below it, squared distances between their points underflow float32.
inline constexpr float kMinGeometrySpan = 1e-12f;

// Assets bake knows how to build, in build order.
const std::vector<std::string>& bakeable_assets();

// The Vulkan ray tracing asset: BLAS built on a device with ray tracing, serialised per device.
struct RtxOptions {
  std::string geometry = "triangles";  // triangles (over the tubes) | capsules (AABBs)
  bool compaction = true;
  std::string device;  // part of the device name; "" picks a discrete GPU
  bool validation = false;
};
nlohmann::json to_json(const RtxOptions& rtx);
// The tubes step's provenance figures: the chunk plan's counts and the mesh's description.
nlohmann::json tube_stats(const TubeMesh& mesh, const std::vector<TubeChunkPlan>& plan);
// The voxel step's provenance figures (bake and linebake-mpi), and its note on dropped chords
// ("" when none were dropped).
nlohmann::json voxel_stats(const VoxelGrid& grid, uint64_t chords, uint64_t bytes_with_density,
                           uint64_t records_in_memory, uint64_t records_spilled);
std::string dropped_chords_note(const VoxelGrid& grid);
// The Embree step's provenance figures (bake and linebake-mpi), with the writer's buffers and
// the primitives and parts of its plan (known whether the BVH is built at bake or not).
nlohmann::json embree_stats(const EmbreeOptions& embree, const StoredCurves& curves,
                            double prepare_s, const EmbreeStoreWriter& writer);

struct BakeOptions {
  std::string input;  // file or synth: source
  // What the cache records as the lines' source (their "source" metadata and the /lines step's
  // parameter): by default `input`; "" records none. For an input that is a stand-in (Python's
  // temporary file for a LineSet's arrays).
  std::optional<std::string> source_name;
  // Several files as one line set, in this order (expand_inputs sorts them); `input` is then
  // only how messages name them. Empty: `input` alone.
  std::vector<std::string> inputs;
  std::optional<Format> format;  // overrides the input's extension
  InvalidPolicy on_invalid = InvalidPolicy::repair;
  // The lines' origin (lines/origin.hpp): "" none (the input's own frame), "auto" (the first
  // valid point, rounded: formats/registry.hpp, auto_origin) or "X,Y,Z".
  std::string origin;
  std::string cache;                         // output; default <input stem>.lbc.h5
  std::vector<std::string> assets{"tubes"};  // and/or "voxels", "embree", "rtx"
  TubeOptions tubes;
  VoxelOptions voxels;
  // Embree curves: radius and attribute follow `tubes` (the same tubes, ray traced).
  EmbreeOptions embree;
  RtxOptions rtx;
  Compression compression = Compression::Lz4;
  int compression_level = -1;  // codec default
  // Whether `compression` and its level were asked for. Where not (`bake` without --compression),
  // a bake into an existing cache keeps the cache's own, its /lines' codec and level: adding an
  // asset to a cache baked with `none` rebuilds nothing for a default's sake.
  bool compression_given = true;
  bool force = false;       // rebuild every step; replace an output file that is not a cache
  bool progress = true;     // terminal progress bars (drawn only on a TTY)
  bool space_check = true;  // refuse up front when the output's file system is too full
  bool dry_run = false;     // read the input, print the estimates, write nothing
  // The process's resident memory at most, in bytes: kDefaultBudget is half of physical memory,
  // kUnlimited holds everything in memory that fits.
  uint64_t memory_budget = kDefaultBudget;
  static constexpr uint64_t kDefaultBudget = 0;
  static constexpr uint64_t kUnlimited = UINT64_MAX;
};

// The attribute names of `o` (--attribute, --radius-attribute, --voxel-attribute) checked against
// the input's header before any of it is read: a mistyped name is a UsageError naming the
// option, not a failure an hour into the bake (the serial and the MPI bake).
void check_attribute_options(const BakeOptions& o, const LineSet& header);

// What a bake expects to write, from the line set's statistics and the options: each step's
// datasets as stored, and the temporary spill files beside the cache at their largest.
struct BakeEstimate {
  uint64_t lines = 0, tubes = 0, voxels = 0, embree = 0;
  uint64_t spill = 0;
  uint64_t total() const { return lines + tubes + voxels + embree + spill; }
  uint64_t step(const std::string& name) const;
};
// `records_in_memory`: the chord records the budget keeps in memory (the rest spill).
BakeEstimate estimate_bake(const LineSetStats& stats, const LineSet& header,
                           const BakeOptions& options, uint64_t records_in_memory);

// One pass of a bake over the data, as measured.
struct BakeStage {
  std::string name;  // "read", "lines", "build", "voxel merge", ...
  double wall_s = 0, cpu_s = 0;
  uint64_t peak_rss_bytes = 0;  // the process's high-water mark during the stage
};

struct BakeStep {
  std::string step;  // "lines", "tubes"
  bool built = false;
  Provenance provenance;
};

struct BakeResult {
  std::string cache;
  bool written = false;  // false: everything was up to date, the file was not touched
  std::vector<BakeStep> steps;
  std::vector<std::string> notes;  // validation repairs, dropped lines
  std::vector<BakeStage> stages;
  uint64_t memory_budget_bytes = 0;  // 0: unlimited
  uint64_t peak_rss_bytes = 0;       // the whole bake's resident high-water mark
  uint64_t batch_points = 0;         // points per batch the budget allowed
  uint64_t spill_peak_bytes = 0;     // temporary files beside the cache, at their largest
  uint64_t bytes_written = 0;        // the cache file's size
  double wall_s = 0;
  BakeEstimate estimate;    // before the build (dry runs stop there)
  uint64_t free_bytes = 0;  // on the cache's file system when it was checked
};

std::string default_cache_path(const std::string& input);
// The cache a bake with these options writes: -o; else, for one input that is a linebake cache,
// that cache (assets are added in place); else default_cache_path of the input. "" for several
// inputs without -o (which bake refuses).
std::string bake_output_path(const BakeOptions& options);
// The /lines step's identity: the inputs' content hash (every file's bytes in order, or a synth
// source's parameters) and the provenance key made of it, the format and the invalid policy.
struct LinesIdentity {
  std::string source_hash, key, format, policy;
  std::string origin;  // as asked ("auto", or the numbers as origin_text writes them); "" none
};
// Bytes of memory one input point costs while it passes through the asset builders (the line
// set's arrays, the tube rings and triangles, voxel records, Embree buffers): what sets the
// batch size within a memory budget.
uint64_t cost_per_point(const BakeOptions& options, const LineSet& header, bool tubes, bool voxels,
                        bool embree);
// `file_hashes`: hash_file() of each input, in order, where the caller has them already
// (linebake-mpi hashes the files on several ranks); empty: computed here.
LinesIdentity lines_identity(const BakeOptions& options,
                             const std::vector<std::string>& file_hashes = {});
// Refuses (InputError) lines too small for the float32 geometry of the assets that have it
// (tubes, Embree's curves, rtx): a diagonal under kMinGeometrySpan, or every point the same.
void check_geometry_span(const LineSetStats& stats, const BakeOptions& options);
// "" or a note that the lines lie so far from the origin, for their extent, that float32
// positions lose more than 1e-4 of the extent (coordinates 1e6 over an extent of 1: steps of
// 0.06).
std::string far_from_origin_note(const LineSetStats& stats);
// Refuses (OutputError) a bake whose estimate (result.estimate) less what it has written already
// passes the room on the cache's file system (result.free_bytes), unless options.space_check is
// off.
void check_free_space(const BakeResult& result, uint64_t already_written,
                      const BakeOptions& options);
// Throws InputError (bad input), OutputError (cache not writable) or Error (bad options).
BakeResult bake(const BakeOptions& options);

// Provenance key of the tube step for a line set with this content hash.
std::string tubes_key(const std::string& lines_hash, const TubeOptions& tubes,
                      Compression compression, int level);
nlohmann::json to_json(const TubeOptions& tubes);
std::string voxels_key(const std::string& lines_hash, const VoxelOptions& voxels,
                       Compression compression, int level);
nlohmann::json to_json(const VoxelOptions& voxels);
std::string embree_key(const std::string& lines_hash, const EmbreeOptions& embree,
                       const TubeOptions& tubes, Compression compression, int level);
nlohmann::json to_json(const EmbreeOptions& embree, const TubeOptions& tubes);
// The Embree step's curves (geometry, world radius, attribute) for these options; Error for
// options that make no curves.
StoredCurves embree_curves(const BakeOptions& options, const LineSet& header,
                           const LineSetStats& stats);

// The threads the builders may use, as the provenance records them.
uint64_t build_threads();

}  // namespace linebake
