#version 460
// Test harness for capsule.glsl on any Vulkan device (lavapipe included): one invocation per
// (segment, ray) case, writing every crossing, and the nearest front crossing ahead of the
// origin, so the CPU test can compare with intersect_capsule(). Not used for rendering.

layout(local_size_x = 64) in;

#include "capsule.glsl"

struct Case {
  vec4 before, p0, p1, after;  // xyz; p0.w = radius, p1.w = flags
  vec4 origin, direction;      // xyz
};
struct Crossings {
  vec4 t;                 // up to four
  vec4 u;
  vec4 normal[4];         // xyz
  uvec4 count;            // x
  vec4 front;             // capsule_front_crossing from the origin: t, u, found (1) or not (0)
  vec4 front_normal;      // xyz
};

layout(set = 0, binding = 0, std140) uniform Params { uvec4 case_count; } params;
layout(set = 0, binding = 1, std430) readonly buffer Cases { Case cases[]; };
layout(set = 0, binding = 2, std430) writeonly buffer Results { Crossings results[]; };

void main() {
  const uint i = gl_GlobalInvocationID.x;
  if (i >= params.case_count.x) return;
  const Case c = cases[i];
  CapsuleSegment s;
  s.before = c.before.xyz;
  s.p0 = c.p0.xyz;
  s.p1 = c.p1.xyz;
  s.after = c.after.xyz;
  s.radius = c.p0.w;
  s.flags = uint(c.p1.w);
  float t[4], u[4];
  vec3 n[4];
  const int count = capsule_crossings(s, c.origin.xyz, c.direction.xyz, t, n, u);
  Crossings r;
  r.t = vec4(t[0], t[1], t[2], t[3]);
  r.u = vec4(u[0], u[1], u[2], u[3]);
  for (int k = 0; k < 4; ++k) r.normal[k] = vec4(n[k], 0.0);
  r.count = uvec4(uint(count), 0u, 0u, 0u);
  float front_t, front_u;
  vec3 front_n;
  const bool found =
      capsule_front_crossing(s, c.origin.xyz, c.direction.xyz, 0.0, front_t, front_n, front_u);
  r.front = vec4(front_t, front_u, found ? 1.0 : 0.0, 0.0);
  r.front_normal = vec4(front_n, 0.0);
  results[i] = r;
}
