#include "tubes/tube_builder.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <glm/glm.hpp>
#include <numbers>
#include <optional>

#include "core/error.hpp"

namespace linebake {
namespace {

using glm::vec3;

vec3 point_at(const LineSet& lines, uint64_t i) {
  return {lines.positions[3 * i], lines.positions[3 * i + 1], lines.positions[3 * i + 2]};
}

// Points of a line that take part in the tube: the first finite one, then each one at least
// farther than `min_distance` from the last kept one.
template <class Visit>
void for_each_kept_point(const LineSet& lines, size_t line, float min_distance, Visit&& visit) {
  const float min2 = min_distance * min_distance;
  vec3 last{};
  bool any = false;
  for (uint64_t i = lines.line_offsets[line]; i < lines.line_offsets[line + 1]; ++i) {
    const vec3 p = point_at(lines, i);
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) continue;
    const vec3 d = p - last;
    if (any && !(glm::dot(d, d) > min2)) continue;  // repeated points always go
    visit(i, p);
    last = p;
    any = true;
  }
}

// A unit vector perpendicular to t, from the axis least aligned with it.
vec3 perpendicular(vec3 t) {
  const vec3 a = std::fabs(t.x) <= std::fabs(t.y) && std::fabs(t.x) <= std::fabs(t.z)
                     ? vec3(1, 0, 0)
                     : (std::fabs(t.y) <= std::fabs(t.z) ? vec3(0, 1, 0) : vec3(0, 0, 1));
  return glm::normalize(glm::cross(t, a));
}

uint16_t to_unorm16(float v, std::array<float, 2> range) {
  const float span = range[1] - range[0];
  if (!(span > 0) || !std::isfinite(v)) return 0;
  return static_cast<uint16_t>(std::clamp((v - range[0]) / span, 0.0f, 1.0f) * 65535 + 0.5f);
}

struct Layout {
  uint64_t sides = 3;
  bool caps = false;
  uint64_t vertex_bytes = 0;
  uint64_t vertices(uint64_t points) const { return points * sides + (caps ? 2 : 0); }
  uint64_t indices(uint64_t points) const {
    return (points - 1) * 6 * sides + (caps ? 6 * sides : 0);
  }
};

// Per-thread scratch for one line: kept points, their source indices and frames.
struct Scratch {
  std::vector<uint64_t> source;
  std::vector<vec3> p, t, n;
};

// Where one line's mesh goes: its first vertex and index in the output piece, and its first
// vertex in the chunk (what the index values count from).
struct LinePlacement {
  uint64_t vertex = 0, index = 0, chunk_vertex = 0;
};

}  // namespace

struct TubeStreamBuilder::State {
  TubeOptions options;
  TubeMesh mesh;  // the description; chunks stay empty
  Layout layout;
  float min_distance = 0;
  int attribute = -1;  // index into the vertex (or line) attributes, -1: none
  bool attribute_per_line = false;
  int radius_attribute = -1;
  float radius_max = 1;
  std::array<float, 32> cos{}, sin{};
  // Plan: kept points per line (0: dropped), the chunks, and the open chunk's running sizes.
  std::vector<uint64_t> kept;
  std::vector<TubeChunkPlan> chunks;
  bool planned = false;
  // A process building part of the set (adopt_plan) holds the kept points of its lines only:
  // kept[0] is line kept_base; total_lines counts the whole set's.
  uint64_t kept_base = 0;
  std::optional<uint64_t> adopted_lines;
  uint64_t total_lines() const { return adopted_lines ? *adopted_lines : kept.size(); }
  uint64_t kept_of(uint64_t line) const { return kept[line - kept_base]; }
  // Build: the next line, its chunk, and where in that chunk the next line starts.
  uint64_t next_line = 0;
  size_t chunk = 0;
  bool chunk_open = false;
  uint64_t chunk_vertices = 0, chunk_indices = 0;
  std::vector<LinePlacement> placement;  // per line of the batch

  void resolve_attributes(const LineSet& header, const LineSetStats& stats);
  void add_to_plan(uint64_t line, uint64_t kept_points);
  void compute_frames(Scratch& s) const;
  void write_line(const LineSet& batch, size_t line, const LinePlacement& place,
                  const TubeOutput& out, Scratch& scratch) const;
};

namespace {

int index_of(const std::vector<Attribute>& list, const std::string& name) {
  for (size_t i = 0; i < list.size(); ++i)
    if (list[i].name == name) return int(i);
  return -1;
}

}  // namespace

