// The capsule primitives of `tiles` (the default geometry): the lines' points and segments.

// x, y, z and the attribute value per point.
layout(set = 0, binding = 1, std430) readonly buffer Points { vec4 points[]; };
// Per segment: its first point << 2 | neighbour flags (accel/capsule_segments.hpp).
layout(set = 0, binding = 2, std430) readonly buffer Segments { uint segments[]; };

// Segment s's capsule on the screen: its pixel bounds [lo, hi] and nearest and farthest view
// depth; false when it lies behind the eye. Binning bins these bounds; the composite tests only
// the pixels inside them, so both must use this one function.
bool screen_bounds(uint s, out vec2 lo, out vec2 hi, out float z_near, out float z_far) {
  const uint first = segments[s] >> 2u;
  vec3 a = points[first].xyz, b = points[first + 1u].xyz;
  const float r = frame.params.y;
  const vec3 f = frame.forward.xyz;
  float za = dot(a - frame.eye.xyz, f), zb = dot(b - frame.eye.xyz, f);
  z_far = max(za, zb) + r;
  // Behind the eye: culled; crossing the plane just in front of it: clipped there (pushed back
  // by the radius, so the end spheres stay in front too).
  const float near = near_clip();
  if (max(za, zb) + r <= near) return false;
  const float clip = near + r;
  if (za < clip || zb < clip) {
    if (max(za, zb) < clip) {
      // Wholly within a radius of the eye: it may cover the whole screen.
      a = frame.eye.xyz + clip * f + (a - frame.eye.xyz - za * f);
      b = frame.eye.xyz + clip * f + (b - frame.eye.xyz - zb * f);
      za = zb = clip;
    } else {
      const vec3 from = za < clip ? b : a, to = za < clip ? a : b;
      const float zf = za < clip ? zb : za, zt = za < clip ? za : zb;
      const vec3 cut = from + (to - from) * ((zf - clip) / (zf - zt));
      if (za < clip) a = cut, za = clip;
      else b = cut, zb = clip;
    }
  }
  const vec3 pa = project(a), pb = project(b);
  // A sphere of radius r at depth z lies within r / (z - r) of its centre's direction in the
  // image plane at distance 1 (conservative also off axis with the factor for the corner).
  const float focal = 0.5 * float(frame.size.y) / length(frame.up.xyz);
  const float corner = sqrt(1.0 + dot(frame.right.xyz, frame.right.xyz) + dot(frame.up.xyz, frame.up.xyz));
  const float ra = r / max(za - r, near) * focal * corner + 1.0;
  const float rb = r / max(zb - r, near) * focal * corner + 1.0;
  lo = min(pa.xy - ra, pb.xy - rb);
  hi = max(pa.xy + ra, pb.xy + rb);
  z_near = min(za, zb) - r;
  return true;
}
