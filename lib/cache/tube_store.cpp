#include "cache/tube_store.hpp"

#include <algorithm>
#include <cstdio>
#include <optional>
#include <set>

#include "cache/line_store.hpp"
#include "core/error.hpp"
#include "core/json_file.hpp"

namespace linebake {

static std::string chunk_group(size_t c) {
  char name[32];
  std::snprintf(name, sizeof name, "/chunk_%06zu", c);
  return kTubesGroup + std::string(name);
}

static nlohmann::json describe(const TubeMesh& mesh, size_t chunks) {
  return {{"sides", mesh.sides},
          {"radius", mesh.radius},
          {"caps", mesh.caps},
          {"normals", to_string(mesh.normals)},
          {"attribute", mesh.attribute},
          {"attribute_range", mesh.attribute_range},
          {"lines_dropped", mesh.lines_dropped},
          {"points_skipped", mesh.points_skipped},
          {"chunks", chunks}};
}

struct TubeStoreSink::State {
  CacheWriter* cache = nullptr;
  bool float_normals = true, attribute = false;
  // The open chunk's datasets.
  std::optional<DatasetStream> positions, normals, attribute_values, indices;
  TubeChunkPlan plan;
  // Parallel writes: every chunk's datasets (made by open_chunks) and plan, and where this rank's
  // rows are.
  struct Chunk {
    std::optional<DatasetStream> positions, normals, attribute_values, indices;
    TubeChunkPlan plan;
    bool made = false;
  };
  bool parallel = false;
  std::vector<Chunk> all;
  size_t first_chunk = 0, last_chunk = 0;
  uint64_t first_vertices = 0, first_indices = 0;
  size_t frontier = 0;     // the lowest chunk this rank may still write to
  std::set<size_t> open;   // chunks made and not yet closed
  std::vector<bool> done;  // chunks closed
  void open_chunk(size_t c, const TubeChunkPlan& plan);
  void make_parallel_chunk(size_t c);
  void close_parallel_chunk(size_t c);
  void close_chunk(size_t c);
  size_t chunks = 0;
  uint64_t disk = 0, memory = 0;
  // The staging buffers of the piece being written, kept between pieces.
  std::vector<float> positions_buffer, normals_buffer;
  std::vector<int16_t> oct_buffer;
  std::vector<uint16_t> attribute_buffer;
  std::vector<uint32_t> index_buffer;
  uint64_t piece_vertices = 0, piece_indices = 0, staging_peak = 0;
};

TubeStoreSink::TubeStoreSink(CacheWriter& cache, const TubeMesh& mesh)
    : state_(std::make_unique<State>()) {
  state_->cache = &cache;
  state_->float_normals = mesh.normals == NormalEncoding::Float32;
  state_->attribute = !mesh.attribute.empty();
  cache.create_group(kTubesGroup);
}

TubeStoreSink::~TubeStoreSink() = default;

void TubeStoreSink::State::open_chunk(size_t c, const TubeChunkPlan& chunk_plan) {
  const std::string g = chunk_group(c);
  cache->create_group(g);
  plan = chunk_plan;
  chunks = std::max(chunks, c + 1);  // the ranks make parallel chunks out of order
  positions.emplace(cache->stream<float>(g + "/positions", plan.vertices, 3));
  normals.emplace(float_normals ? cache->stream<float>(g + "/normals", plan.vertices, 3)
                                : cache->stream<int16_t>(g + "/normals_oct", plan.vertices, 2));
  if (attribute) attribute_values.emplace(cache->stream<uint16_t>(g + "/attribute", plan.vertices));
  indices.emplace(cache->stream<uint32_t>(g + "/indices", plan.indices / 3, 3));
}

TubeStoreSink::TubeStoreSink(CacheWriter& cache, const TubeMesh& mesh,
                             const std::vector<TubeChunkPlan>& plan, size_t first_chunk,
                             uint64_t first_vertices, uint64_t first_indices, size_t last_chunk)
    : TubeStoreSink(cache, mesh) {
  State& s = *state_;
  s.parallel = true;
  s.all.resize(plan.size());
  s.done.assign(plan.size(), false);
  for (size_t c = 0; c < plan.size(); ++c) s.all[c].plan = plan[c];
  s.first_chunk = s.frontier = first_chunk;
  s.last_chunk = last_chunk;
  s.first_vertices = first_vertices;
  s.first_indices = first_indices;
}

void TubeStoreSink::State::make_parallel_chunk(size_t c) {
  Chunk& chunk = all[c];
  if (chunk.made || done[c]) return;
  open.insert(c);
  open_chunk(c, chunk.plan);
  chunk.positions = std::move(positions);
  chunk.normals = std::move(normals);
  chunk.attribute_values = std::move(attribute_values);
  chunk.indices = std::move(indices);
  positions.reset();
  normals.reset();
  attribute_values.reset();
  indices.reset();
  chunk.made = true;
  if (c >= first_chunk && c <= last_chunk) {
    const uint64_t v = c == first_chunk ? first_vertices : 0;
    const uint64_t i = c == first_chunk ? first_indices : 0;
    chunk.positions->start_at(v);
    chunk.normals->start_at(v);
    if (chunk.attribute_values) chunk.attribute_values->start_at(v);
    chunk.indices->start_at(i / 3);
  }
}

size_t TubeStoreSink::chunk_of_line(uint64_t line) const {
  const auto& all = state_->all;
  const auto after = std::upper_bound(
      all.begin(), all.end(), line,
      [](uint64_t l, const State::Chunk& chunk) { return l < chunk.plan.first_line; });
  return after == all.begin() ? 0 : size_t(after - all.begin()) - 1;
}

void TubeStoreSink::open_chunks(const std::vector<uint64_t>& ranges) {
  State& s = *state_;
  std::vector<size_t> wanted;
  for (size_t r = 0; r + 1 < ranges.size(); r += 2)
    for (uint64_t c = ranges[r]; c <= ranges[r + 1] && c < s.all.size(); ++c)
      wanted.push_back(size_t(c));
  std::sort(wanted.begin(), wanted.end());
  for (const size_t c : wanted) s.make_parallel_chunk(c);
}

void TubeStoreSink::begin_chunk(size_t c, const TubeChunkPlan& plan) {
  State& s = *state_;
  if (s.parallel) {  // made by open_chunks
    s.frontier = c;
    return;
  }
  s.open_chunk(c, plan);
}

TubeOutput TubeStoreSink::reserve(size_t c, uint64_t vertices, uint64_t indices) {
  State& s = *state_;
  (void)c;
  s.piece_vertices = vertices;
  s.piece_indices = indices;
  s.positions_buffer.resize(3 * vertices);
  s.index_buffer.resize(indices);
  TubeOutput out;
  out.positions = s.positions_buffer.data();
  out.indices = s.index_buffer.data();
  if (s.float_normals) {
    s.normals_buffer.resize(3 * vertices);
    out.normals = s.normals_buffer.data();
  } else {
    s.oct_buffer.resize(2 * vertices);
    out.normals_oct = s.oct_buffer.data();
  }
  if (s.attribute) {
    s.attribute_buffer.resize(vertices);
    out.attribute = s.attribute_buffer.data();
  }
  const uint64_t staged =
      vertices * (12 + (s.float_normals ? 12 : 4) + (s.attribute ? 2 : 0)) + indices * 4;
  s.staging_peak = std::max(s.staging_peak, staged);
  return out;
}

void TubeStoreSink::written(size_t c) {
  State& s = *state_;
  if (s.parallel && !s.all[c].made)
    throw Error("tubes: rows for chunk " + std::to_string(c) + " before open_chunks made it");
  auto& positions = s.parallel ? s.all[c].positions : s.positions;
  auto& normals = s.parallel ? s.all[c].normals : s.normals;
  auto& attribute_values = s.parallel ? s.all[c].attribute_values : s.attribute_values;
  auto& indices = s.parallel ? s.all[c].indices : s.indices;
  if (s.attribute)
    append_together({rows_of(*positions, s.positions_buffer.data(), s.piece_vertices),
                     s.float_normals ? rows_of(*normals, s.normals_buffer.data(), s.piece_vertices)
                                     : rows_of(*normals, s.oct_buffer.data(), s.piece_vertices),
                     rows_of(*attribute_values, s.attribute_buffer.data(), s.piece_vertices),
                     rows_of(*indices, s.index_buffer.data(), s.piece_indices / 3)});
  else
    append_together({rows_of(*positions, s.positions_buffer.data(), s.piece_vertices),
                     s.float_normals ? rows_of(*normals, s.normals_buffer.data(), s.piece_vertices)
                                     : rows_of(*normals, s.oct_buffer.data(), s.piece_vertices),
                     rows_of(*indices, s.index_buffer.data(), s.piece_indices / 3)});
}

void TubeStoreSink::end_chunk(size_t c) {
  State& s = *state_;
  if (s.parallel) return;  // closed by close_finished() or close()
  s.close_chunk(c);
}

void TubeStoreSink::State::close_chunk(size_t c) {
  State& s = *this;
  const std::string g = chunk_group(c);
  s.disk += s.positions->close() + s.normals->close() + s.indices->close();
  if (s.attribute_values) s.disk += s.attribute_values->close();
  s.memory += s.plan.vertices * (12 + (s.float_normals ? 12 : 4) + (s.attribute ? 2 : 0)) +
              s.plan.indices * 4;
  s.positions.reset();
  s.normals.reset();
  s.attribute_values.reset();
  s.indices.reset();
  s.cache->write_attribute(g, "lines",
                           json_text(nlohmann::json{s.plan.first_line, s.plan.line_count}));
}

void TubeStoreSink::State::close_parallel_chunk(size_t c) {
  make_parallel_chunk(c);  // a chunk no rank reached (none has rows): made to be closed
  positions = std::move(all[c].positions);
  normals = std::move(all[c].normals);
  attribute_values = std::move(all[c].attribute_values);
  indices = std::move(all[c].indices);
  plan = all[c].plan;
  close_chunk(c);
  open.erase(c);
  done[c] = true;
}

size_t TubeStoreSink::frontier() const {
  return state_->frontier;
}
size_t TubeStoreSink::last_chunk() const {
  return state_->last_chunk;
}

void TubeStoreSink::close_finished(const std::vector<uint64_t>& ranks) {
  State& s = *state_;
  std::vector<size_t> finished;
  for (const size_t c : s.open) {
    bool written = true;  // every rank has passed the chunk or never writes to it
    for (size_t r = 0; r + 1 < ranks.size(); r += 2)
      written = written && (c < ranks[r] || c > ranks[r + 1]);
    if (written) finished.push_back(c);
  }
  for (const size_t c : finished) s.close_parallel_chunk(c);
}

void TubeStoreSink::close(const TubeMesh& mesh, Provenance provenance) {
  State& s = *state_;
  for (size_t c = 0; c < s.all.size(); ++c)
    if (!s.done[c]) s.close_parallel_chunk(c);
  s.all.clear();
  s.cache->write_attribute(kTubesGroup, "mesh", json_text(describe(mesh, s.chunks)));
  provenance.disk_bytes = s.disk;
  provenance.memory_bytes = s.memory;
  s.cache->write_provenance(kTubesGroup, provenance);
}

uint64_t TubeStoreSink::staging_bytes() const {
  return state_->staging_peak;
}

void store_tubes(CacheWriter& cache, const TubeMesh& mesh, Provenance provenance) {
  cache.create_group(kTubesGroup);
  uint64_t disk = 0;
  for (size_t c = 0; c < mesh.chunks.size(); ++c) {
    const TubeChunk& chunk = mesh.chunks[c];
    const std::string g = chunk_group(c);
    cache.create_group(g);
    const uint64_t v = chunk.vertex_count();
    disk += cache.write(g + "/positions", chunk.positions.data(), v, 3);
    if (mesh.normals == NormalEncoding::Float32)
      disk += cache.write(g + "/normals", chunk.normals.data(), v, 3);
    else
      disk += cache.write(g + "/normals_oct", chunk.normals_oct.data(), v, 2);
    if (!mesh.attribute.empty()) disk += cache.write(g + "/attribute", chunk.attribute.data(), v);
    disk += cache.write(g + "/indices", chunk.indices.data(), chunk.triangle_count(), 3);
    cache.write_attribute(g, "lines",
                          json_text(nlohmann::json{chunk.first_line, chunk.line_count}));
  }
  cache.write_attribute(kTubesGroup, "mesh", json_text(describe(mesh, mesh.chunks.size())));
  provenance.disk_bytes = disk;
  provenance.memory_bytes = mesh.bytes();
  cache.write_provenance(kTubesGroup, provenance);
}

TubeMesh load_tube_description(const CacheReader& cache) {
  const std::string where = std::string("group ") + kTubesGroup;
  const auto text = cache.attribute(kTubesGroup, "mesh");
  if (!text)
    throw InputError(cache.path(), where,
                     "missing: no tube mesh in this cache; add it with: linebake bake " +
                         cache.path() + " --assets tubes");
  TubeMesh mesh;
  size_t chunks = 0;
  try {
    const auto j = nlohmann::json::parse(*text);
    mesh.sides = j.at("sides");
    mesh.radius = j.at("radius");
    mesh.caps = j.at("caps");
    mesh.normals = parse_normal_encoding(j.at("normals"));
    mesh.attribute = j.at("attribute");
    mesh.attribute_range = j.at("attribute_range");
    mesh.lines_dropped = j.at("lines_dropped");
    mesh.points_skipped = j.at("points_skipped");
    chunks = j.at("chunks");
  } catch (const std::exception& e) {
    throw InputError(cache.path(), where, std::string("bad mesh description: ") + e.what());
  }
  mesh.chunks.resize(chunks);
  for (size_t c = 0; c < chunks; ++c) {
    TubeChunk& chunk = mesh.chunks[c];
    const std::string g = chunk_group(c);
    const auto lines = cache.attribute(g, "lines");
    if (!lines) throw InputError(cache.path(), "group " + g, "missing");
    try {
      const auto j = nlohmann::json::parse(*lines);
      chunk.first_line = j.at(0);
      chunk.line_count = j.at(1);
    } catch (const std::exception& e) {
      throw InputError(cache.path(), "group " + g, std::string("bad line range: ") + e.what());
    }
  }
  return mesh;
}

namespace {

Array<float> read_positions(const CacheReader& cache, const std::string& g) {
  Array<float> positions = cache.read<float>(g + "/positions");
  if (positions.size() % 3)
    throw InputError(cache.path(), "dataset " + g + "/positions", "not 3 floats per vertex");
  return positions;
}

}  // namespace

TubeChunk load_tube_chunk(const CacheReader& cache, const TubeMesh& description, size_t index) {
  TubeChunk chunk;
  chunk.first_line = description.chunks.at(index).first_line;
  chunk.line_count = description.chunks.at(index).line_count;
  const std::string g = chunk_group(index);
  chunk.positions = read_positions(cache, g);
  const uint64_t v = chunk.vertex_count();
  if (description.normals == NormalEncoding::Float32)
    chunk.normals = cache.read<float>(g + "/normals", 3 * v);
  else
    chunk.normals_oct = cache.read<int16_t>(g + "/normals_oct", 2 * v);
  if (!description.attribute.empty()) chunk.attribute = cache.read<uint16_t>(g + "/attribute", v);
  chunk.indices = cache.read<uint32_t>(g + "/indices");
  if (chunk.indices.size() % 3)
    throw InputError(cache.path(), "dataset " + g + "/indices", "not 3 indices per triangle");
  // The hash guards the bytes; this guards a renderer against a cache written wrongly.
  for (size_t i = 0; i < chunk.indices.size(); ++i)
    if (chunk.indices[i] >= v)
      throw InputError(cache.path(), "dataset " + g + "/indices",
                       "index " + std::to_string(chunk.indices[i]) + " at " + std::to_string(i) +
                           " is past the " + std::to_string(v) + " vertices");
  return chunk;
}

TubeMesh load_tubes(const CacheReader& cache) {
  TubeMesh mesh = load_tube_description(cache);
  for (size_t c = 0; c < mesh.chunks.size(); ++c) mesh.chunks[c] = load_tube_chunk(cache, mesh, c);
  return mesh;
}

TubeCounts load_tube_counts(const CacheReader& cache) {
  const TubeMesh description = load_tube_description(cache);
  TubeCounts counts;
  for (size_t c = 0; c < description.chunks.size(); ++c) {
    const std::string g = chunk_group(c);
    const std::vector<uint64_t> positions = cache.shape(g + "/positions"),
                                indices = cache.shape(g + "/indices");
    if (positions.empty() || indices.empty())
      throw InputError(cache.path(), "group " + g, "positions or indices without a shape");
    counts.vertices += positions[0];
    counts.triangles += indices[0];
  }
  return counts;
}

TubeCounts tube_chunk_counts(const CacheReader& cache, size_t index) {
  const std::string g = chunk_group(index);
  const std::vector<uint64_t> positions = cache.shape(g + "/positions"),
                              indices = cache.shape(g + "/indices");
  if (positions.empty() || indices.empty())
    throw InputError(cache.path(), "group " + g, "positions or indices without a shape");
  return {positions[0], indices[0]};
}

uint64_t tube_chunk_bytes(const CacheReader& cache, const TubeMesh& description, size_t index) {
  const TubeCounts counts = tube_chunk_counts(cache, index);
  const uint64_t per_vertex =
      3 * sizeof(float) +
      (description.normals == NormalEncoding::Float32 ? 3 * sizeof(float) : 2 * sizeof(int16_t)) +
      (description.attribute.empty() ? 0 : sizeof(uint16_t));
  return counts.vertices * per_vertex + counts.triangles * 3 * sizeof(uint32_t);
}

Bounds load_tube_bounds(const CacheReader& cache, uint64_t rows_per_read) {
  const TubeMesh description = load_tube_description(cache);
  Bounds bounds;
  for (size_t c = 0; c < description.chunks.size(); ++c)
    include_dataset_points(bounds, cache, chunk_group(c) + "/positions", rows_per_read);
  return bounds;
}

}  // namespace linebake