void TubeStreamBuilder::State::resolve_attributes(const LineSet& header,
                                                  const LineSetStats& stats) {
  const std::string& name = options.attribute;
  if (name != "none") {
    const int vertex =
        name.empty() ? (header.attributes.empty() ? -1 : 0) : index_of(header.attributes, name);
    const int line = vertex >= 0 || name.empty() ? -1 : index_of(header.line_attributes, name);
    if (!name.empty() && vertex < 0 && line < 0)
      throw_unknown_attribute(header, "--attribute", name, false);
    if (vertex >= 0 || line >= 0) {
      attribute = vertex >= 0 ? vertex : line;
      attribute_per_line = line >= 0;
      mesh.attribute = attribute_per_line ? header.line_attributes[size_t(line)].name
                                          : header.attributes[size_t(vertex)].name;
      if (options.attribute_range) {
        mesh.attribute_range = *options.attribute_range;
      } else {
        const ValueRange* r = attribute_per_line ? stats.line_attribute_range(mesh.attribute)
                                                 : stats.attribute_range(mesh.attribute);
        mesh.attribute_range = {r ? r->min : 0.0f, r ? r->max : 0.0f};
      }
    }
  }
  if (!options.radius_attribute.empty()) {
    radius_attribute = index_of(header.attributes, options.radius_attribute);
    if (radius_attribute < 0)
      throw_unknown_attribute(header, "--radius-attribute", options.radius_attribute, true);
    const ValueRange* r = stats.attribute_range(options.radius_attribute);
    radius_max = r ? r->max : 0.0f;
    if (!(radius_max > 0))
      throw Error("tubes: radius attribute '" + options.radius_attribute +
                  "' has no positive value");
  }
}

// Greedy cut at line boundaries: a chunk takes lines until the next one would exceed the index
// limit, 2^32 vertices or the byte budget. Dropped lines join the chunk that is open.
void TubeStreamBuilder::State::add_to_plan(uint64_t line, uint64_t kept_points) {
  const auto fits = [&](uint64_t v, uint64_t i) {
    return i <= options.max_chunk_indices && v <= (uint64_t{1} << 32) &&
           v * layout.vertex_bytes + i * 4 <= options.max_chunk_bytes;
  };
  if (chunks.empty()) chunks.push_back({});
  if (kept_points) {
    const uint64_t v = layout.vertices(kept_points), i = layout.indices(kept_points);
    if (!fits(v, i))
      throw Error("tubes: line " + std::to_string(line) + " alone needs " + std::to_string(i) +
                  " indices and " + std::to_string(v * layout.vertex_bytes + i * 4) +
                  " bytes, more than one chunk may hold");
    if (!fits(chunks.back().vertices + v, chunks.back().indices + i)) {
      chunks.back().line_count = line - chunks.back().first_line;
      chunks.push_back({line, 0, 0, 0});
    }
    chunks.back().vertices += v;
    chunks.back().indices += i;
  }
  kept.push_back(kept_points);
}

