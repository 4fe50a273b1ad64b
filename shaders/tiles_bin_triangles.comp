#version 460
// tiles, pass 1 over the tube mesh's triangles: each triangle's screen bounds binned
// (tiles_keys.glsl) with its nearest vertex depth. Back faces are culled here already.
#include "tiles.glsl"
#include "tiles_triangles.glsl"
// Before tiles_keys.glsl, which reads gl_WorkGroupSize.
layout(local_size_x = 256) in;
#include "tiles_keys.glsl"

void main() {
  load_frame_view();
  const uint s = gl_GlobalInvocationID.x;
  vec2 lo = vec2(0.0), hi = vec2(-1.0);
  float z_near = 0.0, z_far = 0.0;
  // Every invocation takes part in emit_keys (it counts per workgroup).
  const bool visible = s < view.size.w && screen_bounds(s, lo, hi, z_near, z_far);
  emit_keys(s, visible, lo, hi, z_near);
}
