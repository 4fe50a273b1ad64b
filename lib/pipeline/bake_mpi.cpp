#include "pipeline/bake_mpi.hpp"

#include <hdf5.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <limits>
#include <numeric>
#include <sstream>

#include "cache/embree_store.hpp"
#include "cache/line_store.hpp"
#include "cache/tube_store.hpp"
#include "cache/voxel_store.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/hash.hpp"
#include "core/interrupt.hpp"
#include "core/json_file.hpp"
#include "core/measure.hpp"
#include "core/memory_budget.hpp"
#include "core/output_lock.hpp"
#include "core/progress.hpp"
#include "lines/line_spool.hpp"
#include "lines/validate.hpp"
#include "pipeline/bake_budget.hpp"
#include "pipeline/bake_mpi_voxels.hpp"
#include "pipeline/mpi_ranks.hpp"
#include "synth/synth.hpp"

#ifndef H5_HAVE_PARALLEL
#error "bake_mpi.cpp needs the MPI build of HDF5 (libhdf5-openmpi-dev)"
#endif

namespace linebake {
namespace {

// One input file's share of this rank: lines [first, end) of it, by the file's own line index.
struct FileRange {
  size_t file = 0;
  uint64_t first = 0, end = 0;
};

// The lines of a rank's file ranges, one batch at a time; lines of a file before the range are
// read and skipped (formats read front to back), the file is closed after the range.
class RangeReader {
 public:
  // `frame`: the first file's origin, the others' read in it (formats/registry.hpp).
  RangeReader(const std::vector<std::string>& files, std::vector<FileRange> ranges,
              const ReadOptions& read, const Origin& frame)
      : files_(files), ranges_(std::move(ranges)), read_(read), frame_(frame) {}

  // False at the end. `where`: the file and its lines of the batch, for messages.
  bool next(LineSet& batch, uint64_t max_points, std::string& where) {
    while (range_ < ranges_.size()) {
      const FileRange& r = ranges_[range_];
      if (!reader_) {
        reader_ = open_in_frame(files_[r.file], read_, frame_);
        line_ = 0;
      }
      LineSet read;
      if (line_ >= r.end || !reader_->next(read, max_points)) {
        reader_.reset();
        ++range_;
        continue;
      }
      const uint64_t first = line_, end = line_ + read.line_count();
      line_ = end;
      const uint64_t keep_first = std::max(first, r.first), keep_end = std::min(end, r.end);
      if (keep_first >= keep_end) continue;
      batch = header_of(read);
      copy_lines(read, size_t(keep_first - first), size_t(keep_end - first), batch);
      first_line_ = keep_first;
      where = files_[r.file] + " (lines " + std::to_string(keep_first) + ".." +
              std::to_string(keep_end - 1) + ")";
      return true;
    }
    return false;
  }
  // The batch's first line, counted in its file.
  uint64_t first_line() const { return first_line_; }

