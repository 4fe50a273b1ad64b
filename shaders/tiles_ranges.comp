#version 460
// tiles, pass 2 (after the sort): where each tile's keys start and end.
#include "tiles.glsl"

layout(local_size_x = 256) in;

void main() {
  load_frame_view();
  const uint i = flat_workgroup() * gl_WorkGroupSize.x + gl_LocalInvocationID.x;
  const uint n = min(counters.key_count, view.tiles.w);
  if (i >= n) return;
  const uint bits = view.tiles.z;
  const uint tile = keys[i] >> bits;
  if (i == 0u || (keys[i - 1u] >> bits) != tile) ranges[tile].x = i;
  if (i + 1u == n || (keys[i + 1u] >> bits) != tile) ranges[tile].y = i + 1u;
}
