#version 460
// tiles, pass 1 over the tube mesh's triangles: each triangle's screen bounds binned
// (tiles_keys.glsl) with its nearest vertex depth. Back faces are culled here already.
#include "tiles.glsl"
#include "tiles_triangles.glsl"
#include "tiles_keys.glsl"

layout(local_size_x = 256) in;

void main() {
  const uint s = gl_GlobalInvocationID.x;
  if (s >= frame.size.w) return;
  const vec3 a = vertices[2u * indices[3u * s]].xyz, b = vertices[2u * indices[3u * s + 1u]].xyz,
             c = vertices[2u * indices[3u * s + 2u]].xyz;
  // Every ray from the eye meets a plane from one side: a triangle facing away has no front hit.
  if (dot(cross(b - a, c - a), a - frame.eye.xyz) >= 0.0) return;
  const vec3 f = frame.forward.xyz;
  const float za = dot(a - frame.eye.xyz, f), zb = dot(b - frame.eye.xyz, f),
              zc = dot(c - frame.eye.xyz, f);
  const float near = near_clip();
  if (max(za, max(zb, zc)) <= near) return;
  vec2 lo, hi;
  if (min(za, min(zb, zc)) <= near) {
    // Crossing the plane at the eye: its projection is unbounded, so every tile.
    lo = vec2(0.0);
    hi = vec2(frame.size.xy);
  } else {
    const vec3 pa = project(a), pb = project(b), pc = project(c);
    lo = min(pa.xy, min(pb.xy, pc.xy)) - 1.0;
    hi = max(pa.xy, max(pb.xy, pc.xy)) + 1.0;
  }
  emit_keys(s, lo, hi, min(za, min(zb, zc)));
}
