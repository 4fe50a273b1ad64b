#version 460
// Depth peeling, one layer: the nearest fragment strictly behind the depth peeled last time
// (binding 1, -1 before the first layer). The depth test LESS keeps the nearest; a fragment at
// exactly the peeled depth is discarded, so equal depths peel once (techniques.md section 2).
#include "fragment.glsl"

layout(set = 0, binding = 1, std430) readonly buffer Peeled { float peeled[]; };

layout(location = 0) out vec4 layer_colour;  // straight rgb, a
layout(location = 1) out float layer_depth;

void main() {
  const vec4 c = shaded_fragment();
  if (c.a <= 0.0 || gl_FragCoord.z <= peeled[pixel_index()]) discard;
  layer_colour = c;
  layer_depth = gl_FragCoord.z;
}
