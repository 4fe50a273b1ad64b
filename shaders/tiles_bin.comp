#version 460
// tiles, pass 1 over capsules: each segment's capsule is projected to the screen, culled, and
// binned (tiles_keys.glsl) with its nearest view depth.
#include "tiles.glsl"
#include "tiles_capsules.glsl"
#include "tiles_keys.glsl"

layout(local_size_x = 256) in;

void main() {
  const uint s = gl_GlobalInvocationID.x;
  if (s >= frame.size.w) return;
  vec2 lo, hi;
  float z_near, z_far;
  if (screen_bounds(s, lo, hi, z_near, z_far)) emit_keys(s, lo, hi, z_near);
}
