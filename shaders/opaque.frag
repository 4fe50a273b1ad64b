#version 460
// The opaque setting: depth-tested, shaded with the transfer function's colour.
#include "frame.glsl"

layout(location = 0) in vec3 world_position;
layout(location = 1) in vec3 world_normal;
layout(location = 2) in float value;
layout(location = 0) out vec4 colour;

void main() {
  colour = vec4(shade(world_position, world_normal, transfer_function(value).rgb), 1.0);
}
