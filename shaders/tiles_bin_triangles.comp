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
  vec2 lo, hi;
  float z_near, z_far;
  if (screen_bounds(s, lo, hi, z_near, z_far)) emit_keys(s, lo, hi, z_near);
}
