#include "render/ray_tracer.hpp"

#include <tbb/blocked_range2d.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <tuple>

#include "core/error.hpp"
#include "core/interrupt.hpp"
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

bool front_facing(const RawHit& h, const glm::dvec3& direction) {
  return h.hit.Ng_x * direction.x + h.hit.Ng_y * direction.y + h.hit.Ng_z * direction.z <= 0;
}

// Sorts raw[first..] by distance and appends its front hits to `out`: repeated reports of one
// hit, back hits and seam doubles are removed. Every decision looks back only (at raw hits and
// front hits before the one decided), so resolving a ray in pieces, each starting past the
// previous one's hits, gives what resolving it whole gives.
void resolve_from(std::vector<RawHit>& raw, size_t first, const glm::dvec3& direction,
                  const EmbreeScene& scene, std::vector<RayHit>& out, TraceCounters& counters) {
  std::sort(raw.begin() + ptrdiff_t(first), raw.end(), [](const RawHit& a, const RawHit& b) {
    return std::tie(a.t, a.instance, a.geometry, a.primitive) <
           std::tie(b.t, b.instance, b.geometry, b.primitive);
  });
  const size_t before = out.size();
  for (size_t i = first; i < raw.size(); ++i) {
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
    if (!front_facing(h, direction)) {
      ++counters.back_hits;
      continue;
    }
    // A ray through a seam (a joint between segments, an edge between triangles) hits both
    // primitives at one distance; keep the first. A front hit is a seam double when a front hit
    // of an adjacent primitive lies just before it, kept or itself a double: a rule of pairs,
    // so a chain of primitives all crossed at one point (short segments of one line, a vertex's
    // fan of triangles) keeps its first hit only, as tiles keeps it in whatever order its hits
    // come (shaders/tiles_composite.glsl, insert()). Comparing with kept hits only kept every
    // second link of such a chain.
    bool seam = false;
    for (size_t k = i; k-- > 0 && h.t - raw[k].t <= 1e-5 * std::max(1.0, h.t);)
      if (raw[k].instance == h.instance && raw[k].geometry == h.geometry &&
          front_facing(raw[k], direction) &&
          scene.adjacent(h.geometry, raw[k].primitive, h.primitive)) {
        seam = true;
        break;
      }
    if (seam) {
      ++counters.duplicates;
      continue;
    }
    out.push_back({h.t, h.instance, h.geometry, h.primitive, scene.surface(h.hit)});
  }
  counters.hits += out.size() - before;
}

// Sorts by distance, removes repeated reports of one hit, back hits and seam doubles; returns
// the front hits in order.
void resolve(std::vector<RawHit>& raw, const glm::dvec3& direction, const EmbreeScene& scene,
             std::vector<RayHit>& out, TraceCounters& counters) {
  out.clear();
  resolve_from(raw, 0, direction, scene, out, counters);
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
  const SceneFrame& frame = scene.frame();  // traced in the scene's frame, t given back in world's
  std::vector<RawHit> raw;
  collect(scene, frame.to_scene(origin), direction, t_near * frame.scale, t_far * frame.scale,
          collection, raw);
  std::vector<RayHit> hits;
  TraceCounters local;
  resolve(raw, direction, scene, hits, counters ? *counters : local);
  for (RayHit& h : hits) h.t /= frame.scale;
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
  Compositor pixel(direction, tf, options);
  for (const RayHit& h : hits) {
    if (options.early_termination && pixel.opaque()) break;
    pixel.add(h);
  }
  if (composited) *composited += pixel.used();
  return pixel.over_background();
}

Compositor::Compositor(const glm::dvec3& direction, const TransferFunction& tf,
                       const TraceOptions& options)
    : tf_(tf),
      options_(options),
      to_eye_(-glm::normalize(direction)),
      stop_alpha_(options.early_termination ? options.termination_alpha : 1.0) {}

void Compositor::add(const RayHit& h) {
  const Rgba base = tf_.evaluate(h.surface.attribute);
  const glm::dvec3 shaded = shade_hit(base, h.surface.normal, to_eye_, options_.shading);
  colour_ += (1 - alpha_) * base.a * shaded;
  alpha_ += (1 - alpha_) * base.a;
  ++used_;
}

std::array<double, 4> Compositor::over_background() const {
  const auto& bg = options_.shading.background;
  const glm::dvec3 c = colour_ + (1 - alpha_) * glm::dvec3(bg[0], bg[1], bg[2]);
  return {c.x, c.y, c.z, alpha_};
}

