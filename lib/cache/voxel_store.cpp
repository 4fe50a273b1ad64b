#include "cache/voxel_store.hpp"

#include <algorithm>
#include <memory>
#include <optional>

#include "core/error.hpp"
#include "core/json_file.hpp"

namespace linebake {

static std::string density_name(size_t level) {
  return std::string(kVoxelsGroup) + "/density_" + std::to_string(level);
}

static nlohmann::json describe(const VoxelGrid& g, size_t density_levels) {
  return {{"resolution", g.resolution},
          {"origin", g.origin},
          {"voxel_size", g.voxel_size},
          {"quantization", g.quantization},
          {"max_chords_per_voxel", g.max_chords_per_voxel},
          {"attribute", g.attribute},
          {"attribute_range", g.attribute_range},
          {"density_levels", density_levels},
          {"segments", g.segments},
          {"chords_dropped", g.chords_dropped},
          {"voxels_overflowed", g.voxels_overflowed},
          {"voxels_occupied", g.voxels_occupied},
          {"max_error", g.max_error},
          {"mean_error", g.mean_error}};
}

void store_voxels(CacheWriter& cache, const VoxelGrid& g, Provenance provenance) {
  cache.create_group(kVoxelsGroup);
  const std::string base = kVoxelsGroup;
  uint64_t disk = cache.write(base + "/offsets", g.offsets.data(), g.offsets.size());
  disk += cache.write(base + "/chords", g.chords.data(), g.chord_count(), 2);
  disk += cache.write(base + "/line_counts", g.line_counts.data(), g.line_counts.size());
  for (size_t level = 0; level < g.density.size(); ++level)
    disk += cache.write(density_name(level), g.density[level].data(), g.density[level].size());
  cache.write_attribute(kVoxelsGroup, "grid", json_text(describe(g, g.density.size())));
  provenance.disk_bytes = disk;
  provenance.memory_bytes = g.representation_bytes();
  cache.write_provenance(kVoxelsGroup, provenance);
}

struct VoxelStoreSink::State {
  CacheWriter* cache = nullptr;
  VoxelSinkPiece piece;
  std::optional<DatasetStream> offsets, chords, line_counts, density;
  uint64_t chord_count = 0, disk = 0, memory = 0, memory_with_density = 0;
};

VoxelStoreSink::VoxelStoreSink(CacheWriter& cache, VoxelSinkPiece piece)
    : state_(std::make_unique<State>()) {
  state_->cache = &cache;
  state_->piece = piece;
}

VoxelStoreSink::~VoxelStoreSink() = default;

void VoxelStoreSink::begin(const VoxelGrid& g, uint64_t chord_count) {
  State& s = *state_;
  s.cache->create_group(kVoxelsGroup);
  const std::string base = kVoxelsGroup;
  const uint64_t voxels = g.voxel_count();
  s.chord_count = chord_count;
  s.offsets.emplace(s.cache->stream<uint32_t>(base + "/offsets", voxels + 1));
  s.chords.emplace(s.cache->stream<uint32_t>(base + "/chords", chord_count, 2));
  s.line_counts.emplace(s.cache->stream<uint8_t>(base + "/line_counts", voxels));
  s.density.emplace(s.cache->stream<float>(density_name(0), voxels));
  if (s.cache->parallel()) {
    s.offsets->start_at(s.piece.first_voxel);
    s.chords->start_at(s.piece.first_chord);
    s.line_counts->start_at(s.piece.first_voxel);
    s.density->start_at(s.piece.first_voxel);
  }
}

void VoxelStoreSink::voxels(uint64_t, uint64_t count, const uint32_t* offsets,
                            const uint8_t* line_counts, const float* density,
                            const uint32_t* chords, uint64_t chord_count) {
  State& s = *state_;
  append_together({rows_of(*s.offsets, offsets, count), rows_of(*s.chords, chords, chord_count),
                   rows_of(*s.line_counts, line_counts, count),
                   rows_of(*s.density, density, count)});
}

void VoxelStoreSink::end(const VoxelGrid& g, uint32_t chord_count,
                         std::vector<Array<float>> coarse) {
  State& s = *state_;
  if (s.piece.last) s.offsets->append(&chord_count, 1);
  s.cache->write_round();
  s.disk += s.offsets->close() + s.chords->close() + s.line_counts->close() + s.density->close();
  // In a parallel cache the root alone has the coarse levels; every rank creates their datasets.
  const size_t levels = g.density_level_count();
  if (s.piece.root && coarse.size() + 1 != levels)
    throw Error("voxels: " + std::to_string(coarse.size() + 1) + " density levels, expected " +
                std::to_string(levels));
  s.memory = (g.voxel_count() + 1) * 4 + uint64_t(chord_count) * 8;  // offsets + chords
  s.memory_with_density = s.memory + g.voxel_count() * (1 + 4);
  for (size_t level = 1; level < levels; ++level) {
    const auto r = g.level_resolution(level);
    const uint64_t count = uint64_t(r[0]) * r[1] * r[2];
    DatasetStream stream = s.cache->stream<float>(density_name(level), count);
    if (s.piece.root) stream.append(coarse[level - 1].data(), count);
    s.cache->write_round();
    s.disk += stream.close();
    s.memory_with_density += count * sizeof(float);
  }
  s.cache->write_attribute(kVoxelsGroup, "grid", json_text(describe(g, levels)));
}

void VoxelStoreSink::close(Provenance provenance) {
  provenance.disk_bytes = state_->disk;
  provenance.memory_bytes = state_->memory;
  state_->cache->write_provenance(kVoxelsGroup, provenance);
}

uint64_t VoxelStoreSink::chord_count() const {
  return state_->chord_count;
}

uint64_t VoxelStoreSink::memory_with_density() const {
  return state_->memory_with_density;
}

// The grid's description (no arrays) and its density level count.
static VoxelGrid load_description(const CacheReader& cache, size_t& levels) {
  const std::string where = std::string("group ") + kVoxelsGroup;
  const auto text = cache.attribute(kVoxelsGroup, "grid");
  if (!text)
    throw InputError(cache.path(), where,
                     "missing: no voxel grid in this cache; add it with: linebake bake " +
                         cache.path() + " --assets voxels");
  VoxelGrid g;
  try {
    const auto j = nlohmann::json::parse(*text);
    g.resolution = j.at("resolution");
    g.origin = j.at("origin");
    g.voxel_size = j.at("voxel_size");
    g.quantization = j.at("quantization");
    g.max_chords_per_voxel = j.at("max_chords_per_voxel");
    g.attribute = j.at("attribute");
    g.attribute_range = j.at("attribute_range");
    levels = j.at("density_levels");
    g.segments = j.at("segments");
    g.chords_dropped = j.at("chords_dropped");
    g.voxels_overflowed = j.at("voxels_overflowed");
    g.voxels_occupied = j.at("voxels_occupied");
    g.max_error = j.at("max_error");
    g.mean_error = j.at("mean_error");
  } catch (const std::exception& e) {
    throw InputError(cache.path(), where, std::string("bad grid description: ") + e.what());
  }
  if (g.quantization != 16 && g.quantization != 32 && g.quantization != 64)
    throw InputError(cache.path(), where, "quantization must be 16, 32 or 64");
  return g;
}

VoxelGrid load_voxel_description(const CacheReader& cache) {
  size_t levels = 0;
  return load_description(cache, levels);
}

VoxelGrid load_voxels(const CacheReader& cache) {
  size_t levels = 0;
  VoxelGrid g = load_description(cache, levels);
  const uint64_t voxels = g.voxel_count();
  const std::string base = kVoxelsGroup;
  g.offsets = cache.read<uint32_t>(base + "/offsets", voxels + 1);
  g.chords = cache.read<uint32_t>(base + "/chords");
  if (g.offsets[0] != 0 || 2 * uint64_t(g.offsets[voxels]) != g.chords.size())
    throw InputError(cache.path(), "dataset " + base + "/offsets",
                     "does not match the " + std::to_string(g.chords.size() / 2) + " chords");
  for (uint64_t v = 0; v < voxels; ++v)
    if (g.offsets[v + 1] < g.offsets[v])
      throw InputError(cache.path(), "dataset " + base + "/offsets",
                       "decreasing at voxel " + std::to_string(v));
  g.line_counts = cache.read<uint8_t>(base + "/line_counts", voxels);
  for (size_t level = 0; level < levels; ++level) {
    const auto r = g.level_resolution(level);
    g.density.push_back(cache.read<float>(density_name(level), uint64_t(r[0]) * r[1] * r[2]));
  }
  return g;
}

namespace {

// The cache's voxel arrays read a piece at a time (read_rows), each checked against its stored
// hash once read whole (density level 0 where it was read), the offsets as load_voxels checks
// them, and the voxels holding lines against the description's count, which a reader may have
// sized its memory by (vdb_build_bytes).
class CachePieces : public VoxelPieces {
 public:
  explicit CachePieces(const CacheReader& cache)
      : cache_(cache),
        grid_(load_voxel_description(cache)),
        offsets_(cache.rows_check(name("offsets"))),
        line_counts_(cache.rows_check(name("line_counts"))),
        density_(cache.rows_check(density_name(0))),
        chords_(cache.rows_check(name("chords"))) {
    const uint64_t voxels = grid_.voxel_count();
    const auto expect = [&](const std::string& dataset, uint64_t rows, uint64_t columns) {
      const std::vector<uint64_t> shape = cache.shape(dataset);
      const uint64_t got = shape.empty() ? 1 : shape[0];
      if (got != rows || shape.size() > 2 || (shape.size() == 2 ? shape[1] : 1) != columns)
        throw InputError(cache.path(), "dataset " + dataset,
                         "shape " + shape_text(shape) + ", expected " + std::to_string(rows));
    };
    expect(name("offsets"), voxels + 1, 1);
    expect(name("line_counts"), voxels, 1);
    expect(density_name(0), voxels, 1);
    const std::vector<uint64_t> chords = cache.shape(name("chords"));
    if (chords.size() != 2 || chords[1] != 2)
      throw InputError(cache.path(), "dataset " + name("chords"), "not 2 words per chord");
    chord_rows_ = chords[0];
  }
  const VoxelGrid& description() const override { return grid_; }
  void offsets(uint64_t first, uint64_t count, uint32_t* out) override {
    cache_.read_rows(name("offsets"), first, count, out);
    offsets_.add(first, count, out);
    const std::string where = "dataset " + name("offsets");
    // Each offset once, in order: pieces read again (a range's closing offset) are skipped.
    for (uint64_t v = std::max(first, checked_); v < first + count; ++v) {
      if (v > checked_) throw Error("internal error: voxel offsets skipped at " + where);
      const uint32_t offset = out[v - first];
      if (v == 0 && offset != 0) throw InputError(cache_.path(), where, "does not start at 0");
      if (v > 0 && offset < last_)
        throw InputError(cache_.path(), where, "decreasing at voxel " + std::to_string(v - 1));
      if (offset > chord_rows_)
        throw InputError(cache_.path(), where,
                         "does not match the " + std::to_string(chord_rows_) +
                             " chords (past them at voxel " + std::to_string(v) + ")");
      checked_ = v + 1, last_ = offset;
    }
  }
  void line_counts(uint64_t first, uint64_t count, uint8_t* out) override {
    cache_.read_rows(name("line_counts"), first, count, out);
    line_counts_.add(first, count, out);
    for (uint64_t v = std::max(first, counted_); v < first + count; ++v) {
      occupied_ += out[v - first] > 0;
      if (occupied_ > grid_.voxels_occupied) throw occupied_mismatch("more");
    }
    counted_ = std::max(counted_, first + count);
  }
  void density(uint64_t first, uint64_t count, float* out) override {
    cache_.read_rows(density_name(0), first, count, out);
    density_.add(first, count, out);
    density_read_ = true;
  }
  void chords(uint64_t first, uint64_t count, uint32_t* out) override {
    cache_.read_rows(name("chords"), first, count, out);
    chords_.add(first, count, out);
  }
  void finish() override {
    if (checked_ != grid_.voxel_count() + 1 || last_ != chord_rows_)
      throw InputError(cache_.path(), "dataset " + name("offsets"),
                       "does not match the " + std::to_string(chord_rows_) + " chords");
    for (const CacheReader::RowsCheck* check : {&offsets_, &line_counts_, &chords_})
      check->finish();
    if (density_read_) density_.finish();
    if (occupied_ != grid_.voxels_occupied) throw occupied_mismatch("fewer");
  }

 private:
  static std::string name(const char* array) { return std::string(kVoxelsGroup) + "/" + array; }
  static std::string shape_text(const std::vector<uint64_t>& shape) {
    std::string text;
    for (uint64_t n : shape) text += (text.empty() ? "" : " x ") + std::to_string(n);
    return text.empty() ? "scalar" : text;
  }
  InputError occupied_mismatch(const char* than) const {
    return InputError(cache_.path(), std::string("group ") + kVoxelsGroup,
                      "its description says " + std::to_string(grid_.voxels_occupied) +
                          " voxels hold lines; dataset " + name("line_counts") + " has " + than);
  }
  const CacheReader& cache_;
  VoxelGrid grid_;
  CacheReader::RowsCheck offsets_, line_counts_, density_, chords_;
  uint64_t chord_rows_ = 0;
  uint64_t checked_ = 0;                 // offsets checked: [0, checked_)
  uint32_t last_ = 0;                    // the last of them
  uint64_t counted_ = 0, occupied_ = 0;  // line counts seen, and those above 0
  bool density_read_ = false;
};

}  // namespace

std::unique_ptr<VoxelPieces> voxel_pieces(const CacheReader& cache) {
  return std::make_unique<CachePieces>(cache);
}

}  // namespace linebake
