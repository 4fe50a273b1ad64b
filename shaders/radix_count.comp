#version 460
// Radix sort, pass 1 of 3 per digit: each workgroup counts the digits of its block.
#include "radix_sort.glsl"

layout(local_size_x = 256) in;

shared uint histogram[kRadix];

void main() {
  const uint t = gl_LocalInvocationID.x, block = flat_workgroup();
  if (block >= pass.blocks) return;  // the last row's spare workgroups (dispatch.glsl)
  histogram[t] = 0u;
  barrier();
  for (uint i = 0u; i < kItems; ++i) {
    const uint at = block * kBlockItems + i * kThreads + t;
    const bool valid = at < pass.count;
    const uint digit = valid ? digit_of(keys_in[at]) : 0u;
#ifdef LINEBAKE_SUBGROUPS
    // One atomic per digit per subgroup: sorted runs of keys share digits, and atomics on one
    // shared address go one at a time.
    const uvec4 peers = digit_peers(digit, valid);
    if (valid && last_peer(peers)) atomicAdd(histogram[digit], subgroupBallotBitCount(peers));
#else
    if (valid) atomicAdd(histogram[digit], 1u);
#endif
  }
  barrier();
  counts[t * pass.blocks + block] = histogram[t];
}
