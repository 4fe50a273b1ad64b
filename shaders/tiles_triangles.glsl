// The triangle primitives of `tiles --tiles-geometry triangles`: the cached tube mesh.

#include "tiles_pages.glsl"

// Vertex v: x, y, z and the attribute value; its normal (x, y, z, 0).
vec4 vertex_at(uint v) { return unit_at(2u * v); }
vec4 normal_at(uint v) { return unit_at(2u * v + 1u); }
// Index k: three per triangle, counter-clockwise seen from outside.
uint index_at(uint k) { return word_at(k); }

// Triangle s's corners, counter-clockwise seen from outside.
void triangle_corners(uint s, out vec3 a, out vec3 b, out vec3 c) {
  a = vertex_at(index_at(3u * s)).xyz;
  b = vertex_at(index_at(3u * s + 1u)).xyz;
  c = vertex_at(index_at(3u * s + 2u)).xyz;
}

// Triangle s on the screen: its pixel bounds [lo, hi] and nearest and farthest vertex depth;
// false when it faces away or lies behind the eye. Binning bins these bounds; the composite
// tests only the pixels inside them, so both must use this one function.
bool screen_bounds(uint s, out vec2 lo, out vec2 hi, out float z_near, out float z_far) {
  vec3 a, b, c;
  triangle_corners(s, a, b, c);
  // Every ray from the eye meets a plane from one side: a triangle facing away has no front hit.
  if (dot(cross(b - a, c - a), a - view.eye) >= 0.0) return false;
  const vec3 f = view.forward;
  const float za = dot(a - view.eye, f), zb = dot(b - view.eye, f),
              zc = dot(c - view.eye, f);
  z_far = max(za, max(zb, zc));
  const float near = near_clip();
  if (max(za, max(zb, zc)) <= near) return false;
  if (min(za, min(zb, zc)) <= near) {
    // Crossing the plane at the eye: its projection is unbounded, so every tile, unless it lies
    // wholly outside a side of the view's pyramid (pyramid_distances), where no pixel's ray goes
    // (by more than float error: 64 steps of the corners' distances). A fly-through of clouds
    // had binned triangles beside the eye in every tile.
    const vec4 da = pyramid_distances(a - view.eye), db = pyramid_distances(b - view.eye),
               dc = pyramid_distances(c - view.eye);
    const float margin =
        64.0 * 1.1920929e-7 *
        (length(a - view.eye) + length(b - view.eye) + length(c - view.eye));
    if (any(greaterThan(min(da, min(db, dc)), vec4(margin)))) return false;
    lo = vec2(0.0);
    hi = vec2(view.size.xy);
  } else {
    // A sixteenth of a pixel for the float error of the projection and of the composite's
    // ray-triangle test: a pixel whose centre lies outside has no hit (covered_pixels).
    const vec3 pa = project(a), pb = project(b), pc = project(c);
    lo = min(pa.xy, min(pb.xy, pc.xy)) - 0.0625;
    hi = max(pa.xy, max(pb.xy, pc.xy)) + 0.0625;
  }
  z_near = min(za, min(zb, zc));
  return true;
}
