#version 460
// Per-pixel linked lists, gather pass: every fragment is shaded and prepended to its pixel's
// list in the node pool (ll_nodes.glsl: 24- or 12-byte nodes, split across buffers). The counter
// keeps counting past the capacity, so the host learns how many nodes a frame needs.
#include "fragment.glsl"
#include "ll_nodes.glsl"

layout(set = 0, binding = 1, std430) buffer Heads { uint heads[]; };
layout(set = 0, binding = 3, std430) buffer Counter { uint node_count; };

void main() {
  const vec4 c = shaded_fragment();
  if (c.a <= 0.0) return;  // contributes nothing
  const uint index = atomicAdd(node_count, 1u);
  if (index >= frame.size.z) return;  // overflow: counted, the host grows the buffer
  const uint next = atomicExchange(heads[pixel_index()], index);
  write_node(index, c, gl_FragCoord.z, next);
}
