#pragma once
// The transparent ray tracer on the CPU (technique `embree`) and the ground truth (technique
// `reference`: the same tracer over the triangle tube mesh). The hits along a ray are collected
// by an intersection filter that records and rejects each, so Embree traverses a stretch of the
// ray in one call; hits are then de-duplicated (filters can fire twice for one hit), back hits
// dropped (transparent tubes are rasterised with back-face culling), sorted by (t, instance,
// geometry, primitive) and composited front to back in double precision (techniques.md
// section 1).
//
// Traversal bounded by opacity: when a pixel can become opaque (A = 1 exactly, or the
// early-termination alpha), the ray is walked in depth intervals. A closest-hit query finds where
// the first surface is; each interval's hits are collected by the filter, resolved and
// composited with those before, and the walk stops once the pixel is opaque. Interval lengths
// grow while they hold few hits. Every decision of the resolve step looks only at hits before the
// one decided, so the image is the all-hits image exactly (docs/cli.md, `render`). A k-nearest
// filter that shrinks the ray's far end was the other candidate; an Embree 3 filter can move the
// far end only by accepting the current hit, which drops the hits between it and the k-th.

#include <cstdint>
#include <string>
#include <vector>

#include "accel/embree_scene.hpp"
#include "render/camera.hpp"
#include "render/image.hpp"
#include "render/transfer_function.hpp"

namespace linebake {

// Blinn-Phong with a headlight (light at the eye, so the half vector is the view vector).
struct Shading {
  double ambient = 0.1, diffuse = 0.85, specular = 0.2, shininess = 30;
  std::array<double, 3> background{1, 1, 1};  // linear RGB
};

// How the hits along a ray are found. Filter: one traversal whose intersection filter records and
// rejects every hit. Stepping: closest-hit queries repeated from just past the previous hit (what
// hardware ray tracing does); a hit within 1e-6 t of the previous one is not seen again.
enum class HitCollection { Filter, Stepping };
HitCollection parse_hit_collection(const std::string& name);  // filter | stepping
const char* to_string(HitCollection collection);

struct TraceOptions {
  int width = 1280, height = 720;
  // Stop compositing a pixel once its opacity reaches termination_alpha. Off for ground truth.
  bool early_termination = false;
  double termination_alpha = 0.99;
  HitCollection collection = HitCollection::Filter;
  // Trace 4x2 pixel packets with rtcIntersect8 (filter collection only; every hit).
  bool packets = false;
  // Collect every hit of every ray: the depth complexity image and its statistics. Off: the
  // interval walk stops where the pixel is opaque, and the depth complexity is not counted.
  bool every_hit = true;
  Shading shading;
};

struct RayHit {
  double t = 0;
  unsigned instance = RTC_INVALID_GEOMETRY_ID, geometry = 0, primitive = 0;
  SurfacePoint surface;
};

struct TraceCounters {
  uint64_t hits = 0;        // front hits after de-duplication (the depth complexity sum)
  uint64_t duplicates = 0;  // repeated filter calls for one hit, and seam doubles, removed
  uint64_t back_hits = 0;   // rejected
  uint64_t composited = 0;  // hits that went into the pixel (fewer with early termination)
  uint64_t traversals = 0;  // Embree queries: one per ray, or per interval and the first hit's
  uint64_t stopped = 0;     // rays whose walk stopped with the pixel opaque
};

// Every front hit along one ray within [t_near, t_far), nearest first.
std::vector<RayHit> trace_hits(const EmbreeScene& scene, glm::dvec3 origin, glm::dvec3 direction,
                               double t_near = 0, double t_far = 1e300,
                               TraceCounters* counters = nullptr,
                               HitCollection collection = HitCollection::Filter);

// Blinn-Phong of one hit with straight colour `base`, the normal flipped toward the eye.
glm::dvec3 shade_hit(const Rgba& base, glm::dvec3 normal, const glm::dvec3& to_eye,
                     const Shading& shading);

// Front-to-back compositing, one hit at a time (techniques.md section 1), in double precision.
class Compositor {
 public:
  Compositor(const glm::dvec3& direction, const TransferFunction& tf, const TraceOptions& options);
  void add(const RayHit& hit);
  // No further hit can change the pixel: alpha 1, or the early-termination alpha reached.
  bool opaque() const { return alpha_ >= stop_alpha_; }
  uint64_t used() const { return used_; }
  double alpha() const { return alpha_; }
  double stop_alpha() const { return stop_alpha_; }
  std::array<double, 4> over_background() const;  // linear RGB and A

 private:
  const TransferFunction& tf_;
  const TraceOptions& options_;
  glm::dvec3 to_eye_;
  double stop_alpha_;
  glm::dvec3 colour_{0};
  double alpha_ = 0;
  uint64_t used_ = 0;
};

// Whether the interval walk pays: early termination, or opacity 1 over a stretch of the transfer
// function's range (a pixel then becomes opaque at such a hit). Else one traversal collects
// every hit.
bool can_become_opaque(const TransferFunction& tf, const TraceOptions& options);

// Front-to-back compositing of shaded hits over the background: returns linear RGB and A.
std::array<double, 4> composite(const std::vector<RayHit>& hits, const glm::dvec3& direction,
                                const TransferFunction& tf, const TraceOptions& options,
                                uint64_t* composited = nullptr);

struct FrameStats {
  double seconds = 0;
  int width = 0, height = 0;
  bool every_hit = true;  // else counters.hits are the hits visited and no depth complexity
  TraceCounters counters;
  uint32_t max_depth_complexity = 0;
  double mean_depth_complexity = 0;          // over all pixels
  double mean_covered_depth_complexity = 0;  // over pixels with at least one hit
  uint64_t frame_bytes = 0;                  // image + depth-complexity image + peak hit buffers
};

struct Frame {
  Image image;                             // linear RGB
  std::vector<uint32_t> depth_complexity;  // front hits per pixel (empty without every_hit)
  FrameStats stats;
};

// Renders one frame, multithreaded over 16x16 tiles. The result does not depend on the
// thread count.
Frame trace_frame(const EmbreeScene& scene, const Camera& camera, const TransferFunction& tf,
                  const TraceOptions& options);

}  // namespace linebake
