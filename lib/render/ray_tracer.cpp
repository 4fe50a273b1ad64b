#include "render/ray_tracer.hpp"

#include <tbb/blocked_range2d.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <tuple>

#include "core/error.hpp"
#include "core/measure.hpp"

namespace linebake {
namespace {

struct RawHit {
  double t;
  unsigned instance, geometry, primitive;
  RTCHit hit;
};

// The intersection context carries the hit lists to the filter, one per ray of the packet
// (Embree calls the filters with the packet's size and ray order).
struct CollectContext {
  RTCIntersectContext context;
  std::vector<RawHit>* hits;
};

void collect_filter(const RTCFilterFunctionNArguments* args) {
  auto* self = reinterpret_cast<const CollectContext*>(args->context);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == 0) continue;
    RTCHit h;
    h.Ng_x = RTCHitN_Ng_x(args->hit, args->N, i);
    h.Ng_y = RTCHitN_Ng_y(args->hit, args->N, i);
    h.Ng_z = RTCHitN_Ng_z(args->hit, args->N, i);
    h.u = RTCHitN_u(args->hit, args->N, i);
    h.v = RTCHitN_v(args->hit, args->N, i);
    h.primID = RTCHitN_primID(args->hit, args->N, i);
    h.geomID = RTCHitN_geomID(args->hit, args->N, i);
    h.instID[0] = RTCHitN_instID(args->hit, args->N, i, 0);
    self->hits[i].push_back(
        {double(RTCRayN_tfar(args->ray, args->N, i)), h.instID[0], h.geomID, h.primID, h});
    args->valid[i] = 0;  // reject: traversal goes on past this hit
  }
}

auto key(const RawHit& h) {
  return std::tie(h.instance, h.geometry, h.primitive);
}

// Sorts by distance, removes repeated reports of one hit, back hits and seam doubles; returns
// the front hits in order.
void resolve(std::vector<RawHit>& raw, const glm::dvec3& direction, const EmbreeScene& scene,
             std::vector<RayHit>& out, TraceCounters& counters) {
  std::sort(raw.begin(), raw.end(), [](const RawHit& a, const RawHit& b) {
    return std::tie(a.t, a.instance, a.geometry, a.primitive) <
           std::tie(b.t, b.instance, b.geometry, b.primitive);
  });
  out.clear();
  for (size_t i = 0; i < raw.size(); ++i) {
    const RawHit& h = raw[i];
    // A filter can report one hit twice.
    bool repeated = false;
    for (size_t k = i; k-- > 0 && h.t - raw[k].t <= 1e-6 * std::max(1.0, std::abs(h.t));)
      if (key(raw[k]) == key(h)) {
        repeated = true;
        break;
      }
    if (repeated) {
      ++counters.duplicates;
      continue;
    }
    const double facing =
        h.hit.Ng_x * direction.x + h.hit.Ng_y * direction.y + h.hit.Ng_z * direction.z;
    if (facing > 0) {
      ++counters.back_hits;
      continue;
    }
    // A ray through a seam (a joint between segments, an edge between triangles) hits both
    // primitives at one distance; keep the first.
    bool seam = false;
    for (size_t k = out.size(); k-- > 0 && h.t - out[k].t <= 1e-5 * std::max(1.0, h.t);)
      if (out[k].instance == h.instance && out[k].geometry == h.geometry &&
          scene.adjacent(h.geometry, out[k].primitive, h.primitive)) {
        seam = true;
        break;
      }
    if (seam) {
      ++counters.duplicates;
      continue;
    }
    out.push_back({h.t, h.instance, h.geometry, h.primitive, scene.surface(h.hit)});
  }
  counters.hits += out.size();
}

RTCRayHit make_ray(const glm::dvec3& origin, const glm::dvec3& direction, double t_near,
                   double t_far) {
  RTCRayHit rh{};
  rh.ray.org_x = float(origin.x), rh.ray.org_y = float(origin.y), rh.ray.org_z = float(origin.z);
  rh.ray.dir_x = float(direction.x), rh.ray.dir_y = float(direction.y);
  rh.ray.dir_z = float(direction.z);
  rh.ray.tnear = float(t_near);
  rh.ray.tfar = float(std::min(t_far, 3.0e38));
  rh.ray.mask = 0xFFFFFFFFu;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  return rh;
}

void collect_by_filter(const EmbreeScene& scene, const glm::dvec3& origin,
                       const glm::dvec3& direction, double t_near, double t_far,
                       std::vector<RawHit>& raw) {
  CollectContext ctx;
  rtcInitIntersectContext(&ctx.context);
  ctx.context.filter = &collect_filter;
  ctx.hits = &raw;
  RTCRayHit rh = make_ray(origin, direction, t_near, t_far);
  rtcIntersect1(scene.handle(), &ctx.context, &rh);
}