 private:
  const std::vector<std::string>& files_;
  std::vector<FileRange> ranges_;
  ReadOptions read_;
  Origin frame_;
  size_t range_ = 0;
  uint64_t line_ = 0, first_line_ = 0;
  std::unique_ptr<LineReader> reader_;
};

// Every rank's share of the inputs: the lines of all files, in order, cut into `ranks` equal
// ranges of lines; a range covers whole files and parts of the files at its ends.
std::vector<FileRange> share_of(const std::vector<uint64_t>& lines_per_file, int rank, int ranks) {
  const uint64_t total = std::accumulate(lines_per_file.begin(), lines_per_file.end(), uint64_t{0});
  const uint64_t begin = total * uint64_t(rank) / uint64_t(ranks);
  const uint64_t end = total * uint64_t(rank + 1) / uint64_t(ranks);
  std::vector<FileRange> out;
  uint64_t at = 0;
  for (size_t f = 0; f < lines_per_file.size(); ++f) {
    const uint64_t file_begin = at, file_end = at + lines_per_file[f];
    at = file_end;
    const uint64_t a = std::max(begin, file_begin), b = std::min(end, file_end);
    if (a < b) out.push_back({f, a - file_begin, b - file_begin});
  }
  return out;
}

nlohmann::json stats_json(const LineSetStats& s) {
  nlohmann::json j = to_json(s);
  j["position_bytes"] = s.position_bytes;
  j["offset_bytes"] = s.offset_bytes;
  j["attribute_bytes"] = s.attribute_bytes;
  return j;
}

LineSetStats stats_from(const std::string& text) {
  const nlohmann::json j = nlohmann::json::parse(text);
  LineSetStats s = line_stats_from_json(j, "(rank statistics)");
  s.position_bytes = j.at("position_bytes");
  s.offset_bytes = j.at("offset_bytes");
  s.attribute_bytes = j.at("attribute_bytes");
  return s;
}

// Every rank's figures in rank order into `stats` ("rank_figures"), with the rank count and the
// load imbalance: the slowest rank's `first` + `second` seconds over the mean. Collective.
void add_rank_figures(const Ranks& ranks, const nlohmann::json& mine, const char* first,
                      const char* second, nlohmann::json& stats) {
  nlohmann::json list = nlohmann::json::array();
  double max_s = 0, sum_s = 0;
  for (const std::string& r : ranks.allgather(json_text(mine))) {
    list.push_back(nlohmann::json::parse(r));
    const double s = list.back()[first].get<double>() + list.back()[second].get<double>();
    max_s = std::max(max_s, s);
    sum_s += s;
  }
  stats["ranks"] = ranks.size;
  stats["rank_figures"] = list;
  stats["imbalance"] = sum_s > 0 ? max_s / (sum_s / ranks.size) : 1.0;
}

}  // namespace

BakeResult bake_mpi(const BakeOptions& options_in, MPI_Comm comm) {
  const auto bake_start = std::chrono::steady_clock::now();
  const Ranks ranks(comm);
  BakeOptions options = options_in;
  if (options.inputs.empty()) options.inputs = {options.input};
  const std::vector<std::string>& inputs = options.inputs;
  if (options.input.empty())
    options.input = inputs.front() + " and " + std::to_string(inputs.size() - 1) + " more";
  std::sort(options.assets.begin(), options.assets.end());
  options.assets.erase(std::unique(options.assets.begin(), options.assets.end()),
                       options.assets.end());
  const auto asked = [&](const char* asset) {
    return std::find(options.assets.begin(), options.assets.end(), asset) != options.assets.end();
  };
  for (const std::string& asset : options.assets)
    if (asset != "tubes" && asset != "voxels" && asset != "embree")
      throw UsageError(
          "linebake-mpi builds /lines, tubes, voxels and embree, not " + asset +
          "; add it afterwards with the serial linebake bake of the same inputs and -o "
          "(it reuses what is up to date)");
  const bool build_tubes = asked("tubes"), build_voxels = asked("voxels"),
             build_embree = asked("embree");
  if (options.dry_run) throw UsageError("--dry-run: ask the serial linebake bake for the estimate");
  BakeResult result;
  // The serial bake's rule (the CLI locks that path around the job); a cache as the input without
  // -o would be baked in place, which the serial bake does and the job does not.
  result.cache = bake_output_path(options);
  if (result.cache.empty())
    throw UsageError("several inputs make one line set: name its cache with -o");
  if (options.cache.empty() && result.cache == inputs[0])
    throw UsageError(inputs[0] +
                     " is a linebake cache: linebake-mpi does not add assets to a cache in place; "
                     "give -o, or add them with the serial linebake bake");
  // The default: half of the node's memory, shared by the ranks on this node.
  int ranks_on_node = 1;
  {
    MPI_Comm node;
    MPI_Comm_split_type(comm, MPI_COMM_TYPE_SHARED, ranks.rank, MPI_INFO_NULL, &node);
    MPI_Comm_size(node, &ranks_on_node);
    MPI_Comm_free(&node);
  }
  const uint64_t budget_bytes = options.memory_budget == BakeOptions::kDefaultBudget
                                    ? default_memory_budget() / uint64_t(ranks_on_node)
                                : options.memory_budget == BakeOptions::kUnlimited
                                    ? 0
                                    : options.memory_budget;
  result.memory_budget_bytes = budget_bytes;
  const bool show = options.progress && ranks.rank == 0;

  // Rank 0 checks the output and names the temporary file every rank writes.
  // Held by rank 0 until the cache is renamed into place, as the serial bake holds it: a serial
  // bake adding assets to this path meanwhile would replace this one's cache with the old lines.
  std::optional<OutputLock> one_writer;
  std::string temp;
  ranks.agree([&] {
    if (ranks.rank != 0) return;
    // Written through a symbolic link, as the serial bake's AtomicFile does; a device refused.
    result.cache = output_target(result.cache);
    one_writer.emplace(result.cache);
    if (!synth::is_synth_source(inputs[0])) refuse_input_as_output(result.cache, inputs);
    if (std::filesystem::exists(result.cache) && !options.force && !is_linebake_cache(result.cache))
      throw OutputError(result.cache, "exists and is not a linebake cache; --force replaces it");
    remove_stale_temporaries(result.cache);
    temp = temporary_name(result.cache);
  });
  temp = ranks.broadcast(temp);
  result.cache = ranks.broadcast(result.cache);

  // Lines per file: from the header where the format has it, else by reading the file; the
  // files are counted round robin.
  std::vector<uint64_t> lines_per_file(inputs.size(), 0);
  std::string my_hashes;  // "index hash\n" for the files this rank hashed
  // What readers count by reading every line (LineReader::counts_read), summed over the files
  // this rank counted, then over the ranks: the serial bake's metadata whatever the rank count.
  // (A format whose header gives its line count is not read here and has none.)
  std::map<std::string, uint64_t> counts_read;
  ReadOptions read;
  read.format = options.format;
  // A file read whole (OBJ, VTK, VTP) is held within this rank's budget while it is read.
  // Started before anything is read, as the serial bake's: a file read whole for its count
  // leaves its freed heap resident (M_TRIM_THRESHOLD, linebake_mpi.cpp), which a later start
  // would count against the least to work in.
  MemoryBudget budget(budget_bytes);
  if (budget_bytes != 0) read.memory_limit = budget.available();
  LineSet header;
  ranks.agree([&] {
    // Every rank finds the same origin (the same first point of the same files).
    read.origin = resolve_origin(options.origin, inputs, read);
    header = header_of(open_line_reader(inputs[0], read)->header());
    // Before any line is read, as the serial bake (it had failed, exit 4, once the tubes began).
    check_attribute_options(options, header);
    for (size_t f = size_t(ranks.rank); f < inputs.size(); f += size_t(ranks.size)) {
      // The input's identity is its files' bytes: each file hashed by one rank.
      if (!synth::is_synth_source(inputs[f]))
        my_hashes += std::to_string(f) + " " + hash_file(inputs[f]) + "\n";
      auto reader = open_line_reader(inputs[f], read);
      // Every file of one line set carries the first's attributes, as the serial bake checks.
      if (f > 0) check_same_attributes(header, inputs[0], reader->header(), inputs[f]);
      if (const auto n = reader->line_count_hint()) {
        lines_per_file[f] = *n;
        continue;
      }
      // Counted in batches of a million points, fewer where the budget leaves less.
      const uint64_t count_points =
          batch_points_within(reader->header(), read.memory_limit, uint64_t{1} << 20);
      LineSet batch;
      while (reader->next(batch, count_points)) lines_per_file[f] += batch.line_count();
      add_counts(counts_read, reader->counts_read());
    }
  });
  {
    std::string mine;  // "key count\n"
    for (const auto& [key, n] : counts_read) mine += key + " " + std::to_string(n) + "\n";
    counts_read.clear();
    for (const std::string& part : ranks.allgather(mine)) {
      std::istringstream lines(part);
      std::string key;
      uint64_t n = 0;
      while (lines >> key >> n) counts_read[key] += n;
    }
    if (const std::string note = counts_read_note(counts_read); !note.empty())
      result.notes.push_back(options.input + ": " + note);
  }
  lines_per_file = ranks.sum(lines_per_file);
  std::vector<std::string> file_hashes;
  if (!synth::is_synth_source(inputs[0])) {
    file_hashes.resize(inputs.size());
    for (const std::string& part : ranks.allgather(my_hashes)) {
      size_t at = 0;
      while (at < part.size()) {
        const size_t space = part.find(' ', at), end = part.find('\n', at);
        file_hashes[std::stoull(part.substr(at, space - at))] =
            part.substr(space + 1, end - space - 1);
        at = end + 1;
      }
    }
  }

  // Read: this rank's share into its spool, validated batch by batch as the serial bake does.
  const auto read_start = std::chrono::steady_clock::now();
  const double cpu_start = process_cpu_seconds();
  const uint64_t rss_before = current_rss_bytes();
  // The least to work in and the fixed buffers, as the serial bake: each rank's own budget (its
  // resident memory differs), refused on every rank if on one.
  ranks.agree([&] { reserve_bake_fixed_buffers(budget, false); });
  // As the serial bake sizes its batches: a quarter of the budget through the builders.
  const uint64_t per_point =
      cost_per_point(options, header, build_tubes, build_voxels, build_embree);
  const uint64_t batch_points =
      budget.unlimited()
          ? uint64_t{1} << 21
          : std::clamp<uint64_t>(budget.available() / 4 / per_point, 1024, uint64_t{1} << 21);
  result.batch_points = batch_points;
  ranks.agree([&] {
    if (!budget.unlimited())
      budget.reserve(batch_points * per_point,
                     "one batch of " + std::to_string(batch_points) + " points through every step");
  });
  std::optional<LineSpool> spool;
  LineStatsBuilder local_stats(header);
  ValidationReport total;
  const std::string spill_name = result.cache + ".rank" + std::to_string(ranks.rank);
  ranks.agree([&] {
    spool.emplace(spill_name, header);
    RangeReader reader(inputs, share_of(lines_per_file, ranks.rank, ranks.size), read,
                       origin_of(header, inputs[0]));
    LineSet batch;
    std::string where;
    TerminalProgress progress("reading " + options.input);
    uint64_t lines_done = 0;
    const uint64_t lines_total =
        std::accumulate(lines_per_file.begin(), lines_per_file.end(), uint64_t{0});
    while (reader.next(batch, batch_points, where)) {
      throw_if_interrupted();
      lines_done += batch.line_count();
      total.add(validate(batch, options.on_invalid, where, reader.first_line()));
      for (size_t l = 0; l < batch.line_count(); ++l)
        check_line_fits_batch(budget, batch.line_size(l), per_point, where,
                              reader.first_line() + l);
      local_stats.add(batch);
      spool->append(batch);
      if (show) progress.update(lines_done * uint64_t(ranks.size), lines_total);
    }
  });
  const double read_s = seconds_since(read_start);

  // The whole set's figures, and where this rank's lines and points start in it.
  LineSetStats stats;
  stats = stats_from(ranks.reduce(
      json_text(stats_json(local_stats.stats())),
      [](const std::string& a, const std::string& b) {
        return json_text(stats_json(merge(stats_from(a), stats_from(b))));
      },
      [](const std::string& whole) { return whole; }));
  if (stats.lines == 0)  // in the serial bake's words (the ranks' repairs are not gathered here)
    throw InputError(options.input, "",
                     "has no lines, or none left once repaired: nothing to bake (an empty line "
                     "set reads and converts, but a cache holds lines); no cache written");
  check_geometry_span(stats, options);  // the stats are every rank's: so is the outcome
  if (const std::string note = far_from_origin_note(stats); !note.empty())
    result.notes.push_back(options.input + ": " + note);
  {
    // The serial bake's space check, by rank 0 for the file system that holds the cache; the
    // lines' spill of every rank (beside the cache) is written already.
    const uint64_t spilled = ranks.sum(std::vector<uint64_t>{spool ? spool->bytes() : 0})[0];
    ranks.agree([&] {
      if (ranks.rank != 0) return;
      result.estimate = estimate_bake(stats, header, options, budget.available());
      result.free_bytes = free_bytes_for(result.cache);
      check_free_space(result, spilled, options);
    });
  }
  LinePiece piece;
  piece.first_line = ranks.exclusive_sum(local_stats.stats().lines);
  piece.first_point = ranks.exclusive_sum(local_stats.stats().points);
  piece.first = ranks.rank == 0;
  piece.shared = true;
  const uint64_t my_lines = local_stats.stats().lines;
  const uint64_t rounds = ranks.max(spool->batches());
  // The voxel walk's records, and those the exchange brings, spill past their share.
  std::optional<VoxelStreamBuilder> voxels;
  uint64_t voxel_merge_bytes = uint64_t{1} << 30, voxel_exchange_bytes = uint64_t{1} << 30;
  if (build_voxels)
    ranks.agree([&] {
      VoxelMemory memory;
      memory.spill_near = spill_name;
      if (!budget.unlimited()) {
        const VoxelStreamBuilder placement(header, stats, options.voxels);
        budget.reserve(placement.fixed_bytes(),
                       "the voxel grid's chord counts and density mip levels (" +
                           std::to_string(placement.description().voxel_count()) + " voxels)");
        // Every batch's run index, kept to the merge (as the serial bake counts it), and those
        // of the runs the exchange brings, each a wave's units.
        budget.reserve(spool->batches() * placement.run_index_bytes() +
                           placement.received_index_bytes(ranks.size),
                       "the voxel walk's index of " + std::to_string(spool->batches()) +
                           " batches of " + std::to_string(batch_points) +
                           " points and of the runs received from " + std::to_string(ranks.size) +
                           " ranks");
        // Of what the batches (reserved above, a quarter) and the fixed buffers leave: a third
        // for the records walked here, a third for those received, a sixth for the exchange's
        // buffers and the rest for the merge (which follows the exchange).
        const uint64_t left = budget.available();
        voxel_merge_bytes = std::min<uint64_t>(left / 6, uint64_t{256} << 20);
        voxel_exchange_bytes = left / 6;
        memory.records_bytes = left / 3;
      }
      memory.merge_bytes = voxel_merge_bytes;
      voxels.emplace(header, stats, options.voxels, memory);
      voxels->start_at_line(piece.first_line);
    });
  StoredCurves curves;  // the Embree step's description
  if (build_embree)
    ranks.agree([&] {
      curves = embree_curves(options, header, stats);
      curve_part_limit(options.embree);  // throws for a limit no part can meet, on every rank
    });
  {
    const auto notes = ranks.allgather(total.clean() ? "" : total.summary());
    for (int r = 0; r < ranks.size; ++r)
      if (!notes[size_t(r)].empty())
        result.notes.push_back("rank " + std::to_string(r) + ": " + notes[size_t(r)]);
  }

  // From here on every rank writes the same file: an error is that of a collective call, which
  // the others cannot be told of in time. The failing rank removes the file and ends the job.
  RankFigures mine;
  mine.rank = ranks.rank;
  mine.lines = my_lines;
  mine.points = local_stats.stats().points;
  mine.read_s = read_s;
  const auto build_start = std::chrono::steady_clock::now();
  StepMeter meter;
  try {
    // An error past here unwinds this rank alone: its handles are left open, not closed
    // collectively with ranks that are elsewhere (which would wait for ever).
    const h5::LeaveOpenOnUnwind leave_open;
    using h5::Handle;
    Handle fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
    H5Pset_fapl_mpio(fapl, comm, MPI_INFO_NULL);
    H5Pset_all_coll_metadata_ops(fapl, true);
    H5Pset_coll_metadata_write(fapl, true);
    Handle dxpl(H5Pcreate(H5P_DATASET_XFER), H5Pclose);
    H5Pset_dxpl_mpio(dxpl, H5FD_MPIO_COLLECTIVE);
    ParallelWrite parallel;
    parallel.fapl = fapl;
    parallel.dxpl = dxpl;
    parallel.temp_path = temp;
    parallel.owner = ranks.rank == 0;
    parallel.any = [&](std::string& bytes) { ranks.any(bytes); };
    parallel.sum = [&](uint64_t v) { return ranks.sum(v); };
    parallel.reduce = [&](const std::string& piece_here, const ParallelWrite::Join& join,
                          const ParallelWrite::Finish& finish) {
      return ranks.reduce(piece_here, join, finish);
    };
    CacheWriter writer(result.cache, options.compression, options.compression_level, parallel);

    const LinesIdentity identity = lines_identity(options, file_hashes);
    // Pass 1: /lines, the content hash and the tubes' kept points.
    LineStoreWriter store(writer, header, stats, piece);
    LineContentHash hash(header, piece);
    std::optional<TubeStreamBuilder> tubes;
    if (build_tubes) tubes.emplace(header, stats, options.tubes);
    std::vector<uint64_t> kept, line_points;  // per line: kept by the tubes; points (Embree)
    uint64_t skipped = 0;
    {
      TerminalProgress progress("writing /lines");
      auto replay = spool->replay();
      LineSet batch;
      for (uint64_t round = 0; round < rounds; ++round) {
        throw_if_interrupted();
        if (replay->next(batch, UINT64_MAX)) {
          store.append(batch);
          hash.add(batch);
          if (voxels) voxels->add(batch);
          if (build_embree)
            for (size_t l = 0; l < batch.line_count(); ++l)
              line_points.push_back(batch.line_size(l));
          if (tubes) {
            const std::vector<uint64_t> k = tubes->kept_points(batch);
            for (size_t l = 0; l < k.size(); ++l) skipped += batch.line_size(l) - k[l];
            kept.insert(kept.end(), k.begin(), k.end());
          }
        }
        writer.write_round();
        if (show) progress.update(round + 1, rounds);
      }
    }
    const std::string lines_hash = ranks.reduce(
        hash.piece(), LineContentHash::join,
        [&](const std::string& whole) { return LineContentHash::finish(header, whole); });
    // Provenance: rank 0's figures, the same bytes on every rank (attributes are collective);
    // the CPU time is every rank's since the read began (a sum: every rank calls this).
    const auto finish = [&](Provenance& p, const std::string& step) {
      p.step = step;
      p.created = utc_now_iso8601();
      p.threads = build_threads();
      p.compression = to_string(options.compression);
      p.memory_budget = budget_bytes;
      p.build.wall_s = seconds_since(build_start) + read_s;
      p.build.peak_rss = peak_rss_bytes();
      p.build.rss_before = rss_before;
      p.build.cpu_s =
          double(ranks.sum(uint64_t(std::llround((process_cpu_seconds() - cpu_start) * 1e6)))) /
          1e6;
      // Every step's figures are the job's since it began reading: shared with the others.
      p.build.built_with.clear();
      for (const char* other : {"embree", "lines", "tubes", "voxels"})
        if (other != step && (std::string(other) == "lines" || asked(other)))
          p.build.built_with.push_back(other);
    };
    Provenance lines_p;
    finish(lines_p, "lines");
    lines_p.key = identity.key;
    lines_p.input_hash = identity.source_hash;
    lines_p.parameters = {
        {"source", options.input}, {"format", identity.format}, {"on_invalid", identity.policy}};
    if (!identity.origin.empty()) lines_p.parameters["origin"] = identity.origin;
    if (inputs.size() > 1) lines_p.parameters["files"] = inputs;
    lines_p.stats = to_json(stats);
    lines_p.stats["content_hash"] = lines_hash;
    lines_p =
        provenance_from_json(nlohmann::json::parse(ranks.broadcast(json_text(to_json(lines_p)))));
    std::map<std::string, std::string> metadata = header.metadata;
    if (!synth::is_synth_source(inputs[0])) metadata.emplace("source", options.input);
    add_counts_read(metadata, counts_read);
    store.close(metadata, lines_p);

    // Pass 2: the tubes, planned from every rank's kept points.
    if (tubes) {
      // Rank 0 plans the chunks from every rank's kept points (the one copy of 8 bytes per
      // line) and tells each rank where its rows start; the plan itself is a few chunks.
      const std::vector<uint64_t> all_kept = ranks.gather(kept);
      const std::vector<uint64_t> firsts = ranks.gather({piece.first_line, my_lines});
      std::string plan_bytes, error;
      std::vector<uint64_t> places;  // per rank: first chunk, vertices, indices, last chunk
      uint64_t totals[3] = {stats.lines, 0, 0};  // lines, dropped, skipped
      const uint64_t skipped_all = ranks.sum(skipped);
      if (ranks.rank == 0) {
        try {
          tubes->plan_kept(all_kept, skipped_all);
          const std::vector<TubeChunkPlan>& chunks = tubes->finish_plan();
          plan_bytes.assign(reinterpret_cast<const char*>(chunks.data()),
                            chunks.size() * sizeof(TubeChunkPlan));
          for (int r = 0; r < ranks.size; ++r) {
            const uint64_t first = firsts[2 * size_t(r)], count = firsts[2 * size_t(r) + 1];
            const auto p = tubes->position_of(first);
            places.insert(places.end(), {p.chunk, p.vertices, p.indices,
                                         count ? tubes->position_of(first + count - 1).chunk : 0});
          }
          totals[1] = tubes->description().lines_dropped;
          totals[2] = tubes->description().points_skipped;
        } catch (const std::exception& e) {
          error = e.what();
        }
      }
      error = ranks.broadcast(error);
      if (!error.empty()) throw Error(error);  // every rank alike: no line has two points
      plan_bytes = ranks.broadcast(plan_bytes);
      MPI_Bcast(totals, 3, MPI_UINT64_T, 0, comm);
      uint64_t place[4] = {};
      MPI_Scatter(places.data(), 4, MPI_UINT64_T, place, 4, MPI_UINT64_T, 0, comm);
      std::vector<TubeChunkPlan> plan(plan_bytes.size() / sizeof(TubeChunkPlan));
      if (!plan.empty()) std::memcpy(plan.data(), plan_bytes.data(), plan.size() * sizeof plan[0]);
      tubes->adopt_plan(plan, totals[0], totals[1], totals[2], std::move(kept), piece.first_line,
                        {size_t(place[0]), place[1], place[2]});
      TubeStoreSink sink(writer, tubes->description(), plan, size_t(place[0]), place[1], place[2],
                         my_lines ? size_t(place[3]) : 0);
      TerminalProgress progress("building tubes");
      auto replay = spool->replay();
      LineSet batch;
      bool done = my_lines == 0;
      uint64_t next_line = piece.first_line;
      for (uint64_t round = 0; round < rounds; ++round) {
        throw_if_interrupted();
        // Only the chunks in use are open: those this round's batches reach are made on every
        // rank, and those no rank will write to again are closed after the round's writes.
        uint64_t first = 1, last = 0;
        if (!done && replay->next(batch, UINT64_MAX)) {
          if (batch.line_count() > 0) {
            first = sink.chunk_of_line(next_line);
            last = sink.chunk_of_line(next_line + batch.line_count() - 1);
          }
        } else {
          done = true;
        }
        sink.open_chunks(ranks.allgather(std::vector<uint64_t>{first, last}));
        if (!done) {
          tubes->build(batch, sink);
          next_line += batch.line_count();
        }
        writer.write_round();
        sink.close_finished(ranks.allgather(
            std::vector<uint64_t>{done ? UINT64_MAX : sink.frontier(), sink.last_chunk()}));
        if (show) progress.update(round + 1, rounds);
      }
      Provenance p;
      finish(p, "tubes");
      p.key = tubes_key(lines_hash, options.tubes, options.compression, options.compression_level);
      p.input_hash = lines_hash;
      p.parameters = to_json(options.tubes);
      const TubeMesh& mesh = tubes->description();
      p.stats = tube_stats(mesh, plan);
      // Every rank's figures, and the imbalance of the build (max / mean).
      mine.build_s = seconds_since(build_start);
      mine.bytes = writer.bytes_written();
      add_rank_figures(ranks,
                       {{"rank", mine.rank},
                        {"lines", mine.lines},
                        {"points", mine.points},
                        {"read_s", mine.read_s},
                        {"build_s", mine.build_s},
                        {"bytes", mine.bytes},
                        {"peak_rss_bytes", peak_rss_bytes()}},
                       "read_s", "build_s", p.stats);
      p = provenance_from_json(nlohmann::json::parse(ranks.broadcast(json_text(to_json(p)))));
      sink.close(mesh, p);
      BakeStep step{"tubes", true, p};
      result.steps.push_back(step);
      tubes.reset();
    }

    // Embree's buffers: parts planned on rank 0 from every line's points, as the serial bake
    // plans them; each rank writes its lines' rows.
    if (build_embree) {
      double prepare_s = 0;
      const std::vector<uint64_t> all_points = ranks.gather(line_points);
      std::vector<uint64_t>().swap(line_points);
      const std::vector<uint64_t> firsts = ranks.gather({piece.first_line});
      std::string parts_bytes, error;
      std::vector<uint64_t> pieces;  // per rank: part, points and segments before its first line
      if (ranks.rank == 0) {
        try {
          CurvePartPlanner planner(curve_part_limit(options.embree));
          for (uint64_t n : all_points) planner.add(n);
          const std::vector<CurvePart> parts = planner.finish();
          parts_bytes.assign(reinterpret_cast<const char*>(parts.data()),
                             parts.size() * sizeof(CurvePart));
          for (int r = 0; r < ranks.size; ++r) {
            const uint64_t line = firsts[size_t(r)];
            size_t part = 0;
            while (part < parts.size() && parts[part].end_line <= line) ++part;
            uint64_t points = 0, segments = 0;
            if (part < parts.size())
              for (uint64_t l = parts[part].first_line; l < line; ++l) {
                points += all_points[l];
                segments += all_points[l] > 1 ? all_points[l] - 1 : 0;
              }
            pieces.insert(pieces.end(), {uint64_t(part), points, segments});
          }
        } catch (const std::exception& e) {
          error = e.what();
        }
      }
      error = ranks.broadcast(error);
      if (!error.empty()) throw Error(error);  // every rank alike
      parts_bytes = ranks.broadcast(parts_bytes);
      std::vector<CurvePart> parts(parts_bytes.size() / sizeof(CurvePart));
      if (!parts.empty())
        std::memcpy(parts.data(), parts_bytes.data(), parts.size() * sizeof parts[0]);
      uint64_t place[3] = {};
      MPI_Scatter(pieces.data(), 3, MPI_UINT64_T, place, 3, MPI_UINT64_T, 0, comm);
      EmbreeStoreWriter embree(writer, parts, curves.geometry, curves.radius, curves.attribute,
                               {piece.first_line, size_t(place[0]), place[1], place[2]});
      TerminalProgress progress("preparing Embree buffers");
      auto replay = spool->replay();
      LineSet batch;
      for (uint64_t round = 0; round < rounds; ++round) {
        throw_if_interrupted();
        if (replay->next(batch, UINT64_MAX)) {
          const auto start = std::chrono::steady_clock::now();
          embree.append(batch);
          prepare_s += seconds_since(start);
        }
        writer.write_round();
        if (show) progress.update(round + 1, rounds);
      }
      Provenance p;
      finish(p, "embree");
      p.key = embree_key(lines_hash, options.embree, options.tubes, options.compression,
                         options.compression_level);
      p.input_hash = lines_hash;
      p.parameters = to_json(options.embree, options.tubes);
      p.stats = embree_stats(options.embree, curves, ranks.max_value(prepare_s), embree);
      p.stats["ranks"] = ranks.size;
      p.stats["bvh"] =
          "not built under MPI (it needs the whole line set in one process); render builds it";
      p.memory_bytes = embree.buffer_bytes();
      p = provenance_from_json(nlohmann::json::parse(ranks.broadcast(json_text(to_json(p)))));
      embree.close(p);
      result.steps.push_back(BakeStep{"embree", true, p});
    }

    // The voxels: records to the ranks that own their voxels, merged there. The steps before
    // freed their buffers (and HDF5 its filtered chunks' ones), which the heap keeps under
    // linebake-mpi's trim threshold: given back first, else they stay resident through the
    // exchange and merge (2 ranks, tubes and voxels under 128M: 135 to 145 MiB a rank, 22 MiB of
    // it such free heap).
    if (voxels) {
      trim_free_heap();
      merge_voxels_mpi(
          ranks, *voxels, writer, voxel_exchange_bytes, voxel_merge_bytes, show,
          [&](const nlohmann::json& figures, uint64_t chords, uint64_t bytes_with_density) {
            Provenance p;
            finish(p, "voxels");
            p.key = voxels_key(lines_hash, options.voxels, options.compression,
                               options.compression_level);
            p.input_hash = lines_hash;
            p.parameters = to_json(options.voxels);
            p.spill_bytes = ranks.sum(voxels->spilled_bytes());
            const VoxelGrid& g = voxels->description();
            p.stats = voxel_stats(g, chords, bytes_with_density,
                                  ranks.max(voxels->peak_record_bytes()), p.spill_bytes);
            add_rank_figures(ranks, figures, "exchange_s", "merge_s", p.stats);
            p = provenance_from_json(nlohmann::json::parse(ranks.broadcast(json_text(to_json(p)))));
            result.steps.push_back(BakeStep{"voxels", true, p});
            if (g.chords_dropped) result.notes.push_back(dropped_chords_note(g));
            return p;
          });
      voxels.reset();
    }
    writer.commit();
  } catch (const std::exception& e) {
    std::remove(temp.c_str());
    spool.reset();
    const auto* interrupted = dynamic_cast<const Interrupted*>(&e);
    const bool output = dynamic_cast<const OutputError*>(&e) != nullptr;
    throw CollectiveWriteFailed("rank " + std::to_string(ranks.rank) + ": " + e.what(),
                                interrupted ? 128 + interrupted->signal()
                                : output    ? 3
                                            : 4);
  }
  spool.reset();
  MPI_Barrier(comm);  // rank 0 has renamed the file
  result.written = true;
  result.steps.insert(result.steps.begin(), BakeStep{"lines", true, {}});
  const StepFigures f = meter.stop();
  BakeStage stage;
  stage.name = "build (rank " + std::to_string(ranks.rank) + ")";
  stage.wall_s = f.wall_s;
  stage.cpu_s = f.cpu_s;
  stage.peak_rss_bytes = f.peak_rss;
  result.stages.push_back(stage);
  result.peak_rss_bytes = f.peak_rss;
  result.wall_s = seconds_since(bake_start);
  return result;
}

}  // namespace linebake
