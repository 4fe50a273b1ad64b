#version 460
// tiles, pass 1 over capsules: each segment's capsule is projected to the screen, culled, and
// binned (tiles_keys.glsl) with its nearest view depth; a capsule whose bounds hold a few pixel
// centres only where one of those pixels' rays may cross its surface (bin_test_pixels).
#include "tiles.glsl"
#include "tiles_capsules.glsl"
// Before tiles_keys.glsl, which reads gl_WorkGroupSize.
layout(local_size_x = 256) in;
#include "tiles_keys.glsl"

// Capsules whose bounds hold at most kTestedPixels pixel centres (tiles_keys.glsl) are binned
// only where a pixel's ray may have a front crossing on the surface the capsule owns
// (capsule.glsl: the chain's union surface, a joint's sphere the segment's that ends there). A
// key costs the sort and the composite whether or not a pixel hits it, and the bounds of a short
// capsule hold pixels whose rays miss it or meet its neighbours' surface instead.

// What one segment's pixel tests share: the segment, its neighbours' ends (flags & 1: before,
// & 2: after), its axis, the growth of its capsule and the square of the depth inside a
// neighbour's capsule that rules a crossing out (may_own_a_crossing).
struct OwnerTest {
  vec3 p0, p1, before, after, axis;
  uint flags;
  float len, grow, inside2;
  // The neighbours' axes (before to p0, p1 to after) over their squared lengths (0: none).
  vec3 before_axis, after_axis;
};

OwnerTest owner_test_of(uint s) {
  const uint word = segment_at(s), first = word >> 2u;
  OwnerTest o;
  o.p0 = point_at(first).xyz;
  o.p1 = point_at(first + 1u).xyz;
  o.flags = word & 3u;
  o.before = (o.flags & 1u) != 0u ? point_at(first - 1u).xyz : o.p0;
  o.after = (o.flags & 2u) != 0u ? point_at(first + 2u).xyz : o.p1;
  o.len = length(o.p1 - o.p0);
  o.axis = o.len > 0.0 ? (o.p1 - o.p0) / o.len : vec3(0.0);
  const float u = 1.1920929e-7, r = view.params.y;
  const float from_eye = length(o.p0 - view.eye);
  o.grow = 1e-3 * r + 64.0 * u * (from_eye + o.len);
  // More than the composite's tolerance (capsule_in_neighbour: 1e-6 r and 8 float steps of the
  // hit's extent, t and coordinates) and either side's float error in the distances.
  const vec3 magnitude = abs(o.p0);
  const float largest = max(magnitude.x, max(magnitude.y, magnitude.z));
  const float margin = 1e-2 * r + 64.0 * u * (from_eye + o.len + r + largest);
  o.inside2 = r > margin ? (r - margin) * (r - margin) : 0.0;
  const vec3 before = o.p0 - o.before, after = o.after - o.p1;
  o.before_axis = dot(before, before) > 0.0 ? before / dot(before, before) : vec3(0.0);
  o.after_axis = dot(after, after) > 0.0 ? after / dot(after, after) : vec3(0.0);
  return o;
}

// The smaller root of a t^2 + 2 b t + c (the cancellation-free form; +inf: none).
float smaller_root(float a, float b, float c) {
  const float discriminant = b * b - a * c;
  if (discriminant < 0.0) return 1.0 / 0.0;
  const float root = sqrt(discriminant);
  return b >= 0.0 ? -(b + root) / a : c / (root - b);
}

// Where the unit ray from `from_centre` (the origin less the centre) enters the sphere of
// `radius` (+inf: never).
float sphere_entry(vec3 from_centre, vec3 direction, float radius) {
  const float b = dot(from_centre, direction);
  const float discriminant = b * b - (dot(from_centre, from_centre) - radius * radius);
  return discriminant >= 0.0 ? -b - sqrt(discriminant) : 1.0 / 0.0;
}

// The squared distance of x from segment a-b, given (b - a) / |b - a|^2 (the per-pixel tests
// take no division here).
float distance2_to_segment(vec3 x, vec3 a, vec3 b, vec3 axis_over_length2) {
  const float h = clamp(dot(x - a, axis_over_length2), 0.0, 1.0);
  const vec3 miss = x - mix(a, b, h);
  return dot(miss, miss);
}

