#version 460
// Depth complexity: counts the front-facing fragments per pixel, whatever their opacity (as the
// CPU tracer counts front hits), and keeps the maximum: the layers depth peeling needs at most.
#include "fragment.glsl"

layout(set = 0, binding = 5, std430) buffer Stats { uint longest; uint depth_complexity[]; };

void main() {
  const uint before = atomicAdd(depth_complexity[pixel_index()], 1u);
  atomicMax(longest, before + 1u);
}