// Tangents bisect the unit directions of the two segments at a point (one-sided at the ends;
// the incoming direction where the line turns back on itself). Normals are rotation-minimising
// by double reflection (Wang et al. 2008). Reflections preserve length and orthogonality, so
// the serial chain from point to point carries only the two reflections (renormalised every 32
// steps against float drift); projecting onto the tangent's plane and normalising happen off
// the chain, where they overlap across points instead of adding to its latency.
void TubeStreamBuilder::State::compute_frames(Scratch& s) const {
  const size_t m = s.p.size();
  s.t.resize(m);
  s.n.resize(m);
  const auto unit_or = [](vec3 v, vec3 fallback) {
    const float len2 = glm::dot(v, v);
    return len2 > 1e-30f ? v * (1 / std::sqrt(len2)) : fallback;
  };
  vec3 previous = unit_or(s.p[1] - s.p[0], vec3(0, 0, 1));
  s.t[0] = previous;
  for (size_t i = 1; i < m; ++i) {
    const vec3 incoming = previous;
    const vec3 outgoing = i + 1 < m ? unit_or(s.p[i + 1] - s.p[i], incoming) : incoming;
    s.t[i] = unit_or(incoming + outgoing, incoming);
    previous = outgoing;
  }
  vec3 r = perpendicular(s.t[0]);
  s.n[0] = r;
  for (size_t i = 0; i + 1 < m; ++i) {
    // First reflection in the plane bisecting p[i], p[i+1]; second in the plane that maps the
    // reflected tangent onto t[i+1]. A zero-length step (min_point_distance 0) skips the first.
    const vec3 v1 = s.p[i + 1] - s.p[i];
    const float c1 = glm::dot(v1, v1);
    const float k1 = c1 > 1e-30f ? 2 / c1 : 0.0f;
    const vec3 t_l = s.t[i] - (k1 * glm::dot(v1, s.t[i])) * v1;
    const vec3 v2 = s.t[i + 1] - t_l;
    const float c2 = glm::dot(v2, v2);
    const float k2 = c2 > 1e-20f ? 2 / c2 : 0.0f;
    const vec3 r_l = r - (k1 * glm::dot(v1, r)) * v1;
    r = r_l - (k2 * glm::dot(v2, r_l)) * v2;
    if ((i & 31) == 31) r = unit_or(r - glm::dot(r, s.t[i + 1]) * s.t[i + 1], r);
    s.n[i + 1] = r;
  }
  for (size_t i = 1; i < m; ++i) {
    const vec3 t = s.t[i], q = s.n[i] - glm::dot(s.n[i], t) * t;
    const float len2 = glm::dot(q, q);
    s.n[i] = len2 > 1e-30f ? q * (1 / std::sqrt(len2)) : perpendicular(t);
  }
}

void TubeStreamBuilder::State::write_line(const LineSet& batch, size_t line,
                                          const LinePlacement& place, const TubeOutput& out,
                                          Scratch& s) const {
  s.source.clear();
  s.p.clear();
  for_each_kept_point(batch, line, min_distance, [&](uint64_t i, vec3 p) {
    s.source.push_back(i);
    s.p.push_back(p);
  });
  compute_frames(s);

  const uint64_t n = layout.sides;
  const size_t m = s.p.size();
  const uint64_t v0 = place.vertex;
  float* pos = out.positions + 3 * v0;
  float* nrm = out.normals ? out.normals + 3 * v0 : nullptr;
  int16_t* oct = out.normals_oct ? out.normals_oct + 2 * v0 : nullptr;
  uint16_t* attr = out.attribute ? out.attribute + v0 : nullptr;
  const auto emit = [&](vec3 p, vec3 normal, uint16_t a) {
    *pos++ = p.x, *pos++ = p.y, *pos++ = p.z;
    if (nrm) *nrm++ = normal.x, *nrm++ = normal.y, *nrm++ = normal.z;
    if (oct) {
      const auto e = encode_octahedral(normal.x, normal.y, normal.z);
      *oct++ = e[0], *oct++ = e[1];
    }
    if (attr) *attr++ = a;
  };
  const std::vector<float>* attribute_values =
      attribute < 0        ? nullptr
      : attribute_per_line ? &batch.line_attributes[size_t(attribute)].values
                           : &batch.attributes[size_t(attribute)].values;
  const std::vector<float>* radius_values =
      radius_attribute < 0 ? nullptr : &batch.attributes[size_t(radius_attribute)].values;
  const uint16_t line_value = attribute_values && attribute_per_line
                                  ? to_unorm16((*attribute_values)[line], mesh.attribute_range)
                                  : 0;
  // Locals, not members: the float stores below could alias them and force reloads.
  const float radius = mesh.radius, radius_maximum = radius_max;
  const std::array<float, 2> range = mesh.attribute_range;
  const std::array<float, 32> cos_j = cos, sin_j = sin;
  // Scalar components, not vec3 copies: GCC spills 12-byte structs through the stack here and
  // the partial reloads stall store forwarding (measured: ~15% of the build).
  for (size_t i = 0; i < m; ++i) {
    const float px = s.p[i].x, py = s.p[i].y, pz = s.p[i].z;
    const float tx = s.t[i].x, ty = s.t[i].y, tz = s.t[i].z;
    const float nx = s.n[i].x, ny = s.n[i].y, nz = s.n[i].z;
    const float bx = ty * nz - tz * ny, by = tz * nx - tx * nz, bz = tx * ny - ty * nx;
    float r = radius;
    if (radius_values) {
      const float v = (*radius_values)[s.source[i]];
      r *= v > 0 && std::isfinite(v) ? v / radius_maximum : 0.01f;
    }
    for (uint64_t j = 0; j < n; ++j) {
      const float c = cos_j[j], sn = sin_j[j];
      const float ox = c * nx + sn * bx, oy = c * ny + sn * by, oz = c * nz + sn * bz;
      pos[0] = px + r * ox, pos[1] = py + r * oy, pos[2] = pz + r * oz;
      pos += 3;
      if (nrm) {
        nrm[0] = ox, nrm[1] = oy, nrm[2] = oz;
        nrm += 3;
      } else {
        const auto e = encode_octahedral(ox, oy, oz);
        oct[0] = e[0], oct[1] = e[1];
        oct += 2;
      }
    }
    if (attr) {
      const uint16_t a =
          attribute_per_line ? line_value : to_unorm16((*attribute_values)[s.source[i]], range);
      for (uint64_t j = 0; j < n; ++j) *attr++ = a;
    }
  }
  if (layout.caps) {
    const uint16_t a_first = attr ? out.attribute[v0] : 0;
    const uint16_t a_last = attr ? out.attribute[v0 + (m - 1) * n] : 0;
    emit(s.p[0], -s.t[0], a_first);
    emit(s.p[m - 1], s.t[m - 1], a_last);
  }

  // Two triangles per segment and ring index; winding makes the normals point outwards. Index
  // values count from the chunk's first vertex.
  uint32_t* idx = out.indices + place.index;
  const uint64_t c0 = place.chunk_vertex;
  for (uint64_t i = 0; i + 1 < m; ++i) {
    const uint64_t ring = c0 + i * n, next = ring + n;
    for (uint64_t j = 0; j < n; ++j) {
      const uint64_t j1 = j + 1 == n ? 0 : j + 1;
      const uint32_t a = uint32_t(ring + j), b = uint32_t(ring + j1);
      const uint32_t c = uint32_t(next + j1), d = uint32_t(next + j);
      *idx++ = a, *idx++ = b, *idx++ = c;
      *idx++ = a, *idx++ = c, *idx++ = d;
    }
  }
  if (layout.caps) {
    const uint64_t first = c0, last = c0 + (m - 1) * n, centre = c0 + m * n;
    for (uint64_t j = 0; j < n; ++j) {
      const uint64_t j1 = j + 1 == n ? 0 : j + 1;
      *idx++ = uint32_t(centre), *idx++ = uint32_t(first + j1), *idx++ = uint32_t(first + j);
    }
    for (uint64_t j = 0; j < n; ++j) {
      const uint64_t j1 = j + 1 == n ? 0 : j + 1;
      *idx++ = uint32_t(centre + 1), *idx++ = uint32_t(last + j), *idx++ = uint32_t(last + j1);
    }
  }
}

