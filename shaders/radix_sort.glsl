// Shared by the passes of the GPU radix sort (lib/render/vulkan/radix_sort.hpp): 32-bit keys with
// 32-bit values, sorted stably by 8-bit digits, least significant first. The design is the
// reduce-then-scan sort of AMD FidelityFX Parallel Sort (count per block, scan the per-digit
// counts of all blocks, scatter), written anew for linebake: a block is kBlockItems keys, one
// workgroup of kThreads threads each; the scatter ranks keys stably by counting bits of per-digit
// thread masks in shared memory (radix_scatter.comp), so neither subgroup operations nor
// anything past core Vulkan compute is needed.
//
// Compiled with LINEBAKE_SUBGROUPS (shaders/CMakeLists.txt), the passes use basic, ballot and
// arithmetic subgroup operations instead, for devices that have them in compute (the host picks;
// it also asks for full subgroups of at least 8 invocations): the scan adds within subgroups,
// and the count and scatter find a key's peers of the same digit in its subgroup with one ballot
// per digit bit, the warp-level multi-split of Onesweep (Adinets and Merrill 2022), so the
// scatter ranks a whole block behind three barriers instead of three a chunk. A thread's keys
// are then placed by its subgroup and lane (thread_index()), not its local index, whose mapping
// to subgroups Vulkan leaves open: the order, and so stability, follows the subgroups.
#ifdef LINEBAKE_SUBGROUPS
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#endif

#include "dispatch.glsl"

const uint kThreads = 256;
// Keys per thread per block: 4096 a block, near Onesweep's 15 x 256. Against 4 a thread, the
// blocks' digit counts (written, scanned twice and read per key) are a quarter, and on lavapipe
// a sort of 1.5 million 24-bit keys took 0.8 times as long (with
// the copies to and from the device).
const uint kItems = 16;
const uint kBlockItems = kThreads * kItems;
const uint kRadix = 256;
const uint kPartition = 1024;  // counts per scan partition

layout(set = 0, binding = 0, std430) buffer KeysIn { uint keys_in[]; };
layout(set = 0, binding = 1, std430) buffer ValuesIn { uint values_in[]; };
layout(set = 0, binding = 2, std430) buffer KeysOut { uint keys_out[]; };
layout(set = 0, binding = 3, std430) buffer ValuesOut { uint values_out[]; };
// counts[digit * blocks + block]: how many keys of each block have each digit, then (after the
// scan) where the first of them goes.
layout(set = 0, binding = 4, std430) buffer Counts { uint counts[]; };
layout(set = 0, binding = 5, std430) buffer Partitions { uint partition_sums[]; };

layout(push_constant) uniform Pass {
  uint count;   // keys
  uint shift;   // of the digit
  uint blocks;  // ceil(count / kBlockItems)
  uint total;   // counts: kRadix * blocks
} pass;

uint digit_of(uint key) {
  return (key >> pass.shift) & (kRadix - 1u);
}

#ifdef LINEBAKE_SUBGROUPS
const uint kMaxSubgroups = kThreads / 8u;  // subgroups of at least 8 (the host checks)

// The thread's place in the workgroup's order: subgroup by subgroup, lane by lane.
uint thread_index() {
  return gl_SubgroupID * gl_SubgroupSize + gl_SubgroupInvocationID;
}

// The lanes of this subgroup holding a key (`valid`) of the same digit as this lane's.
uvec4 digit_peers(uint digit, bool valid) {
  uvec4 peers = subgroupBallot(valid);
  for (uint b = 0u; b < 8u; ++b) {
    const bool set = ((digit >> b) & 1u) != 0u;
    const uvec4 vote = subgroupBallot(set);
    peers &= set ? vote : ~vote;
  }
  return peers;
}

// Whether this lane is the last of its peers (the one that speaks for them).
bool last_peer(uvec4 peers) {
  return subgroupBallotFindMSB(peers) == gl_SubgroupInvocationID;
}
#else
uint thread_index() {
  return gl_LocalInvocationID.x;
}
#endif
