#version 460
// Per-pixel linked lists, gather pass: every fragment is shaded and prepended to its pixel's
// list. Nodes are 6 uints: straight r, g, b, a (float bits), depth (float bits), next. The counter
// keeps counting past the capacity, so the host learns how many nodes a frame needs.
#include "frame.glsl"

layout(location = 0) in vec3 world_position;
layout(location = 1) in vec3 world_normal;
layout(location = 2) in float value;

layout(set = 0, binding = 1, std430) buffer Heads { uint heads[]; };
layout(set = 0, binding = 2, std430) buffer Nodes { uint nodes[]; };
layout(set = 0, binding = 3, std430) buffer Counter { uint node_count; };

void main() {
  const vec4 c = transfer_function(value);
  if (c.a <= 0.0) return;  // contributes nothing
  const vec3 rgb = shade(world_position, world_normal, c.rgb);
  const uint index = atomicAdd(node_count, 1u);
  if (index >= frame.size.z) return;  // overflow: counted, the host grows the buffer
  const uint pixel = uint(gl_FragCoord.y) * frame.size.x + uint(gl_FragCoord.x);
  const uint next = atomicExchange(heads[pixel], index);
  const uint base = 6u * index;
  nodes[base] = floatBitsToUint(rgb.r);
  nodes[base + 1u] = floatBitsToUint(rgb.g);
  nodes[base + 2u] = floatBitsToUint(rgb.b);
  nodes[base + 3u] = floatBitsToUint(c.a);
  nodes[base + 4u] = floatBitsToUint(gl_FragCoord.z);
  nodes[base + 5u] = next;
}