bool can_become_opaque(const TransferFunction& tf, const TraceOptions& options) {
  if (options.early_termination) return true;
  // Opacity 1 over a stretch of the range, not at a single value (semi's top end): a hit lands
  // exactly on one value too rarely to pay for the walk.
  const auto& p = tf.opacities;
  for (size_t i = 0; i + 1 < p.size(); ++i)
    if (p[i].opacity >= 1 && p[i + 1].opacity >= 1 && p[i + 1].x > p[i].x) return true;
  return p.size() == 1 && p[0].opacity >= 1;
}

namespace {

// Buffers one thread reuses from ray to ray.
struct RayScratch {
  std::vector<RawHit> raw, interval;
  std::vector<RayHit> hits;
};

// The length of the next interval of a walk that has found `front_hits` over `walked` past the
// first surface, `last_hits` of its raw hits in the last interval. Every traversal starts at
// the root again, and a hit found beyond the stop is traversed for nothing: the interval reaches
// half of the way to where the opacity so far, at the mean opacity per hit and the hit density
// so far, predicts the stop (one more traversal with better statistics costs less than
// overshooting; measured, README). With no prediction (no opacity yet, or a stop at exactly
// A = 1, which only an opaque hit reaches), the interval grows, fastest while it holds few hits.
double next_interval(const Compositor& pixel, size_t front_hits, double walked, size_t last_hits,
                     double length, double shortest) {
  const double a = pixel.alpha(), stop = pixel.stop_alpha();
  if (a <= 0 || stop >= 1 || walked <= 0 || front_hits == 0)
    return length * (last_hits < 16 ? 4 : 2);
  const double opacity_per_hit = -std::log1p(-a) / double(pixel.used());
  const double hits_needed = std::log((1 - a) / (1 - stop)) / opacity_per_hit;
  const double hits_per_length = double(front_hits) / walked;
  return std::max(shortest, 0.5 * hits_needed / hits_per_length);
}

// The depth-interval walk of one ray (ray_tracer.hpp): returns the pixel over the background.
// `scale` is the first interval's length past the first surface.
std::array<double, 4> walk_intervals(const EmbreeScene& scene, const glm::dvec3& origin,
                                     const glm::dvec3& direction, double t_near, double t_far,
                                     double scale, const TransferFunction& tf,
                                     const TraceOptions& options, RayScratch& scratch,
                                     TraceCounters& counters) {
  Compositor pixel(direction, tf, options);
  scratch.raw.clear();
  scratch.hits.clear();
  // Where the first surface is, front or back: a closest-hit query, no filter.
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit first = make_ray(origin, direction, t_near, t_far);
  rtcIntersect1(scene.handle(), &context, &first);
  ++counters.traversals;
  if (first.hit.geomID == RTC_INVALID_GEOMETRY_ID) return pixel.over_background();
  // Interval ends are floats, as Embree's ray is: a hit at exactly an end belongs to the next
  // interval, whose tnear it is.
  const auto to_float = [](double t) { return double(float(std::min(t, 3.0e38))); };
  t_far = to_float(t_far);
  double length = scale;
  double lo = t_near, hi = to_float(std::min(t_far, double(first.ray.tfar) + length));
  size_t composited = 0;
  for (;;) {
    const bool last = hi >= t_far;
    scratch.interval.clear();
    collect_by_filter(scene, origin, direction, lo, hi, scratch.interval);
    ++counters.traversals;
    const size_t first_new = scratch.raw.size();
    for (const RawHit& h : scratch.interval)
      if (last || h.t < hi) scratch.raw.push_back(h);
    resolve_from(scratch.raw, first_new, direction, scene, scratch.hits, counters);
    for (; composited < scratch.hits.size() && !pixel.opaque(); ++composited)
      pixel.add(scratch.hits[composited]);
    if (pixel.opaque()) {
      ++counters.stopped;
      break;
    }
    if (last) break;
    length = next_interval(pixel, scratch.hits.size(), hi - double(first.ray.tfar),
                           scratch.raw.size() - first_new, length, scale);
    lo = hi;
    hi = to_float(std::min(t_far, lo + length));
    if (hi <= lo) hi = to_float(t_far);
  }
  counters.composited += pixel.used();
  return pixel.over_background();
}

}  // namespace

