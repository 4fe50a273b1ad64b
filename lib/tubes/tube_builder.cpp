#include "tubes/tube_builder.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <glm/glm.hpp>
#include <numbers>

#include "core/error.hpp"

namespace linebake {
namespace {

using glm::vec3;

vec3 point(const LineSet& lines, uint64_t i) {
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
    const vec3 p = point(lines, i);
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

// Where a line's vertices and indices go in its chunk.
struct Placement {
  uint64_t kept_points = 0;  // 0: the line is dropped
  uint64_t chunk = 0;
  uint64_t vertex_base = 0;
  uint64_t index_base = 0;
};

struct ChunkPlan {
  uint64_t first_line = 0, line_count = 0, vertices = 0, indices = 0;
};

// Greedy cut at line boundaries: a chunk takes lines until the next one would exceed the index
// limit, 2^32 vertices or the byte budget. Dropped lines join the chunk that is open.
std::vector<ChunkPlan> plan_chunks(std::vector<Placement>& placement, const Layout& layout,
                                   const TubeOptions& options) {
  std::vector<ChunkPlan> plans;
  const auto fits = [&](uint64_t v, uint64_t i) {
    return i <= options.max_chunk_indices && v <= (uint64_t{1} << 32) &&
           v * layout.vertex_bytes + i * 4 <= options.max_chunk_bytes;
  };
  for (size_t l = 0; l < placement.size(); ++l) {
    Placement& place = placement[l];
    if (plans.empty()) plans.push_back({});
    if (place.kept_points) {
      const uint64_t v = layout.vertices(place.kept_points), i = layout.indices(place.kept_points);
      if (!fits(v, i))
        throw Error("tubes: line " + std::to_string(l) + " alone needs " + std::to_string(i) +
                    " indices and " + std::to_string(v * layout.vertex_bytes + i * 4) +
                    " bytes, more than one chunk may hold");
      if (!fits(plans.back().vertices + v, plans.back().indices + i)) {
        plans.back().line_count = l - plans.back().first_line;
        plans.push_back({l, 0, 0, 0});
      }
      place.vertex_base = plans.back().vertices;
      place.index_base = plans.back().indices;
      plans.back().vertices += v;
      plans.back().indices += i;
    }
    place.chunk = plans.size() - 1;
  }
  if (!plans.empty()) plans.back().line_count = placement.size() - plans.back().first_line;
  return plans;
}

// Per-thread scratch for one line: kept points, their source indices and frames.
struct Scratch {
  std::vector<uint64_t> source;
  std::vector<vec3> p, t, n;
};

class Builder {
 public:
  Builder(const LineSet& lines, const TubeOptions& options, TubeMesh& mesh)
      : lines_(lines), options_(options), mesh_(mesh) {}
  void build(const ProgressFn& progress);

 private:
  void resolve_attributes();
  void compute_frames(Scratch& s) const;
  void write_line(size_t line, Scratch& scratch) const;

  const LineSet& lines_;
  const TubeOptions& options_;
  TubeMesh& mesh_;
  Layout layout_;
  float min_distance_ = 0;
  const std::vector<float>* attribute_ = nullptr;
  bool attribute_per_line_ = false;
  const std::vector<float>* radius_values_ = nullptr;
  float radius_max_ = 1;
  std::vector<Placement> placement_;
  std::vector<float> cos_, sin_;
};

void Builder::resolve_attributes() {
  const std::string& name = options_.attribute;
  if (name != "none") {
    const Attribute* a = name.empty()
                             ? (lines_.attributes.empty() ? nullptr : &lines_.attributes[0])
                             : lines_.find_attribute(name);
    const Attribute* la = a || name.empty() ? nullptr : lines_.find_line_attribute(name);
    if (!name.empty() && !a && !la) throw Error("tubes: no attribute named '" + name + "'");
    if (a || la) {
      const Attribute& chosen = a ? *a : *la;
      attribute_ = &chosen.values;
      attribute_per_line_ = la != nullptr;
      mesh_.attribute = chosen.name;
      if (options_.attribute_range) {
        mesh_.attribute_range = *options_.attribute_range;
      } else {
        const ValueRange r = compute_range(chosen.values);
        mesh_.attribute_range = {r.min, r.max};
      }
    }
  }
  if (!options_.radius_attribute.empty()) {
    const Attribute* r = lines_.find_attribute(options_.radius_attribute);
    if (!r) throw Error("tubes: no vertex attribute named '" + options_.radius_attribute + "'");
    radius_values_ = &r->values;
    radius_max_ = compute_range(r->values).max;
    if (!(radius_max_ > 0))
      throw Error("tubes: radius attribute '" + r->name + "' has no positive value");
  }
}

// Tangents bisect the unit directions of the two segments at a point (one-sided at the ends;
// the incoming direction where the line turns back on itself). Normals are rotation-minimising
// by double reflection (Wang et al. 2008). Reflections preserve length and orthogonality, so
// the serial chain from point to point carries only the two reflections (renormalised every 32
// steps against float drift); projecting onto the tangent's plane and normalising happen off
// the chain, where they overlap across points instead of adding to its latency.
void Builder::compute_frames(Scratch& s) const {
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

void Builder::write_line(size_t line, Scratch& s) const {
  const Placement& place = placement_[line];
  if (!place.kept_points) return;
  s.source.clear();
  s.p.clear();
  for_each_kept_point(lines_, line, min_distance_, [&](uint64_t i, vec3 p) {
    s.source.push_back(i);
    s.p.push_back(p);
  });
  compute_frames(s);

  TubeChunk& chunk = mesh_.chunks[place.chunk];
  const uint64_t n = layout_.sides;
  const size_t m = s.p.size();
  const uint64_t v0 = place.vertex_base;
  float* pos = chunk.positions.data() + 3 * v0;
  float* nrm = chunk.normals.empty() ? nullptr : chunk.normals.data() + 3 * v0;
  int16_t* oct = chunk.normals_oct.empty() ? nullptr : chunk.normals_oct.data() + 2 * v0;
  uint16_t* attr = chunk.attribute.empty() ? nullptr : chunk.attribute.data() + v0;
  const auto emit = [&](vec3 p, vec3 normal, uint16_t a) {
    *pos++ = p.x, *pos++ = p.y, *pos++ = p.z;
    if (nrm) *nrm++ = normal.x, *nrm++ = normal.y, *nrm++ = normal.z;
    if (oct) {
      const auto e = encode_octahedral(normal.x, normal.y, normal.z);
      *oct++ = e[0], *oct++ = e[1];
    }
    if (attr) *attr++ = a;
  };
  const uint16_t line_value = attribute_ && attribute_per_line_
                                  ? to_unorm16((*attribute_)[line], mesh_.attribute_range)
                                  : 0;
  // Locals, not members: the float stores below could alias them and force reloads.
  const float radius = mesh_.radius, radius_max = radius_max_;
  const std::array<float, 2> range = mesh_.attribute_range;
  std::array<float, 32> cos_j, sin_j;
  std::copy(cos_.begin(), cos_.end(), cos_j.begin());
  std::copy(sin_.begin(), sin_.end(), sin_j.begin());
  // Scalar components, not vec3 copies: GCC spills 12-byte structs through the stack here and
  // the partial reloads stall store forwarding (measured: ~15% of the build).
  for (size_t i = 0; i < m; ++i) {
    const float px = s.p[i].x, py = s.p[i].y, pz = s.p[i].z;
    const float tx = s.t[i].x, ty = s.t[i].y, tz = s.t[i].z;
    const float nx = s.n[i].x, ny = s.n[i].y, nz = s.n[i].z;
    const float bx = ty * nz - tz * ny, by = tz * nx - tx * nz, bz = tx * ny - ty * nx;
    float r = radius;
    if (radius_values_) {
      const float v = (*radius_values_)[s.source[i]];
      r *= v > 0 && std::isfinite(v) ? v / radius_max : 0.01f;
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
          attribute_per_line_ ? line_value : to_unorm16((*attribute_)[s.source[i]], range);
      for (uint64_t j = 0; j < n; ++j) *attr++ = a;
    }
  }
  if (layout_.caps) {
    const uint16_t a_first = attr ? chunk.attribute[v0] : 0;
    const uint16_t a_last = attr ? chunk.attribute[v0 + (m - 1) * n] : 0;
    emit(s.p[0], -s.t[0], a_first);
    emit(s.p[m - 1], s.t[m - 1], a_last);
  }

  // Two triangles per segment and ring index; winding makes the normals point outwards.
  uint32_t* idx = chunk.indices.data() + place.index_base;
  for (uint64_t i = 0; i + 1 < m; ++i) {
    const uint64_t ring = v0 + i * n, next = ring + n;
    for (uint64_t j = 0; j < n; ++j) {
      const uint64_t j1 = j + 1 == n ? 0 : j + 1;
      const uint32_t a = uint32_t(ring + j), b = uint32_t(ring + j1);
      const uint32_t c = uint32_t(next + j1), d = uint32_t(next + j);
      *idx++ = a, *idx++ = b, *idx++ = c;
      *idx++ = a, *idx++ = c, *idx++ = d;
    }
  }
  if (layout_.caps) {
    const uint64_t first = v0, last = v0 + (m - 1) * n, centre = v0 + m * n;
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

}  // namespace

float world_radius(const LineSet& lines, const TubeOptions& options) {
  return options.radius_absolute ? options.radius
                                 : options.radius * compute_bounds(lines).diagonal();
}

namespace {

void Builder::build(const ProgressFn& progress) {
  if (options_.sides < 3 || options_.sides > 32)
    throw Error("tubes: sides must be 3..32, got " + std::to_string(options_.sides));
  if (!(options_.radius > 0) || !std::isfinite(options_.radius))
    throw Error("tubes: radius must be positive");
  const float diagonal = compute_bounds(lines_).diagonal();
  mesh_.sides = options_.sides;
  mesh_.caps = options_.caps;
  mesh_.normals = options_.normals;
  mesh_.radius = world_radius(lines_, options_);
  if (!(mesh_.radius > 0)) throw Error("tubes: the data has no extent, use an absolute radius");
  min_distance_ = options_.min_point_distance * diagonal;
  resolve_attributes();
  layout_ = {uint64_t(options_.sides), options_.caps,
             tube_vertex_bytes(options_.normals, attribute_ != nullptr)};
  for (int j = 0; j < options_.sides; ++j) {
    const double angle = 2 * std::numbers::pi * j / options_.sides;
    cos_.push_back(float(std::cos(angle)));
    sin_.push_back(float(std::sin(angle)));
  }

  const size_t line_count = lines_.line_count();
  placement_.assign(line_count, {});
  tbb::parallel_for(tbb::blocked_range<size_t>(0, line_count, 256), [&](auto range) {
    for (size_t l = range.begin(); l != range.end(); ++l) {
      uint64_t kept = 0;
      for_each_kept_point(lines_, l, min_distance_, [&](uint64_t, vec3) { ++kept; });
      placement_[l].kept_points = kept >= 2 ? kept : 0;
    }
  });
  uint64_t kept_total = 0;
  for (const Placement& p : placement_) {
    kept_total += p.kept_points;
    mesh_.lines_dropped += p.kept_points == 0;
  }
  const std::vector<ChunkPlan> plans = plan_chunks(placement_, layout_, options_);
  if (mesh_.lines_dropped == line_count) throw Error("tubes: no line has two distinct points");
  mesh_.points_skipped = lines_.point_count() - kept_total;  // includes points of dropped lines

  mesh_.chunks.resize(plans.size());
  for (size_t c = 0; c < plans.size(); ++c) {
    TubeChunk& chunk = mesh_.chunks[c];
    chunk.first_line = plans[c].first_line;
    chunk.line_count = plans[c].line_count;
    chunk.positions = Array<float>(3 * plans[c].vertices);
    if (options_.normals == NormalEncoding::Float32)
      chunk.normals = Array<float>(3 * plans[c].vertices);
    else
      chunk.normals_oct = Array<int16_t>(2 * plans[c].vertices);
    if (attribute_) chunk.attribute = Array<uint16_t>(plans[c].vertices);
    chunk.indices = Array<uint32_t>(plans[c].indices);
  }

  // Every line writes its own precomputed range: the bytes do not depend on the schedule.
  // Batches let the calling thread report progress between them.
  const size_t batches = std::clamp<size_t>(line_count / 4096, 1, 64);
  for (size_t b = 0; b < batches; ++b) {
    const size_t begin = line_count * b / batches, end = line_count * (b + 1) / batches;
    tbb::parallel_for(tbb::blocked_range<size_t>(begin, end, 64), [&](auto range) {
      Scratch scratch;
      for (size_t l = range.begin(); l != range.end(); ++l) write_line(l, scratch);
    });
    if (progress) progress(end, line_count);
  }
}

}  // namespace

TubeMesh build_tubes(const LineSet& lines, const TubeOptions& options, const ProgressFn& progress) {
  TubeMesh mesh;
  Builder(lines, options, mesh).build(progress);
  return mesh;
}

}  // namespace linebake
