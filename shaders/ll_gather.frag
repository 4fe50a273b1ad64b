#version 460
// Per-pixel linked lists, gather pass: every fragment is shaded and prepended to its pixel's
// list. Nodes are 6 uints: straight r, g, b, a (float bits), depth (float bits), next. The counter
// keeps counting past the capacity, so the host learns how many nodes a frame needs.
#include "fragment.glsl"

layout(set = 0, binding = 1, std430) buffer Heads { uint heads[]; };
layout(set = 0, binding = 2, std430) buffer Nodes { uint nodes[]; };
layout(set = 0, binding = 3, std430) buffer Counter { uint node_count; };

void main() {
  const vec4 c = shaded_fragment();
  if (c.a <= 0.0) return;  // contributes nothing
  const uint index = atomicAdd(node_count, 1u);
  if (index >= frame.size.z) return;  // overflow: counted, the host grows the buffer
  const uint next = atomicExchange(heads[pixel_index()], index);
  const uint base = 6u * index;
  nodes[base] = floatBitsToUint(c.r);
  nodes[base + 1u] = floatBitsToUint(c.g);
  nodes[base + 2u] = floatBitsToUint(c.b);
  nodes[base + 3u] = floatBitsToUint(c.a);
  nodes[base + 4u] = floatBitsToUint(gl_FragCoord.z);
  nodes[base + 5u] = next;
}
