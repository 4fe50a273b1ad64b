// The capsule primitives of `tiles` (the default geometry): the lines' points and segments.

#include "tiles_pages.glsl"

// x, y, z and the attribute value of point i.
vec4 point_at(uint i) { return unit_at(i); }
// Segment s's word: its first point << 2 | neighbour flags (accel/capsule_segments.hpp).
uint segment_at(uint s) { return word_at(s); }

// The slopes x / z of the two planes through the eye that touch the sphere of radius r whose
// centre lies at (x, z) in the view's x-z plane (z > r): solutions of m^2 (z^2 - r^2) - 2 m x z +
// x^2 - r^2 = 0, the line x = m z at distance r from the centre. Exact extremes of x / z over
// the sphere; the same with y for the other axis.
vec2 tangent_slopes(float x, float z, float r) {
  const float root = r * sqrt(max(x * x + z * z - r * r, 0.0));
  return vec2(x * z - root, x * z + root) / (z * z - r * r);
}

// Segment s's capsule on the screen: its pixel bounds [lo, hi] and nearest and farthest view
// depth; false when it lies behind the eye. Binning bins these bounds; the composite tests only
// the pixels inside them, so both must use this one function.
//
// The bounds are those of the capsule of radius r' = 1.25 r + 128 float steps of the distances,
// twice the slack of may_cross (tiles_composite.comp), so that they hold every pixel whose ray
// passes that test, and a sixteenth of a pixel for the float error of the bound itself: the exact
// projection of its two end spheres (tangent_slopes), whose convex hull the capsule is. The
// image is then the same to the byte as with any wider bounds, and a capsule between pixel
// centres covers no pixel (covered_pixels, tiles.glsl). A capsule that comes within 2 r' of the
// plane of the eye takes the older, looser bound below.
bool screen_bounds(uint s, out vec2 lo, out vec2 hi, out float z_near, out float z_far) {
  const uint first = segment_at(s) >> 2u;
  const vec3 a = point_at(first).xyz, b = point_at(first + 1u).xyz;
  const float r = view.params.y;
  const vec3 f = view.forward;
  float za = dot(a - view.eye, f), zb = dot(b - view.eye, f);
  z_far = max(za, zb) + r;
  z_near = min(za, zb) - r;
  const vec3 qa = a - view.eye, qb = b - view.eye;
  const float wide = 1.25 * r + 128.0 * 1.1920929e-7 * (length(qa) + length(b - a));
  if (min(za, zb) > 2.0 * wide + near_clip()) {
    const vec3 right = view.right, up = view.up;
    const float right_length = length(right), up_length = length(up);
    const vec2 xa = tangent_slopes(dot(qa, right) / right_length, za, wide);
    const vec2 xb = tangent_slopes(dot(qb, right) / right_length, zb, wide);
    const vec2 ya = tangent_slopes(dot(qa, up) / up_length, za, wide);
    const vec2 yb = tangent_slopes(dot(qb, up) / up_length, zb, wide);
    // Slopes to pixels as project() maps them (y grows downwards).
    const vec2 x = (vec2(min(xa.x, xb.x), max(xa.y, xb.y)) / right_length + 1.0) * 0.5 *
                   float(view.size.x);
    const vec2 y = (-vec2(max(ya.y, yb.y), min(ya.x, yb.x)) / up_length + 1.0) * 0.5 *
                   float(view.size.y);
    lo = vec2(x.x, y.x) - 0.0625;
    hi = vec2(x.y, y.y) + 0.0625;
    return true;
  }
  // Near the plane of the eye: first the part of the segment within reach of the view's pyramid
  // (pyramid_distances). A ray's point within `wide` of the capsule's axis is inside the
  // pyramid, so the axis point it is near lies within `wide` of it: the rest of the segment has
  // no hit. Without this, a capsule crossing the eye's plane far off to the side took the bounds
  // of the whole screen below (a fly-through of clouds at 1920x1080: 65.8 million keys).
  // In offsets from the eye, as the rest of this path, so that no rounding of world coordinates
  // far from the origin moves the ends by more than `wide` allows.
  const float reach = 2.0 * wide;
  const vec4 da = pyramid_distances(qa), db = pyramid_distances(qb);
  float t0 = 0.0, t1 = 1.0;
  for (int k = 0; k < 4; ++k) {
    if (da[k] > reach && db[k] > reach) return false;
    const float at = (da[k] - reach) / (da[k] - db[k]);
    if (da[k] > reach) t0 = max(t0, at);
    if (db[k] > reach) t1 = min(t1, at);
  }
  if (t0 > t1) return false;
  vec3 ua = qa + t0 * (qb - qa), ub = qa + t1 * (qb - qa);
  za = dot(ua, f), zb = dot(ub, f);
  // Behind the eye: culled; crossing the plane just in front of it: clipped there (pushed back
  // by the radius, so the end spheres stay in front too).
  const float near = near_clip();
  if (max(za, zb) + r <= near) return false;
  const float clip = near + r;
  if (za < clip || zb < clip) {
    if (max(za, zb) < clip) {
      // Wholly within a radius of the eye: it may cover the whole screen.
      ua = clip * f + (ua - za * f);
      ub = clip * f + (ub - zb * f);
      za = zb = clip;
    } else {
      const vec3 from = za < clip ? ub : ua, to = za < clip ? ua : ub;
      const float zf = za < clip ? zb : za, zt = za < clip ? za : zb;
      const vec3 cut = from + (to - from) * ((zf - clip) / (zf - zt));
      if (za < clip) ua = cut, za = clip;
      else ub = cut, zb = clip;
    }
  }
  const vec3 pa = project_offset(ua), pb = project_offset(ub);
  // A sphere of radius r at depth z lies within r / (z - r) of its centre's direction in the
  // image plane at distance 1 (conservative also off axis with the factor for the corner).
  const float focal = 0.5 * float(view.size.y) / length(view.up);
  const float corner = sqrt(1.0 + dot(view.right, view.right) + dot(view.up, view.up));
  const float ra = r / max(za - r, near) * focal * corner + 1.0;
  const float rb = r / max(zb - r, near) * focal * corner + 1.0;
  lo = min(pa.xy - ra, pb.xy - rb);
  hi = max(pa.xy + ra, pb.xy + rb);
  z_near = min(za, zb) - r;
  return true;
}

// The place h in [0, 1] on the segment p0 + h e that comes nearest the line of the unit ray
// `direction`, given w = p0 less a point of that line, and `miss`, that nearest approach seen
// along the ray. The composite's near test (may_cross) and binning's pixel tests
// (tiles_bin.comp) share it.
float nearest_on_segment(vec3 w, vec3 e, vec3 direction, out vec3 miss) {
  // The parts of w and e across the ray: the segment seen along the ray.
  const vec3 across = w - dot(w, direction) * direction;
  const vec3 slope = e - dot(e, direction) * direction;
  const float slope2 = dot(slope, slope);
  const float h = slope2 > 0.0 ? clamp(-dot(across, slope) / slope2, 0.0, 1.0) : 0.0;
  miss = across + h * slope;
  return h;
}