void collect_by_stepping(const EmbreeScene& scene, const glm::dvec3& origin,
                         const glm::dvec3& direction, double t_near, double t_far,
                         std::vector<RawHit>& raw) {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  for (double t = t_near;;) {
    RTCRayHit rh = make_ray(origin, direction, t, t_far);
    rtcIntersect1(scene.handle(), &context, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return;
    const double hit_t = rh.ray.tfar;
    raw.push_back({hit_t, rh.hit.instID[0], rh.hit.geomID, rh.hit.primID, rh.hit});
    // Just past the hit, and always forward in float.
    t = std::max(hit_t * (1 + 1e-6), double(std::nextafter(float(hit_t), 3.0e38f)));
  }
}

// A packet of 4x2 pixels traced together (rtcIntersect8, coherent): lanes with valid = 0 are off
// the tile.
constexpr int kPacketWidth = 4, kPacketHeight = 2, kPacket = kPacketWidth * kPacketHeight;

void collect_packet(const EmbreeScene& scene, const glm::dvec3& origin,
                    const glm::dvec3 (&direction)[kPacket], const double (&t_near)[kPacket],
                    const double (&t_far)[kPacket], const int (&valid)[kPacket],
                    std::vector<RawHit> (&raw)[kPacket]) {
  CollectContext ctx;
  rtcInitIntersectContext(&ctx.context);
  ctx.context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  ctx.context.filter = &collect_filter;
  ctx.hits = raw;
  alignas(32) RTCRayHit8 rh{};
  alignas(32) int mask[kPacket];
  for (int i = 0; i < kPacket; ++i) {
    raw[i].clear();
    mask[i] = valid[i] ? -1 : 0;
    rh.ray.org_x[i] = float(origin.x), rh.ray.org_y[i] = float(origin.y);
    rh.ray.org_z[i] = float(origin.z);
    rh.ray.dir_x[i] = float(direction[i].x), rh.ray.dir_y[i] = float(direction[i].y);
    rh.ray.dir_z[i] = float(direction[i].z);
    rh.ray.tnear[i] = float(t_near[i]);
    rh.ray.tfar[i] = float(std::min(t_far[i], 3.0e38));
    rh.ray.mask[i] = 0xFFFFFFFFu;
    rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
  }
  rtcIntersect8(mask, scene.handle(), &ctx.context, &rh);
}

void collect(const EmbreeScene& scene, const glm::dvec3& origin, const glm::dvec3& direction,
             double t_near, double t_far, HitCollection collection, std::vector<RawHit>& raw) {
  raw.clear();
  if (collection == HitCollection::Filter)
    collect_by_filter(scene, origin, direction, t_near, t_far, raw);
  else
    collect_by_stepping(scene, origin, direction, t_near, t_far, raw);
}

}  // namespace

HitCollection parse_hit_collection(const std::string& name) {
  if (name == "filter") return HitCollection::Filter;
  if (name == "stepping") return HitCollection::Stepping;
  throw Error("unknown hit collection '" + name + "' (filter, stepping)");
}

const char* to_string(HitCollection collection) {
  return collection == HitCollection::Filter ? "filter" : "stepping";
}

std::vector<RayHit> trace_hits(const EmbreeScene& scene, glm::dvec3 origin, glm::dvec3 direction,
                               double t_near, double t_far, TraceCounters* counters,
                               HitCollection collection) {
  direction = glm::normalize(direction);
  std::vector<RawHit> raw;
  collect(scene, origin, direction, t_near, t_far, collection, raw);
  std::vector<RayHit> hits;
  TraceCounters local;
  resolve(raw, direction, scene, hits, counters ? *counters : local);
  return hits;
}

glm::dvec3 shade_hit(const Rgba& base, glm::dvec3 n, const glm::dvec3& to_eye, const Shading& s) {
  if (glm::dot(n, to_eye) < 0) n = -n;  // interpolated normals can tip past the silhouette
  const double lambert = std::max(0.0, glm::dot(n, to_eye));
  const glm::dvec3 c(base.r, base.g, base.b);
  return (s.ambient + s.diffuse * lambert) * c +
         s.specular * std::pow(lambert, s.shininess) * glm::dvec3(1);
}

std::array<double, 4> composite(const std::vector<RayHit>& hits, const glm::dvec3& direction,
                                const TransferFunction& tf, const TraceOptions& options,
                                uint64_t* composited) {
  const Shading& s = options.shading;
  const glm::dvec3 to_eye = -glm::normalize(direction);
  glm::dvec3 colour(0);
  double alpha = 0;
  uint64_t used = 0;
  for (const RayHit& h : hits) {
    if (options.early_termination && alpha >= options.termination_alpha) break;
    const Rgba base = tf.evaluate(h.surface.attribute);
    const glm::dvec3 shaded = shade_hit(base, h.surface.normal, to_eye, s);
    colour += (1 - alpha) * base.a * shaded;
    alpha += (1 - alpha) * base.a;
    ++used;
  }
  if (composited) *composited += used;
  const glm::dvec3 bg(s.background[0], s.background[1], s.background[2]);
  colour += (1 - alpha) * bg;
  return {colour.x, colour.y, colour.z, alpha};
}

