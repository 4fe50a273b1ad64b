#pragma once
// Generalized tubes as an Embree user geometry: each line is a chain of capsules (a cylinder per
// segment, a sphere at every point), the paper's analytic tube primitive. The chain's surface is
// the surface of the union: a primitive reports the part of its capsule that lies outside its
// neighbours (a joint sphere belongs to the segment it ends), so a ray crosses each tube wall
// once, like round linear curves with neighbour flags and like rasterised tubes.
//
// One radius per segment (the first point's): linebake tubes have a constant radius, and the
// varying-radius case (cone frustums between spheres) is not built.

#include <embree3/rtcore.h>

#include <cstdint>
#include <glm/glm.hpp>

namespace linebake {

// The chain's buffers, laid out like round linear curves: FLOAT4 (x, y, z, r) vertices, the first
// vertex of each segment, RTC_CURVE_FLAG_NEIGHBOR_LEFT / _RIGHT per segment.
struct CapsuleChain {
  const float* vertices = nullptr;
  const uint32_t* indices = nullptr;
  const uint8_t* flags = nullptr;
};

struct CapsuleHit {
  double t = 0;
  glm::dvec3 normal{0};  // unit, outward
  double u = 0;          // position along the segment, 0..1
};

// Where the ray origin + t direction (unit direction) crosses the chain surface that `segment`
// owns, nearest first: at most four crossings (cylinder and end sphere, in and out).
int intersect_capsule(const CapsuleChain& chain, uint32_t segment, const glm::dvec3& origin,
                      const glm::dvec3& direction, CapsuleHit hits[4]);

// Makes `geometry` (RTC_GEOMETRY_TYPE_USER) a capsule chain of `segments` primitives over
// `chain`, which must outlive it. Hits go through the intersection filters in distance order.
void set_capsule_geometry(RTCGeometry geometry, const CapsuleChain* chain, uint32_t segments);

}  // namespace linebake
