#include "render/voxel_ray_caster.hpp"

#include <tbb/blocked_range2d.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "core/measure.hpp"

namespace linebake {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

struct VoxelHit {
  double t;
  uint32_t line_bits;
  glm::dvec3 normal;
  double attribute;
};

// Ray (unit direction) against the capsule of radius r around [a, b]: the entering distance, or
// -1. Cylinder first, then the end sphere on the side the cylinder hit falls off.
double intersect_capsule(const glm::dvec3& ro, const glm::dvec3& rd, const glm::dvec3& a,
                         const glm::dvec3& b, double r) {
  const glm::dvec3 ba = b - a, oa = ro - a;
  const double baba = glm::dot(ba, ba);
  if (baba > 1e-24) {
    const double bard = glm::dot(ba, rd), baoa = glm::dot(ba, oa);
    const double k2 = baba - bard * bard;
    const double k1 = baba * glm::dot(oa, rd) - baoa * bard;
    const double k0 = baba * glm::dot(oa, oa) - baoa * baoa - r * r * baba;
    if (k2 > 0) {
      const double h = k1 * k1 - k2 * k0;
      if (h < 0) return -1;
      const double t = (-k1 - std::sqrt(h)) / k2;
      const double y = baoa + t * bard;
      if (y > 0 && y < baba) return t;
      const glm::dvec3 oc = y <= 0 ? oa : ro - b;
      const double sb = glm::dot(rd, oc), sc = glm::dot(oc, oc) - r * r;
      const double sh = sb * sb - sc;
      return sh > 0 ? -sb - std::sqrt(sh) : -1;
    }
  }
  // A point (or a ray along the axis): the sphere at the nearer end decides.
  const glm::dvec3 oc = glm::dot(rd, ba) > 0 ? oa : ro - b;
  const double sb = glm::dot(rd, oc), sc = glm::dot(oc, oc) - r * r;
  const double sh = sb * sb - sc;
  return sh > 0 ? -sb - std::sqrt(sh) : -1;
}

struct Caster {
  const VoxelGrid& grid;
  const OccupancyPyramid& occupancy;
  const TransferFunction& tf;
  const VrcOptions& options;
  double radius;

  glm::dvec3 voxel_point(uint32_t x, uint32_t y, uint32_t z, const std::array<float, 3>& l) const {
    const double s = grid.voxel_size;
    return {grid.origin[0] + (double(x) + double(l[0])) * s,
            grid.origin[1] + (double(y) + double(l[1])) * s,
            grid.origin[2] + (double(z) + double(l[2])) * s};
  }

  double attribute_value(uint8_t unorm) const {
    const auto& r = grid.attribute_range;
    return double(r[0]) + double(unorm) / 255.0 * (double(r[1]) - double(r[0]));
  }

  // Hits of the chords around voxel v with t in [t_enter, t_exit), nearest first, one per line id.
  void voxel_hits(const std::array<int64_t, 3>& v, const glm::dvec3& eye, const glm::dvec3& dir,
                  double t_enter, double t_exit, std::vector<VoxelHit>& hits,
                  uint64_t& chords_tested) const {
    hits.clear();
    const auto& res = grid.resolution;
    // Intersect from the voxel's entry point: from the eye, |o - a|^2 and (o - a).(b - a)^2
    // cancel in float32 (the GPU's precision) when the eye is far from a thin tube.
    const glm::dvec3 local = eye + t_enter * dir;
    for (int64_t z = std::max<int64_t>(v[2] - 1, 0); z <= std::min<int64_t>(v[2] + 1, res[2] - 1);
         ++z)
      for (int64_t y = std::max<int64_t>(v[1] - 1, 0); y <= std::min<int64_t>(v[1] + 1, res[1] - 1);
           ++y)
        for (int64_t x = std::max<int64_t>(v[0] - 1, 0);
             x <= std::min<int64_t>(v[0] + 1, res[0] - 1); ++x) {
          const uint64_t i = grid.index(uint32_t(x), uint32_t(y), uint32_t(z));
          for (uint32_t c = grid.offsets[i]; c < grid.offsets[i + 1]; ++c) {
            ++chords_tested;
            const DecodedChord d =
                unpack_chord(grid.chords[2 * c], grid.chords[2 * c + 1], grid.quantization);
            const glm::dvec3 a = voxel_point(uint32_t(x), uint32_t(y), uint32_t(z), d.start);
            const glm::dvec3 b = voxel_point(uint32_t(x), uint32_t(y), uint32_t(z), d.end);
            const double t = t_enter + intersect_capsule(local, dir, a, b, radius);
            if (!(t >= t_enter && t < t_exit)) continue;
            const glm::dvec3 p = eye + t * dir, ab = b - a;
            const double len2 = glm::dot(ab, ab);
            const double s = len2 > 0 ? std::clamp(glm::dot(p - a, ab) / len2, 0.0, 1.0) : 0.0;
            const glm::dvec3 n = p - (a + s * ab);
            const double attribute =
                attribute_value(d.attribute_start) +
                s * (attribute_value(d.attribute_end) - attribute_value(d.attribute_start));
            hits.push_back(
                {t, d.line_bits, glm::length(n) > 0 ? glm::normalize(n) : -dir, attribute});
          }
        }
    std::sort(hits.begin(), hits.end(), [](const VoxelHit& p, const VoxelHit& q) {
      return p.t < q.t || (p.t == q.t && p.line_bits < q.line_bits);
    });
    // Chords of one line in neighbouring voxels overlap near their shared face: keep the nearest.
    size_t kept = 0;
    for (size_t i = 0; i < hits.size(); ++i) {
      bool seen = false;
      for (size_t k = 0; k < kept; ++k) seen = seen || hits[k].line_bits == hits[i].line_bits;
      if (!seen) hits[kept++] = hits[i];
    }
    hits.resize(kept);
  }

