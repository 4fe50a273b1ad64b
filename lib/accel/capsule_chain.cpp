#include "accel/capsule_chain.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace linebake {
namespace {

struct Segment {
  glm::dvec3 p0, p1;
  double radius;
};

Segment segment_of(const CapsuleChain& chain, uint32_t s) {
  const float* v = chain.vertices + 4 * uint64_t(chain.indices[s]);
  return {{v[0], v[1], v[2]}, {v[4], v[5], v[6]}, v[3]};
}

double distance_to_segment(const glm::dvec3& x, const Segment& s) {
  const glm::dvec3 axis = s.p1 - s.p0;
  const double length2 = glm::dot(axis, axis);
  const double h = length2 > 0 ? std::clamp(glm::dot(x - s.p0, axis) / length2, 0.0, 1.0) : 0.0;
  return glm::length(x - (s.p0 + h * axis));
}

// Real roots of a t^2 + b t + c, ascending (the cancellation-free form).
int solve_quadratic(double a, double b, double c, double roots[2]) {
  const double discriminant = b * b - 4 * a * c;
  if (a == 0 || discriminant < 0) return 0;
  const double q = -0.5 * (b + std::copysign(std::sqrt(discriminant), b));
  roots[0] = q / a;
  roots[1] = q != 0 ? c / q : roots[0];
  if (roots[0] > roots[1]) std::swap(roots[0], roots[1]);
  return 2;
}

// Writes lane i of a hit packet of size n.
void write_hit(RTCHitN* hits, unsigned n, unsigned i, const CapsuleHit& c, unsigned primitive,
               unsigned geometry, unsigned instance) {
  RTCHitN_Ng_x(hits, n, i) = float(c.normal.x);
  RTCHitN_Ng_y(hits, n, i) = float(c.normal.y);
  RTCHitN_Ng_z(hits, n, i) = float(c.normal.z);
  RTCHitN_u(hits, n, i) = float(c.u);
  RTCHitN_v(hits, n, i) = 0;
  RTCHitN_primID(hits, n, i) = primitive;
  RTCHitN_geomID(hits, n, i) = geometry;
  RTCHitN_instID(hits, n, i, 0) = instance;
}

void capsule_bounds(const RTCBoundsFunctionArguments* args) {
  const Segment s =
      segment_of(*static_cast<const CapsuleChain*>(args->geometryUserPtr), args->primID);
  const glm::dvec3 lo = glm::min(s.p0, s.p1) - s.radius, hi = glm::max(s.p0, s.p1) + s.radius;
  *args->bounds_o = {float(lo.x), float(lo.y), float(lo.z), 0,
                     float(hi.x), float(hi.y), float(hi.z), 0};
}

// Runs the filters on the crossings of ray lane i in distance order; the first one they accept
// is the hit (`accept` writes it). Rejected crossings let traversal go on. The filters see the
// caller's packet (Embree keeps packet size and ray order for them) with only lane i valid and
// its tfar set to the candidate distance, restored when they reject it.
template <class Args, class Invoke, class Accept>
void report(const Args* args, RTCRayN* rays, unsigned i, Invoke&& invoke, Accept&& accept) {
  const auto& chain = *static_cast<const CapsuleChain*>(args->geometryUserPtr);
  const unsigned n = args->N, instance = args->context->instID[0];
  const glm::dvec3 origin(RTCRayN_org_x(rays, n, i), RTCRayN_org_y(rays, n, i),
                          RTCRayN_org_z(rays, n, i));
  const glm::dvec3 direction(RTCRayN_dir_x(rays, n, i), RTCRayN_dir_y(rays, n, i),
                             RTCRayN_dir_z(rays, n, i));
  CapsuleHit crossings[4];
  const int count = intersect_capsule(chain, args->primID, origin, direction, crossings);
  for (int k = 0; k < count; ++k) {
    const float t = float(crossings[k].t), tfar = RTCRayN_tfar(rays, n, i);
    if (!(t > RTCRayN_tnear(rays, n, i) && t < tfar)) continue;
    alignas(64) unsigned char storage[sizeof(RTCHit16)];
    auto* hit = reinterpret_cast<RTCHitN*>(storage);
    write_hit(hit, n, i, crossings[k], args->primID, args->geomID, instance);
    int valid[16] = {};
    valid[i] = -1;
    RTCRayN_tfar(rays, n, i) = t;
    RTCFilterFunctionNArguments f{valid, args->geometryUserPtr, args->context, rays, hit, n};
    invoke(args, &f);
    if (valid[i] != 0) {
      accept(crossings[k], instance);
      return;
    }
    RTCRayN_tfar(rays, n, i) = tfar;
  }
}

void capsule_intersect(const RTCIntersectFunctionNArguments* args) {
  RTCRayN* rays = RTCRayHitN_RayN(args->rayhit, args->N);
  RTCHitN* hits = RTCRayHitN_HitN(args->rayhit, args->N);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == 0) continue;
    report(args, rays, i, &rtcFilterIntersection, [&](const CapsuleHit& c, unsigned instance) {
      write_hit(hits, args->N, i, c, args->primID, args->geomID, instance);  // tfar is c.t
    });
  }
}

