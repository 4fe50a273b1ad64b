#version 460
#ifdef TILES_WIDE_WORDS
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#endif
// tiles, pass 3 over capsules (tiles_composite.glsl): each pixel's ray against the capsule chain
// (capsule.glsl: the chain's union surface, front crossings only, as Embree's capsules and rtx
// capsules).
#include "tiles.glsl"
#include "tiles_capsules.glsl"
#include "shading.glsl"
#define CAPSULE_COORDINATE_ERROR 1.0  // doubtful crossings kept; seam doubles dropped
#include "capsule.glsl"

const uint kBatch = 256, kSlots = 256;
#ifdef TILES_WIDE_WORDS
// The segment's ends in 64-bit words, two floats each (p0.xy, p0.z and the key's depth bound,
// p1.xy, p1.z and the farthest view depth): the near test reads them in one shared load. On
// lavapipe each such load is a loop over the 8 lanes of a SIMD unit, with a step per component
// (docs/tiles.md, "Per-lane shared loads on lavapipe"); one load of four 64-bit words ran 3.6 %
// fewer of the paper-small convection frame's JIT instructions than two of four floats.
shared u64vec4 batch_ends[kBatch];
#else
shared vec4 batch_p0[kBatch];      // xyz, the key's depth bound
shared vec4 batch_p1[kBatch];      // xyz, the farthest view depth
#endif
shared vec4 batch_before[kBatch];  // xyz, flags
shared vec3 batch_after[kBatch];
#ifndef TILES_LATE_SHADING
shared vec2 batch_values[kBatch];  // the attribute at p0 and p1 (late shading reads them again)
#endif

// Segment s's capsule and the attribute at its ends, read from the primitive buffers.
CapsuleSegment stored_segment(uint s, out vec2 values) {
  const uint word = segment_at(s);
  const uint p = word >> 2u, flags = word & 3u;
  const vec4 p0 = point_at(p), p1 = point_at(p + 1u);
  CapsuleSegment c;
  c.p0 = p0.xyz;
  c.p1 = p1.xyz;
  c.before = (flags & 1u) != 0u ? point_at(p - 1u).xyz : p0.xyz;
  c.after = (flags & 2u) != 0u ? point_at(p + 2u).xyz : p1.xyz;
  c.flags = flags;
  c.radius = view.params.y;
  values = vec2(p0.w, p1.w);
  return c;
}

void load_primitive(uint lane, uint s, float bound, float far) {
  vec2 values;
  const CapsuleSegment c = stored_segment(s, values);
#ifdef TILES_WIDE_WORDS
  batch_ends[lane] = u64vec4(packUint2x32(floatBitsToUint(c.p0.xy)),
                             packUint2x32(floatBitsToUint(vec2(c.p0.z, bound))),
                             packUint2x32(floatBitsToUint(c.p1.xy)),
                             packUint2x32(floatBitsToUint(vec2(c.p1.z, far))));
#else
  batch_p0[lane] = vec4(c.p0, bound);
  batch_p1[lane] = vec4(c.p1, far);
#endif
#ifndef TILES_LATE_SHADING
  batch_values[lane] = values;
#endif
  batch_before[lane] = vec4(c.before, float(c.flags));
  batch_after[lane] = c.after;
}

// What may_cross reads of batch entry i, and the depth bound.
const int kNearWords = 2;
void near_words(uint i, out vec4 words[kNearWords]) {
#ifdef TILES_WIDE_WORDS
  const u64vec4 ends = batch_ends[i];
  words[0] = uintBitsToFloat(uvec4(unpackUint2x32(ends.x), unpackUint2x32(ends.y)));
  words[1] = uintBitsToFloat(uvec4(unpackUint2x32(ends.z), unpackUint2x32(ends.w)));
}
float depth_bound(uint i) { return uintBitsToFloat(unpackUint2x32(batch_ends[i].y).y); }
#else
  words[0] = batch_p0[i];
  words[1] = batch_p1[i];
}
float depth_bound(uint i) { return batch_p0[i].w; }
#endif

