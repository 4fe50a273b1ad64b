// Shared by the passes of the GPU radix sort (lib/render/vulkan/radix_sort.hpp): 32-bit keys with
// 32-bit values, sorted stably by 8-bit digits, least significant first. The design is the
// reduce-then-scan sort of AMD FidelityFX Parallel Sort (count per block, scan the per-digit
// counts of all blocks, scatter), written anew for linebake: a block is kBlockItems keys, one
// workgroup of kThreads threads each; the scatter ranks keys stably by counting bits of per-digit
// thread masks in shared memory (radix_scatter.comp), so neither subgroup operations nor
// anything past core Vulkan compute is needed.

const uint kThreads = 256;
const uint kItems = 4;  // keys per thread per block
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