float world_radius(const Bounds& bounds, const TubeOptions& options) {
  return options.radius_absolute ? options.radius : options.radius * bounds.diagonal();
}

float world_radius(const LineSet& lines, const TubeOptions& options) {
  return world_radius(compute_bounds(lines), options);
}

TubeStreamBuilder::TubeStreamBuilder(const LineSet& header, const LineSetStats& stats,
                                     const TubeOptions& options)
    : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.options = options;
  if (options.sides < 3 || options.sides > 32)
    throw Error("tubes: sides must be 3..32, got " + std::to_string(options.sides));
  if (!(options.radius > 0) || !std::isfinite(options.radius))
    throw Error("tubes: radius must be positive");
  s.mesh.sides = options.sides;
  s.mesh.caps = options.caps;
  s.mesh.normals = options.normals;
  s.mesh.radius = world_radius(stats.bounds, options);
  if (!(s.mesh.radius > 0)) throw Error("tubes: the data has no extent, use an absolute radius");
  s.min_distance = options.min_point_distance * stats.bounds.diagonal();
  s.resolve_attributes(header, stats);
  s.layout = {uint64_t(options.sides), options.caps,
              tube_vertex_bytes(options.normals, s.attribute >= 0)};
  for (int j = 0; j < options.sides; ++j) {
    const double angle = 2 * std::numbers::pi * j / options.sides;
    s.cos[size_t(j)] = float(std::cos(angle));
    s.sin[size_t(j)] = float(std::sin(angle));
  }
  s.kept.reserve(stats.lines);
}

TubeStreamBuilder::~TubeStreamBuilder() = default;