// Whether the pixel's ray may cross the capsule of a batch entry, given its near words: the
// line of the ray passes within the radius of the segment (every crossing capsule.glsl reports
// lies on the segment's own capsule), with a 64th of a radius and the float error of the far
// eye to spare. A cheap test before the exact one: only the entries that pass it become pairs.
// With an eighth of a radius to spare, 18 % of the pairs of paper-small's convection frame 1 at
// 640x360 lay in that margin, none with a hit; a 64th gives 15 % fewer pairs and rounds and the
// same bytes (13 frames of the four sets and three transfer functions, docs/tiles.md).
// (Computing the reach here costs less on lavapipe than a third shared load of it:
// docs/tiles.md, "Per-lane shared loads on lavapipe".)
bool may_cross(vec4 words[kNearWords], vec3 direction) {
  const vec3 w = words[0].xyz - view.eye, e = words[1].xyz - words[0].xyz;
  vec3 miss;
  nearest_on_segment(w, e, direction, miss);
  const float slack = 0.015625 * view.params.y + 64.0 * 1.1920929e-7 * (length(w) + length(e));
  const float reach = view.params.y + slack;
  return dot(miss, miss) <= reach * reach;
}

// The nearest front crossing of the ray with capsule chain surface c: its t along the ray, the
// surface normal there and where along the segment it lies (0 to 1). A capsule is convex, so a
// ray enters it once; capsule_front_crossing can report a front crossing on both sides of a
// joint only as the float double of one, and that double is not composited again (seam_of).
bool capsule_hit(CapsuleSegment c, vec3 direction, out float t_hit, out vec3 normal,
                 out float along) {
  // From the ray's point nearest the segment's start: in float32 the quadratics lose the radius
  // against the squared distance from a far eye.
  const float t0 = dot(c.p0 - view.eye, direction);
  float t;
  t_hit = 0.0;
  if (!capsule_front_crossing(c, view.eye + t0 * direction, direction, t0, t, normal, along))
    return false;
  t_hit = t + t0;
  return true;
}

// The shaded colour of a capsule_hit, `values` the attribute at the segment's ends.
vec4 capsule_colour(vec3 direction, float t_hit, vec3 normal, float along, vec2 values) {
  const vec4 base = transfer_function(values.x + along * (values.y - values.x));
  return vec4(shade(view.eye + t_hit * direction, normal, base.rgb), base.a);
}

// Batch entry i's hit, shaded unless the window shades late.
bool first_hit(uint i, vec3 direction, out float t_hit, out vec4 colour) {
  CapsuleSegment c;
  vec4 words[kNearWords];
  near_words(i, words);
  c.p0 = words[0].xyz;
  c.p1 = words[1].xyz;
  c.before = batch_before[i].xyz;
  c.after = batch_after[i];
  c.flags = uint(batch_before[i].w);
  c.radius = view.params.y;
  vec3 normal;
  float along;
  colour = vec4(0.0);
  if (!capsule_hit(c, direction, t_hit, normal, along)) return false;
#ifndef TILES_LATE_SHADING
  colour = capsule_colour(direction, t_hit, normal, along, batch_values[i]);
#endif
  return true;
}

// The colour of a pending hit at t on segment s, composited late: the same test on the same
// floats, read again from the primitive buffers, gives the same hit (TILES_LATE_SHADING,
// tiles_composite.glsl). Should a compiler compute the test otherwise here (no test is marked
// precise), false and the colour of the segment's start facing the ray: counted, not lost.
bool hit_colour(uint s, float t, vec3 direction, out vec4 colour) {
  vec2 values;
  const CapsuleSegment c = stored_segment(s, values);
  float t_hit, along;
  vec3 normal;
  const bool found = capsule_hit(c, direction, t_hit, normal, along);
  if (!found) t_hit = t, normal = -direction, along = 0.0;
  colour = capsule_colour(direction, t_hit, normal, along, values);
  return found;
}

// Two reports of one joint differ by the float error of the crossings (capsule.glsl), measured
// from the ray's point nearest the segment's start (first_hit).
float seam_of(uint i, vec3 direction) {
  vec4 words[kNearWords];
  near_words(i, words);
  const float t0 = dot(words[0].xyz - view.eye, direction);
  return 1e-3 * view.params.y + 32.0 * 1.1920929e-7 * (abs(t0) + length(words[0].xyz));
}

#include "tiles_composite.glsl"