Frame trace_frame(const EmbreeScene& scene, const Camera& camera, const TransferFunction& tf_in,
                  const TraceOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  TransferFunction tf = tf_in;
  if (tf.range[0] == 0 && tf.range[1] == 0) {
    const auto r = scene.attribute_range();
    tf.range = {r[0], r[1]};
  }
  const int w = options.width, h = options.height;
  Frame frame;
  frame.image = Image(w, h, 3);
  frame.depth_complexity.assign(size_t(w) * h, 0);
  struct Scratch {
    std::vector<RawHit> raw[kPacket];
    std::vector<RayHit> hits;
    TraceCounters counters;
    size_t peak_raw = 0;
  };
  tbb::enumerable_thread_specific<Scratch> scratch;
  const glm::dvec3 forward = camera.forward();
  // The ray through pixel (x, y), clipped against the camera's near and far planes as
  // rasterisation is.
  const auto ray = [&](int x, int y, glm::dvec3& dir, double& t_near, double& t_far) {
    dir = camera.ray_direction(x, y, w, h);
    const double cosine = glm::dot(dir, forward);
    t_near = camera.near / cosine, t_far = camera.far / cosine;
  };
  const auto shade = [&](Scratch& sc, std::vector<RawHit>& raw, int x, int y,
                         const glm::dvec3& dir) {
    sc.peak_raw = std::max(sc.peak_raw, raw.capacity());
    resolve(raw, dir, scene, sc.hits, sc.counters);
    const auto c = composite(sc.hits, dir, tf, options, &sc.counters.composited);
    for (int k = 0; k < 3; ++k) frame.image.at(x, y, k) = float(c[k]);
    frame.depth_complexity[size_t(y) * w + x] = uint32_t(sc.hits.size());
  };
  const bool packets = options.packets && options.collection == HitCollection::Filter;
  tbb::parallel_for(tbb::blocked_range2d<int>(0, h, 16, 0, w, 16), [&](const auto& tile) {
    Scratch& sc = scratch.local();
    const auto rows = tile.rows(), cols = tile.cols();
    if (!packets) {
      for (int y = rows.begin(); y != rows.end(); ++y)
        for (int x = cols.begin(); x != cols.end(); ++x) {
          glm::dvec3 dir;
          double t_near, t_far;
          ray(x, y, dir, t_near, t_far);
          collect(scene, camera.eye, dir, t_near, t_far, options.collection, sc.raw[0]);
          shade(sc, sc.raw[0], x, y, dir);
        }
      return;
    }
    for (int y0 = rows.begin(); y0 < rows.end(); y0 += kPacketHeight)
      for (int x0 = cols.begin(); x0 < cols.end(); x0 += kPacketWidth) {
        glm::dvec3 dir[kPacket];
        double t_near[kPacket], t_far[kPacket];
        int valid[kPacket];
        for (int i = 0; i < kPacket; ++i) {
          const int x = x0 + i % kPacketWidth, y = y0 + i / kPacketWidth;
          valid[i] = x < cols.end() && y < rows.end();
          ray(valid[i] ? x : x0, valid[i] ? y : y0, dir[i], t_near[i], t_far[i]);
        }
        collect_packet(scene, camera.eye, dir, t_near, t_far, valid, sc.raw);
        for (int i = 0; i < kPacket; ++i)
          if (valid[i]) shade(sc, sc.raw[i], x0 + i % kPacketWidth, y0 + i / kPacketWidth, dir[i]);
      }
  });
  FrameStats& st = frame.stats;
  st.width = w, st.height = h;
  uint64_t hit_buffer_bytes = 0;
  for (const Scratch& sc : scratch) {
    st.counters.hits += sc.counters.hits;
    st.counters.duplicates += sc.counters.duplicates;
    st.counters.back_hits += sc.counters.back_hits;
    st.counters.composited += sc.counters.composited;
    hit_buffer_bytes += (packets ? kPacket : 1) * sc.peak_raw * sizeof(RawHit) +
                        sc.hits.capacity() * sizeof(RayHit);
  }
  uint64_t covered = 0;
  for (uint32_t d : frame.depth_complexity) {
    st.max_depth_complexity = std::max(st.max_depth_complexity, d);
    covered += d > 0;
  }
  st.mean_depth_complexity = double(st.counters.hits) / double(size_t(w) * h);
  st.mean_covered_depth_complexity = covered ? double(st.counters.hits) / double(covered) : 0.0;
  st.frame_bytes = frame.image.pixels.size() * sizeof(float) +
                   frame.depth_complexity.size() * sizeof(uint32_t) + hit_buffer_bytes;
  st.seconds = seconds_since(start);
  return frame;
}

}  // namespace linebake