  // The largest empty occupancy level at voxel v (-1: v's neighbourhood has chords).
  int empty_level(const std::array<int64_t, 3>& v) const {
    int empty = -1;
    for (int k = int(occupancy.levels()) - 1; k >= 0; --k)
      if (!occupancy.occupied(size_t(k), uint32_t(v[0] >> k), uint32_t(v[1] >> k),
                              uint32_t(v[2] >> k))) {
        empty = k;
        break;
      }
    return empty;
  }

  struct Pixel {
    glm::dvec3 colour{0};
    double alpha = 0;
    uint32_t hits = 0;
  };

  Pixel cast(const glm::dvec3& eye, const glm::dvec3& dir, std::vector<VoxelHit>& hits,
             VrcCounters& counters) const {
    Pixel px;
    const auto& res = grid.resolution;
    const double s = grid.voxel_size;
    // Grid coordinates g(t) = g0 + t gd, t in world units along the unit direction.
    glm::dvec3 g0, gd;
    double t0 = 0, t1 = kInfinity;
    for (int k = 0; k < 3; ++k) {
      g0[k] = (eye[k] - double(grid.origin[size_t(k)])) / s;
      gd[k] = dir[k] / s;
      if (gd[k] == 0) {
        if (g0[k] < 0 || g0[k] > double(res[size_t(k)])) return px;
        continue;
      }
      double ta = (0 - g0[k]) / gd[k], tb = (double(res[size_t(k)]) - g0[k]) / gd[k];
      if (ta > tb) std::swap(ta, tb);
      t0 = std::max(t0, ta), t1 = std::min(t1, tb);
    }
    if (!(t0 < t1)) return px;
    std::array<int64_t, 3> v{}, step{};
    for (int k = 0; k < 3; ++k) {
      v[size_t(k)] = std::clamp<int64_t>(int64_t(std::floor(g0[k] + t0 * gd[k])), 0,
                                         int64_t(res[size_t(k)]) - 1);
      step[size_t(k)] = gd[k] > 0 ? 1 : -1;
    }
    // Distance at which the ray leaves cell [lo, hi) along each axis; the smallest wins.
    const auto exit = [&](const std::array<int64_t, 3>& lo, int64_t size, int& axis) {
      double t = kInfinity;
      for (int k = 0; k < 3; ++k) {
        if (gd[k] == 0) continue;
        const double face = double(gd[k] > 0 ? lo[size_t(k)] + size : lo[size_t(k)]);
        const double tk = (face - g0[k]) / gd[k];
        if (tk < t) t = tk, axis = k;
      }
      return t;
    };
    double t_enter = t0;
    const Shading& sh = options.shading;
    const glm::dvec3 to_eye = -dir;
    while (t_enter < t1) {
      if (options.skip_empty_space) {
        const int level = empty_level(v);
        if (level >= 0) {
          ++counters.cells_skipped;
          const int64_t size = int64_t(1) << level;
          std::array<int64_t, 3> lo{};
          for (size_t k = 0; k < 3; ++k) lo[k] = (v[k] >> level) << level;
          int axis = 0;
          // A ray along a cell's face can leave it where it entered: it still steps out of the
          // cell (it had ended there, dropping every hit behind).
          const double t_exit = std::max(exit(lo, size, axis), t_enter);
          t_enter = t_exit;
          for (size_t k = 0; k < 3; ++k)
            v[k] = int(k) == axis
                       ? (step[k] > 0 ? lo[k] + size : lo[k] - 1)
                       : std::clamp<int64_t>(int64_t(std::floor(g0[int(k)] + t_exit * gd[int(k)])),
                                             lo[k], lo[k] + size - 1);
          if (v[size_t(axis)] < 0 || v[size_t(axis)] >= int64_t(res[size_t(axis)])) break;
          continue;
        }
      }
      ++counters.voxels_visited;
      int axis = 0;
      const double t_exit = std::min(exit(v, 1, axis), t1);
      voxel_hits(v, eye, dir, t_enter, t_exit, hits, counters.chords_tested);
      for (const VoxelHit& h : hits) {
        if (options.early_termination && px.alpha >= options.termination_alpha) break;
        const Rgba base = tf.evaluate(h.attribute);
        px.colour += (1 - px.alpha) * base.a * shade_hit(base, h.normal, to_eye, sh);
        px.alpha += (1 - px.alpha) * base.a;
        ++px.hits;
      }
      if (options.early_termination && px.alpha >= options.termination_alpha) break;
      t_enter = t_exit;
      v[size_t(axis)] += step[size_t(axis)];
      if (v[size_t(axis)] < 0 || v[size_t(axis)] >= int64_t(res[size_t(axis)])) break;
    }
    return px;
  }
};

}  // namespace

