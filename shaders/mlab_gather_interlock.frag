#version 460
// MLAB and MLABDB's second pass under ordered fragment shader interlock: fragments of a pixel
// enter in primitive order, the order a CPU reference can reproduce.
#extension GL_ARB_fragment_shader_interlock : require
#include "mlab_insert.glsl"

layout(pixel_interlock_ordered) in;

void main() {
  const vec4 c = shaded_fragment();
  beginInvocationInterlockARB();
  if (c.a > 0.0) mlab_fragment(pixel_index(), c);
  endInvocationInterlockARB();
}
