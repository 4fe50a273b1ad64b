#version 460
// The cached tube mesh: world-space positions and normals, the attribute as unorm16.
#include "frame.glsl"

layout(location = 0) in vec3 position;
layout(location = 1) in vec3 normal;
layout(location = 2) in float attribute_unorm;  // R16_UNORM

layout(location = 0) out vec3 world_position;
layout(location = 1) out vec3 world_normal;
layout(location = 2) out float value;

void main() {
  world_position = position;
  world_normal = normal;
  value = frame.ranges.x + (frame.ranges.y - frame.ranges.x) * attribute_unorm;
  gl_Position = frame.view_projection * vec4(position, 1.0);
}
