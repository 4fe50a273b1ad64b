#version 460
// tiles, pass 3 over capsules (tiles_composite.glsl): each pixel's ray against the capsule chain
// (capsule.glsl: the chain's union surface, front crossings only, as Embree's capsules and rtx
// capsules).
#include "tiles.glsl"
#include "tiles_capsules.glsl"
#include "shading.glsl"
#define CAPSULE_COORDINATE_ERROR 1.0  // doubtful crossings kept; seam doubles dropped
#include "capsule.glsl"

const uint kBatch = 256, kSlots = 256;
shared vec4 batch_p0[kBatch];      // xyz, attribute
shared vec4 batch_p1[kBatch];      // xyz, attribute
shared vec4 batch_before[kBatch];  // xyz, flags
shared vec3 batch_after[kBatch];

void load_primitive(uint lane, uint s) {
  const uint word = segments[s];
  const uint p = word >> 2u, flags = word & 3u;
  batch_p0[lane] = points[p];
  batch_p1[lane] = points[p + 1u];
  batch_before[lane] = vec4((flags & 1u) != 0u ? points[p - 1u].xyz : points[p].xyz, float(flags));
  batch_after[lane] = (flags & 2u) != 0u ? points[p + 2u].xyz : points[p + 1u].xyz;
}

// Whether the pixel's ray may cross batch entry i's capsule: the line of the ray passes within
// the radius of the segment (every crossing capsule.glsl reports lies on the segment's own
// capsule), with half a radius and the float error of the far eye to spare. A cheap test
// before the exact one: only the entries that pass it become pairs.
bool may_cross(uint i, vec3 direction) {
  const vec3 w = batch_p0[i].xyz - frame.eye.xyz, e = batch_p1[i].xyz - batch_p0[i].xyz;
  // The parts of w and e across the ray: the segment seen along the ray.
  const vec3 across = w - dot(w, direction) * direction;
  const vec3 slope = e - dot(e, direction) * direction;
  const float slope2 = dot(slope, slope);
  const float h = slope2 > 0.0 ? clamp(-dot(across, slope) / slope2, 0.0, 1.0) : 0.0;
  const float slack = 0.125 * frame.params.y + 64.0 * 1.1920929e-7 * (length(w) + length(e));
  return length(across + h * slope) <= frame.params.y + slack;
}

// The nearest front crossing of the ray with batch entry i's capsule chain surface, shaded. A
// capsule is convex, so a ray enters it once; capsule_crossings can report a second front
// crossing only as the float double of the first, at the rim between the cylinder and an end
// sphere, and that double is not composited again.
bool first_hit(uint i, vec3 direction, out float t_hit, out vec4 colour) {
  CapsuleSegment c;
  c.p0 = batch_p0[i].xyz;
  c.p1 = batch_p1[i].xyz;
  c.before = batch_before[i].xyz;
  c.after = batch_after[i];
  c.flags = uint(batch_before[i].w);
  c.radius = frame.params.y;
  float t[4], u[4];
  vec3 n[4];
  // From the ray's point nearest the segment's start: in float32 the quadratics lose the radius
  // against the squared distance from a far eye.
  const float t0 = dot(c.p0 - frame.eye.xyz, direction);
  const int crossings =
      capsule_crossings(c, frame.eye.xyz + t0 * direction, direction, true, t, n, u);
  bool found = false;
  vec3 normal = vec3(0.0);
  float along = 0.0;
  t_hit = 0.0;
  colour = vec4(0.0);
  for (int k = 0; k < 4; ++k) {
    if (found || k >= crossings || t[k] + t0 <= 0.0 || dot(n[k], direction) >= 0.0) continue;
    found = true;  // a front crossing ahead
    t_hit = t[k] + t0, normal = n[k], along = u[k];
  }
  if (!found) return false;
  const vec4 base = transfer_function(batch_p0[i].w + along * (batch_p1[i].w - batch_p0[i].w));
  colour = vec4(shade(frame.eye.xyz + t_hit * direction, normal, base.rgb), base.a);
  return true;
}

// Two reports of one joint differ by the float error of the crossings (capsule.glsl), measured
// from the ray's point nearest the segment's start (first_hit).
float seam_of(uint i, vec3 direction) {
  const float t0 = dot(batch_p0[i].xyz - frame.eye.xyz, direction);
  return 1e-3 * frame.params.y + 32.0 * 1.1920929e-7 * (abs(t0) + length(batch_p0[i].xyz));
}

#include "tiles_composite.glsl"