std::vector<uint64_t> TubeStreamBuilder::kept_points(const LineSet& batch) const {
  const State& s = *state_;
  std::vector<uint64_t> kept(batch.line_count());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, kept.size(), 256), [&](auto range) {
    for (size_t l = range.begin(); l != range.end(); ++l) {
      uint64_t k = 0;
      for_each_kept_point(batch, l, s.min_distance, [&](uint64_t, vec3) { ++k; });
      kept[l] = k >= 2 ? k : 0;
    }
  });
  return kept;
}

void TubeStreamBuilder::plan_kept(const std::vector<uint64_t>& kept, uint64_t points_skipped) {
  State& s = *state_;
  for (const uint64_t k : kept) {
    s.add_to_plan(s.kept.size(), k);
    s.mesh.lines_dropped += k == 0;
  }
  s.mesh.points_skipped += points_skipped;
}

TubeStreamBuilder::Position TubeStreamBuilder::position_of(uint64_t line) const {
  const State& s = *state_;
  if (!s.planned) throw Error("tubes: position_of() before finish_plan()");
  Position p;
  while (p.chunk + 1 < s.chunks.size() && s.chunks[p.chunk + 1].first_line <= line) ++p.chunk;
  for (uint64_t l = s.chunks[p.chunk].first_line; l < line && l < s.kept.size(); ++l)
    if (s.kept[l]) {
      p.vertices += s.layout.vertices(s.kept[l]);
      p.indices += s.layout.indices(s.kept[l]);
    }
  return p;
}

void TubeStreamBuilder::adopt_plan(std::vector<TubeChunkPlan> chunks, uint64_t total_lines,
                                   uint64_t lines_dropped, uint64_t points_skipped,
                                   std::vector<uint64_t> kept, uint64_t first_line,
                                   const Position& start) {
  State& s = *state_;
  s.chunks = std::move(chunks);
  s.adopted_lines = total_lines;
  s.mesh.lines_dropped = lines_dropped;
  s.mesh.points_skipped = points_skipped;
  s.kept = std::move(kept);
  s.kept_base = first_line;
  s.planned = true;
  s.next_line = first_line;
  s.chunk = start.chunk;
  s.chunk_open = true;  // begun by the process before this one, or begun here at its start
  s.chunk_vertices = start.vertices;
  s.chunk_indices = start.indices;
}

void TubeStreamBuilder::plan(const LineSet& batch) {
  State& s = *state_;
  const size_t count = batch.line_count();
  const std::vector<uint64_t> kept = kept_points(batch);
  for (size_t l = 0; l < count; ++l) {
    s.add_to_plan(s.kept.size(), kept[l]);
    s.mesh.lines_dropped += kept[l] == 0;
    s.mesh.points_skipped += batch.line_size(l) - kept[l];  // with the points of dropped lines
  }
}

const std::vector<TubeChunkPlan>& TubeStreamBuilder::finish_plan() {
  State& s = *state_;
  if (s.kept.empty() || s.mesh.lines_dropped == s.kept.size())
    throw Error("tubes: no line has two distinct points");
  s.chunks.back().line_count = s.kept.size() - s.chunks.back().first_line;
  s.planned = true;
  return s.chunks;
}

const TubeMesh& TubeStreamBuilder::description() const {
  return state_->mesh;
}

uint64_t TubeStreamBuilder::vertex_bytes() const {
  return state_->layout.vertex_bytes;
}

uint64_t TubeStreamBuilder::output_bytes(uint64_t first_line, uint64_t line_count) const {
  const State& s = *state_;
  uint64_t bytes = 0;
  for (uint64_t l = first_line; l < first_line + line_count && l < s.kept.size(); ++l)
    if (s.kept[l])
      bytes +=
          s.layout.vertices(s.kept[l]) * s.layout.vertex_bytes + s.layout.indices(s.kept[l]) * 4;
  return bytes;
}