double vrc_radius(const VoxelGrid& grid, double requested) {
  const double voxel = grid.voxel_size;
  if (!(requested > 0)) return 0.5 * voxel;
  return std::min(requested, voxel);
}

VrcFrame cast_voxel_frame(const VoxelGrid& grid, const OccupancyPyramid& occupancy,
                          const Camera& camera, const TransferFunction& tf_in,
                          const VrcOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  TransferFunction tf = tf_in;
  if (tf.range[0] == 0 && tf.range[1] == 0)
    tf.range = {double(grid.attribute_range[0]), double(grid.attribute_range[1])};
  const int w = options.width, h = options.height;
  VrcFrame frame;
  frame.image = Image(w, h, 3);
  frame.alpha.assign(size_t(w) * size_t(h), 0.0f);
  frame.depth_complexity.assign(size_t(w) * size_t(h), 0);
  frame.stats.radius = vrc_radius(grid, options.radius);
  frame.stats.radius_clamped = options.radius > grid.voxel_size;
  const Caster caster{grid, occupancy, tf, options, frame.stats.radius};
  struct Scratch {
    std::vector<VoxelHit> hits;
    VrcCounters counters;
  };
  tbb::enumerable_thread_specific<Scratch> scratch;
  const glm::dvec3 bg(options.shading.background[0], options.shading.background[1],
                      options.shading.background[2]);
  tbb::parallel_for(tbb::blocked_range2d<int>(0, h, 16, 0, w, 16), [&](const auto& tile) {
    Scratch& sc = scratch.local();
    for (int y = tile.rows().begin(); y != tile.rows().end(); ++y)
      for (int x = tile.cols().begin(); x != tile.cols().end(); ++x) {
        const glm::dvec3 dir = camera.ray_direction(x, y, w, h);
        const auto px = caster.cast(camera.eye, dir, sc.hits, sc.counters);
        const glm::dvec3 c = px.colour + (1 - px.alpha) * bg;
        for (int k = 0; k < 3; ++k) frame.image.at(x, y, k) = float(c[k]);
        const size_t i = size_t(y) * size_t(w) + size_t(x);
        frame.alpha[i] = float(px.alpha);
        frame.depth_complexity[i] = px.hits;
      }
  });
  VrcStats& s = frame.stats;
  for (const Scratch& sc : scratch) {
    s.voxels_visited += sc.counters.voxels_visited;
    s.cells_skipped += sc.counters.cells_skipped;
    s.chords_tested += sc.counters.chords_tested;
  }
  for (uint32_t d : frame.depth_complexity) {
    s.hits += d;
    s.max_depth_complexity = std::max(s.max_depth_complexity, d);
  }
  s.frame_bytes = uint64_t(w) * uint64_t(h) * (12 + 4 + 4);
  s.seconds = seconds_since(start);
  return frame;
}

}  // namespace linebake
