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
shared vec4 batch_p0[kBatch];      // xyz, the key's depth bound
shared vec4 batch_p1[kBatch];      // xyz, the farthest view depth
shared vec4 batch_before[kBatch];  // xyz, flags
shared vec3 batch_after[kBatch];
shared vec2 batch_values[kBatch];  // the attribute at p0 and p1

void load_primitive(uint lane, uint s, float bound, float far) {
  const uint word = segments[s];
  const uint p = word >> 2u, flags = word & 3u;
  const vec4 p0 = points[p], p1 = points[p + 1u];
  batch_p0[lane] = vec4(p0.xyz, bound);
  batch_p1[lane] = vec4(p1.xyz, far);
  batch_values[lane] = vec2(p0.w, p1.w);
  batch_before[lane] = vec4((flags & 1u) != 0u ? points[p - 1u].xyz : p0.xyz, float(flags));
  batch_after[lane] = (flags & 2u) != 0u ? points[p + 2u].xyz : p1.xyz;
}

// What may_cross reads of batch entry i, and the depth bound.
const int kNearWords = 2;
void near_words(uint i, out vec4 words[kNearWords]) {
  words[0] = batch_p0[i];
  words[1] = batch_p1[i];
}
float depth_bound(uint i) { return batch_p0[i].w; }

// Whether the pixel's ray may cross the capsule of a batch entry, given its near words: the
// line of the ray passes within the radius of the segment (every crossing capsule.glsl reports
// lies on the segment's own capsule), with an eighth of a radius and the float error of the far
// eye to spare. A cheap test before the exact one: only the entries that pass it become pairs.
// (Computing the reach here costs less on lavapipe than a third shared load of it: README,
// "Per-lane shared loads on lavapipe".)
bool may_cross(vec4 words[kNearWords], vec3 direction) {
  const vec3 w = words[0].xyz - frame.eye.xyz, e = words[1].xyz - words[0].xyz;
  // The parts of w and e across the ray: the segment seen along the ray.
  const vec3 across = w - dot(w, direction) * direction;
  const vec3 slope = e - dot(e, direction) * direction;
  const float slope2 = dot(slope, slope);
  const float h = slope2 > 0.0 ? clamp(-dot(across, slope) / slope2, 0.0, 1.0) : 0.0;
  const vec3 miss = across + h * slope;
  const float slack = 0.125 * frame.params.y + 64.0 * 1.1920929e-7 * (length(w) + length(e));
  const float reach = frame.params.y + slack;
  return dot(miss, miss) <= reach * reach;
}

// The nearest front crossing of the ray with batch entry i's capsule chain surface, shaded. A
// capsule is convex, so a ray enters it once; capsule_front_crossing can report a front crossing
// on both sides of a joint only as the float double of one, and that double is not composited
// again (seam_of).
bool first_hit(uint i, vec3 direction, out float t_hit, out vec4 colour) {
  CapsuleSegment c;
  c.p0 = batch_p0[i].xyz;
  c.p1 = batch_p1[i].xyz;
  c.before = batch_before[i].xyz;
  c.after = batch_after[i];
  c.flags = uint(batch_before[i].w);
  c.radius = frame.params.y;
  // From the ray's point nearest the segment's start: in float32 the quadratics lose the radius
  // against the squared distance from a far eye.
  const float t0 = dot(c.p0 - frame.eye.xyz, direction);
  float t;
  vec3 normal;
  float along;
  t_hit = 0.0;
  colour = vec4(0.0);
  if (!capsule_front_crossing(c, frame.eye.xyz + t0 * direction, direction, t0, t, normal, along))
    return false;
  t_hit = t + t0;
  const vec2 ends = batch_values[i];
  const vec4 base = transfer_function(ends.x + along * (ends.y - ends.x));
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
