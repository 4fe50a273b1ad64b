#version 460
// Radix sort, pass 1 of 3 per digit: each workgroup counts the digits of its block.
#include "radix_sort.glsl"

layout(local_size_x = 256) in;

shared uint histogram[kRadix];

void main() {
  const uint t = gl_LocalInvocationID.x, block = gl_WorkGroupID.x;
  histogram[t] = 0u;
  barrier();
  for (uint i = 0u; i < kItems; ++i) {
    const uint at = block * kBlockItems + i * kThreads + t;
    if (at < pass.count) atomicAdd(histogram[digit_of(keys_in[at])], 1u);
  }
  barrier();
  counts[t * pass.blocks + block] = histogram[t];
}