Frame trace_frame(const EmbreeScene& scene, const Camera& world_camera,
                  const TransferFunction& tf_in, const TraceOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  // Traced in the scene's frame (EmbreeScene::frame: short curves are scaled up); its directions
  // are the world's, its distances `frame.scale` times as long.
  const SceneFrame& scene_frame = scene.frame();
  Camera camera = world_camera;
  camera.eye = scene_frame.to_scene(world_camera.eye);
  camera.target = scene_frame.to_scene(world_camera.target);
  camera.near *= scene_frame.scale, camera.far *= scene_frame.scale;
  TransferFunction tf = tf_in;
  if (tf.range[0] == 0 && tf.range[1] == 0) {
    const auto r = scene.attribute_range();
    tf.range = {r[0], r[1]};
  }
  const int w = options.width, h = options.height;
  const bool packets = options.packets && options.collection == HitCollection::Filter;
  // The interval walk where it can stop early; every hit when asked for, or when it cannot.
  const bool walk = !options.every_hit && !packets && options.collection == HitCollection::Filter &&
                    can_become_opaque(tf, options);
  Frame frame;
  frame.image = Image(w, h, 3);
  if (!walk) frame.depth_complexity.assign(size_t(w) * h, 0);
  struct Scratch {
    std::vector<RawHit> raw[kPacket];
    std::vector<RayHit> hits;
    RayScratch ray;
    TraceCounters counters;
    size_t peak_raw = 0;
  };
  // The first interval past the first surface: a few tube radii in most sets.
  const double scale =
      std::max(1e-6, double(scene.bounds().diagonal()) / 256.0) * scene_frame.scale;
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
  // A large frame of a deep scene takes seconds: Ctrl-C between tiles, not frames (never a frame
  // with tiles missing).
  StopLatch stop;
  tbb::parallel_for(tbb::blocked_range2d<int>(0, h, 16, 0, w, 16), [&](const auto& tile) {
    if (stop.stopped()) return;
    Scratch& sc = scratch.local();
    const auto rows = tile.rows(), cols = tile.cols();
    if (!packets) {
      for (int y = rows.begin(); y != rows.end(); ++y)
        for (int x = cols.begin(); x != cols.end(); ++x) {
          glm::dvec3 dir;
          double t_near, t_far;
          ray(x, y, dir, t_near, t_far);
          if (!walk) {
            collect(scene, camera.eye, dir, t_near, t_far, options.collection, sc.raw[0]);
            ++sc.counters.traversals;
            shade(sc, sc.raw[0], x, y, dir);
            continue;
          }
          const auto c = walk_intervals(scene, camera.eye, dir, t_near, t_far, scale, tf, options,
                                        sc.ray, sc.counters);
          for (int k = 0; k < 3; ++k) frame.image.at(x, y, k) = float(c[k]);
          sc.peak_raw = std::max(sc.peak_raw, sc.ray.raw.capacity() + sc.ray.interval.capacity());
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
        ++sc.counters.traversals;
        for (int i = 0; i < kPacket; ++i)
          if (valid[i]) shade(sc, sc.raw[i], x0 + i % kPacketWidth, y0 + i / kPacketWidth, dir[i]);
      }
  });
  stop.throw_if_stopped();
  FrameStats& st = frame.stats;
  st.width = w, st.height = h;
  st.every_hit = !walk;
  uint64_t hit_buffer_bytes = 0;
  for (const Scratch& sc : scratch) {
    st.counters.hits += sc.counters.hits;
    st.counters.duplicates += sc.counters.duplicates;
    st.counters.back_hits += sc.counters.back_hits;
    st.counters.composited += sc.counters.composited;
    st.counters.traversals += sc.counters.traversals;
    st.counters.stopped += sc.counters.stopped;
    hit_buffer_bytes += (packets ? kPacket : 1) * sc.peak_raw * sizeof(RawHit) +
                        (sc.hits.capacity() + sc.ray.hits.capacity()) * sizeof(RayHit);
  }
  uint64_t covered = 0;
  for (uint32_t d : frame.depth_complexity) {
    st.max_depth_complexity = std::max(st.max_depth_complexity, d);
    covered += d > 0;
  }
  if (!walk) {
    st.mean_depth_complexity = double(st.counters.hits) / double(size_t(w) * h);
    st.mean_covered_depth_complexity = covered ? double(st.counters.hits) / double(covered) : 0.0;
  }
  st.frame_bytes = frame.image.pixels.size() * sizeof(float) +
                   frame.depth_complexity.size() * sizeof(uint32_t) + hit_buffer_bytes;
  st.seconds = seconds_since(start);
  return frame;
}

}  // namespace linebake