// The batch's lines in runs of one chunk: each run asks the sink for its memory, the lines
// write their own precomputed ranges in parallel (so the bytes do not depend on the schedule),
// and the run is handed over.
void TubeStreamBuilder::build(const LineSet& batch, TubeSink& sink) {
  State& s = *state_;
  if (!s.planned) throw Error("tubes: build() before finish_plan()");
  const size_t count = batch.line_count();
  if (s.next_line + count > s.kept_base + s.kept.size())
    throw Error("tubes: the build pass sees more lines than the plan");
  size_t line = 0;
  while (line < count) {
    // Lines before the next chunk's first belong to the open chunk.
    while (!s.chunk_open || (s.chunk + 1 < s.chunks.size() &&
                             s.next_line + line >= s.chunks[s.chunk + 1].first_line)) {
      if (s.chunk_open) {
        sink.end_chunk(s.chunk);
        ++s.chunk;
      }
      sink.begin_chunk(s.chunk, s.chunks[s.chunk]);
      s.chunk_open = true;
      s.chunk_vertices = s.chunk_indices = 0;
    }
    const TubeChunkPlan& plan = s.chunks[s.chunk];
    const size_t end =
        size_t(std::min<uint64_t>(count, plan.first_line + plan.line_count - s.next_line));
    s.placement.resize(end - line);
    uint64_t vertices = 0, indices = 0;
    for (size_t l = line; l < end; ++l) {
      const uint64_t k = s.kept_of(s.next_line + l);
      s.placement[l - line] = {vertices, indices, s.chunk_vertices + vertices};
      if (k) {
        vertices += s.layout.vertices(k);
        indices += s.layout.indices(k);
      }
    }
    if (vertices > 0) {
      const TubeOutput out = sink.reserve(s.chunk, vertices, indices);
      tbb::parallel_for(tbb::blocked_range<size_t>(line, end, 64), [&](auto range) {
        Scratch scratch;
        for (size_t l = range.begin(); l != range.end(); ++l)
          if (s.kept_of(s.next_line + l))
            s.write_line(batch, l, s.placement[l - line], out, scratch);
      });
      sink.written(s.chunk);
    }
    s.chunk_vertices += vertices;
    s.chunk_indices += indices;
    line = end;
  }
  s.next_line += count;
  if (s.next_line == s.total_lines() && s.chunk_open) {
    sink.end_chunk(s.chunk);
    s.chunk_open = false;
  }
}

namespace {

// Builds into the mesh's own arrays: the sink hands out memory inside each chunk.
class MeshSink : public TubeSink {
 public:
  MeshSink(TubeMesh& mesh, bool has_attribute) : mesh_(mesh), has_attribute_(has_attribute) {}
  void begin_chunk(size_t c, const TubeChunkPlan& plan) override {
    if (mesh_.chunks.size() <= c) mesh_.chunks.resize(c + 1);
    TubeChunk& chunk = mesh_.chunks[c];
    chunk.first_line = plan.first_line;
    chunk.line_count = plan.line_count;
    chunk.positions = Array<float>(3 * plan.vertices);
    if (mesh_.normals == NormalEncoding::Float32)
      chunk.normals = Array<float>(3 * plan.vertices);
    else
      chunk.normals_oct = Array<int16_t>(2 * plan.vertices);
    if (has_attribute_) chunk.attribute = Array<uint16_t>(plan.vertices);
    chunk.indices = Array<uint32_t>(plan.indices);
    vertices_ = indices_ = 0;
  }
  TubeOutput reserve(size_t c, uint64_t vertices, uint64_t indices) override {
    TubeChunk& chunk = mesh_.chunks[c];
    TubeOutput out;
    out.positions = chunk.positions.data() + 3 * vertices_;
    if (!chunk.normals.empty()) out.normals = chunk.normals.data() + 3 * vertices_;
    if (!chunk.normals_oct.empty()) out.normals_oct = chunk.normals_oct.data() + 2 * vertices_;
    if (!chunk.attribute.empty()) out.attribute = chunk.attribute.data() + vertices_;
    out.indices = chunk.indices.data() + indices_;
    vertices_ += vertices;
    indices_ += indices;
    return out;
  }
  void written(size_t) override {}
  void end_chunk(size_t) override {}

 private:
  TubeMesh& mesh_;
  bool has_attribute_;
  uint64_t vertices_ = 0, indices_ = 0;
};

}  // namespace

// The whole line set as one batch: nothing is copied, and build() runs every line in parallel.
TubeMesh build_tubes(const LineSet& lines, const TubeOptions& options, const ProgressFn& progress) {
  TubeStreamBuilder builder(lines, compute_stats(lines), options);
  builder.plan(lines);
  builder.finish_plan();
  TubeMesh mesh = builder.description();
  MeshSink sink(mesh, !mesh.attribute.empty());
  builder.build(lines, sink);
  if (progress) progress(lines.line_count(), lines.line_count());
  return mesh;
}

}  // namespace linebake