void capsule_occluded(const RTCOccludedFunctionNArguments* args) {
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == 0) continue;
    report(args, args->ray, i, &rtcFilterOcclusion, [&](const CapsuleHit&, unsigned) {
      RTCRayN_tfar(args->ray, args->N, i) = -std::numeric_limits<float>::infinity();
    });
  }
}

}  // namespace

int intersect_capsule(const CapsuleChain& chain, uint32_t segment, const glm::dvec3& origin,
                      const glm::dvec3& direction, CapsuleHit hits[4]) {
  const Segment s = segment_of(chain, segment);
  const uint8_t flags = chain.flags[segment];
  const double r = s.radius;
  const glm::dvec3 axis_vector = s.p1 - s.p0;
  const double length = glm::length(axis_vector);
  const glm::dvec3 axis = length > 0 ? axis_vector / length : glm::dvec3(0);
  const auto along = [&](const glm::dvec3& x) { return glm::dot(x - s.p0, axis); };
  int count = 0;
  const auto keep = [&](double t, const glm::dvec3& normal) {
    const glm::dvec3 x = origin + t * direction;
    // Inside a neighbour's capsule: not on the surface of the union.
    const double inside = r * (1 - 1e-6);
    if ((flags & RTC_CURVE_FLAG_NEIGHBOR_LEFT) &&
        distance_to_segment(x, segment_of(chain, segment - 1)) < inside)
      return;
    if ((flags & RTC_CURVE_FLAG_NEIGHBOR_RIGHT) &&
        distance_to_segment(x, segment_of(chain, segment + 1)) < inside)
      return;
    const double u = length > 0 ? std::clamp(along(x) / length, 0.0, 1.0) : 0.0;
    hits[count++] = {t, glm::normalize(normal), u};
  };
  double roots[2];
  // The cylinder between the end planes.
  if (length > 0) {
    const glm::dvec3 w = origin - s.p0;
    const glm::dvec3 d_perp = direction - glm::dot(direction, axis) * axis;
    const glm::dvec3 w_perp = w - glm::dot(w, axis) * axis;
    const int n = solve_quadratic(glm::dot(d_perp, d_perp), 2 * glm::dot(w_perp, d_perp),
                                  glm::dot(w_perp, w_perp) - r * r, roots);
    for (int k = 0; k < n; ++k) {
      const double h = glm::dot(w + roots[k] * direction, axis);
      if (h >= 0 && h <= length) keep(roots[k], w_perp + roots[k] * d_perp);
    }
  }
  // The sphere at the end point, outside the cylinder's slab; the start sphere only on a line's
  // first segment (elsewhere it is the previous segment's end sphere).
  const auto sphere = [&](const glm::dvec3& centre, bool beyond_end) {
    const glm::dvec3 w = origin - centre;
    const int n = solve_quadratic(glm::dot(direction, direction), 2 * glm::dot(w, direction),
                                  glm::dot(w, w) - r * r, roots);
    for (int k = 0; k < n; ++k) {
      const glm::dvec3 x = origin + roots[k] * direction;
      const double h = along(x);
      if (beyond_end ? h > length : h < 0) keep(roots[k], x - centre);
    }
  };
  sphere(s.p1, true);
  if (!(flags & RTC_CURVE_FLAG_NEIGHBOR_LEFT)) sphere(s.p0, false);
  std::sort(hits, hits + count, [](const CapsuleHit& a, const CapsuleHit& b) { return a.t < b.t; });
  return count;
}

void set_capsule_geometry(RTCGeometry geometry, const CapsuleChain* chain, uint32_t segments) {
  rtcSetGeometryUserPrimitiveCount(geometry, segments);
  rtcSetGeometryUserData(geometry, const_cast<CapsuleChain*>(chain));
  rtcSetGeometryBoundsFunction(geometry, &capsule_bounds, nullptr);
  rtcSetGeometryIntersectFunction(geometry, &capsule_intersect);
  rtcSetGeometryOccludedFunction(geometry, &capsule_occluded);
}

}  // namespace linebake
