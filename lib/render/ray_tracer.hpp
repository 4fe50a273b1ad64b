#pragma once
// The transparent ray tracer on the CPU (technique `embree`) and the ground truth (technique
// `reference`: the same tracer over the triangle tube mesh). Every hit along a ray is collected
// by an intersection filter that records and rejects it, so Embree traverses the whole ray in
// one call; hits are then de-duplicated (filters can fire twice for one hit), back hits dropped
// (transparent tubes are rasterised with back-face culling), sorted by (t, instance, geometry,
// primitive) and composited front to back in double precision (techniques.md section 1).

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
  // Trace 4x2 pixel packets with rtcIntersect8 (filter collection only).
  bool packets = false;
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
};

// Every front hit along one ray within [t_near, t_far), nearest first.
std::vector<RayHit> trace_hits(const EmbreeScene& scene, glm::dvec3 origin, glm::dvec3 direction,
                               double t_near = 0, double t_far = 1e300,
                               TraceCounters* counters = nullptr,
                               HitCollection collection = HitCollection::Filter);

// Blinn-Phong of one hit with straight colour `base`, the normal flipped toward the eye.
glm::dvec3 shade_hit(const Rgba& base, glm::dvec3 normal, const glm::dvec3& to_eye,
                     const Shading& shading);

// Front-to-back compositing of shaded hits over the background: returns linear RGB and A.
std::array<double, 4> composite(const std::vector<RayHit>& hits, const glm::dvec3& direction,
                                const TransferFunction& tf, const TraceOptions& options,
                                uint64_t* composited = nullptr);

struct FrameStats {
  double seconds = 0;
  int width = 0, height = 0;
  TraceCounters counters;
  uint32_t max_depth_complexity = 0;
  double mean_depth_complexity = 0;          // over all pixels
  double mean_covered_depth_complexity = 0;  // over pixels with at least one hit
  uint64_t frame_bytes = 0;                  // image + depth-complexity image + peak hit buffers
};

struct Frame {
  Image image;                             // linear RGB
  std::vector<uint32_t> depth_complexity;  // front hits per pixel
  FrameStats stats;
};

// Renders one frame, multithreaded over 16x16 tiles. The result does not depend on the
// thread count.
Frame trace_frame(const EmbreeScene& scene, const Camera& camera, const TransferFunction& tf,
                  const TraceOptions& options);

}  // namespace linebake