// Whether the ray from the eye along the unit `direction` may have a front crossing on the
// surface segment o owns, as the composite's first_hit computes it (capsule_front_crossing,
// from the ray's point nearest o.p0). That crossing x enters the capsule, so it lies between
// where the ray enters the capsule grown by o.grow and the ray's point nearest the segment (the
// distance from the segment is convex along the ray), both widened by o.grow for float error;
// the composite keeps x unless it lies inside a neighbour's capsule. The distance from a
// neighbour is convex along the ray too: where both ends of that stretch lie inside the same
// neighbour's capsule by the margin of o.inside2, so does x, and the ray has no crossing on this
// segment's surface.
bool may_own_a_crossing(OwnerTest o, vec3 direction) {
  const float radius = view.params.y + o.grow;
  const vec3 origin = view.eye + dot(o.p0 - view.eye, direction) * direction;
  const vec3 w = origin - o.p0, w1 = origin - o.p1;
  // The capsule's entry: the least of its end spheres' and its cylinder's between the end
  // planes. The spheres' roots in the plain form, without a division: the origin lies near the
  // segment's ends in the bounds of a few pixels, where the plain form loses only float steps of
  // the segment's length.
  float entry = min(sphere_entry(w, direction, radius), sphere_entry(w1, direction, radius));
  if (o.len > 0.0) {
    const vec3 d_perp = direction - dot(direction, o.axis) * o.axis;
    const vec3 w_perp = w - dot(w, o.axis) * o.axis;
    const float a = dot(d_perp, d_perp);
    // Within half a degree of the axis the cylinder's roots lose precision (the composite's
    // too): kept.
    if (a < 1e-4) return true;
    const float root =
        smaller_root(a, dot(w_perp, d_perp), dot(w_perp, w_perp) - radius * radius);
    const float h = dot(w + root * direction, o.axis);
    if (h >= 0.0 && h <= o.len) entry = min(entry, root);
  }
  if (isinf(entry)) return false;
  // The ray's point nearest the segment: the segment's point nearest the ray's line, then along
  // the ray.
  const vec3 e = o.p1 - o.p0;
  vec3 miss;
  const float h = nearest_on_segment(-w, e, direction, miss);
  const float nearest = dot(h * e - w, direction);
  const vec3 x0 = origin + (entry - o.grow) * direction;
  const vec3 x1 = origin + (nearest + o.grow) * direction;
  if ((o.flags & 1u) != 0u &&
      distance2_to_segment(x0, o.before, o.p0, o.before_axis) < o.inside2 &&
      distance2_to_segment(x1, o.before, o.p0, o.before_axis) < o.inside2)
    return false;
  if ((o.flags & 2u) != 0u && distance2_to_segment(x0, o.p1, o.after, o.after_axis) < o.inside2 &&
      distance2_to_segment(x1, o.p1, o.after, o.after_axis) < o.inside2)
    return false;
  return true;
}

// Whether the line of the ray from the eye along the unit `direction` passes within the grown
// radius of segment o and o.grow more: a ray that does not cannot enter the grown capsule
// (may_own_a_crossing).
bool ray_passes_near(OwnerTest o, vec3 direction) {
  vec3 miss;
  nearest_on_segment(o.p0 - view.eye, o.p1 - o.p0, direction, miss);
  const float reach = view.params.y + 2.0 * o.grow;
  return dot(miss, miss) <= reach * reach;
}

// Whether the ray of a pixel whose centre lies in segment s's bounds [lo, hi] may have a
// crossing on its surface (true for bounds of more pixels than binning.x, untested). First the
// cheap test of every pixel, then the full one of those that pass it, in a loop that ends at the
// first that may cross: on lavapipe a SIMD unit runs both sides of every branch, and leaves only
// loops early, once all its lanes are done.
bool bin_test_pixels(uint s, vec2 lo, vec2 hi) {
  ivec2 p0, extent;
  const int pixels = tested_pixels(lo, hi, p0, extent);
  if (pixels < 0) return true;
  const OwnerTest o = owner_test_of(s);
  uint near = 0u;
  for (int k = 0; k < kTestedPixels; ++k) {
    if (k >= pixels) break;
    if (ray_passes_near(o, ray_direction(tested_pixel(p0, extent, k)))) near |= 1u << k;
  }
  bool crossing = false;
  for (uint left = near; left != 0u && !crossing; left &= left - 1u)
    crossing = may_own_a_crossing(o, ray_direction(tested_pixel(p0, extent, findLSB(left))));
  return crossing;
}

void main() {
  load_frame_view();
  const uint s = flat_workgroup() * gl_WorkGroupSize.x + gl_LocalInvocationID.x;
  vec2 lo = vec2(0.0), hi = vec2(-1.0);
  float z_near = 0.0, z_far = 0.0;
  // Every invocation takes part in emit_keys (it counts per workgroup).
  bool visible = s < view.size.w && screen_bounds(s, lo, hi, z_near, z_far);
  if (visible) visible = bin_test_pixels(s, lo, hi);
  emit_keys(s, visible, lo, hi, z_near);
}
