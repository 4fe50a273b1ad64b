#version 460
// Radix sort, pass 3 of 3 per digit: each workgroup moves its block's keys (and values) to their
// places. The block goes in chunks of kThreads keys in order. Per chunk, each digit gets a bit
// mask of the threads holding a key of it, so a key's rank among the chunk's keys of its digit
// is the count of bits before its thread's; the block's running count per digit carries the
// order across chunks: the sort is stable. Three barriers a chunk: on lavapipe a barrier
// switches every SIMD batch of the workgroup, and a split sort's scans (seven dozen of them a
// chunk, an earlier version of this file) took most of the sort's time.
// With LINEBAKE_SUBGROUPS (radix_sort.glsl) the ranks come from ballots instead: below.
#include "radix_sort.glsl"

layout(local_size_x = 256) in;

#ifdef LINEBAKE_SUBGROUPS
// Per subgroup and digit, how many of the subgroup's keys have that digit, then where the first
// of them goes in the block's run of that digit. 16 bits a count, two digits a word: a block's
// 4096 keys never carry into the neighbour, and 32 subgroups of 8 fit lavapipe's 32 KiB.
shared uint subgroup_digits[kMaxSubgroups][kRadix / 2u];

void main() {
  const uint t = gl_LocalInvocationID.x, block = flat_workgroup(), s = gl_SubgroupID;
  if (block >= pass.blocks) return;  // the last row's spare workgroups (dispatch.glsl)
  for (uint i = t; i < kMaxSubgroups * kRadix / 2u; i += kThreads)
    subgroup_digits[i / (kRadix / 2u)][i % (kRadix / 2u)] = 0u;
  barrier();
  // A subgroup's keys are a run of kItems * gl_SubgroupSize keys of the block, taken a subgroup
  // wide at a time; a key's rank among the subgroup's keys of its digit is the count of the
  // earlier steps' plus its peers before it.
  const uint first = block * kBlockItems + s * kItems * gl_SubgroupSize + gl_SubgroupInvocationID;
  uint key[kItems], rank[kItems];
  for (uint i = 0u; i < kItems; ++i) {
    const uint at = first + i * gl_SubgroupSize;
    const bool valid = at < pass.count;
    key[i] = valid ? keys_in[at] : 0u;
    const uint digit = digit_of(key[i]), shift = (digit & 1u) * 16u;
    const uvec4 peers = digit_peers(digit, valid);
    rank[i] = ((subgroup_digits[s][digit / 2u] >> shift) & 0xFFFFu) +
              subgroupBallotExclusiveBitCount(peers);
    subgroupMemoryBarrierShared();
    subgroupBarrier();
    if (valid && last_peer(peers))
      atomicAdd(subgroup_digits[s][digit / 2u], subgroupBallotBitCount(peers) << shift);
    subgroupMemoryBarrierShared();
    subgroupBarrier();
  }
  barrier();
  // Thread t scans word t over the subgroups: both digits at once, as neither half carries.
  if (t < kRadix / 2u) {
    uint running = 0u;
    for (uint g = 0u; g < gl_NumSubgroups; ++g) {
      const uint here = subgroup_digits[g][t];
      subgroup_digits[g][t] = running;
      running += here;
    }
  }
  barrier();
  for (uint i = 0u; i < kItems; ++i) {
    const uint at = first + i * gl_SubgroupSize;
    if (at >= pass.count) continue;
    const uint digit = digit_of(key[i]);
    const uint to = counts[digit * pass.blocks + block] +
                    ((subgroup_digits[s][digit / 2u] >> ((digit & 1u) * 16u)) & 0xFFFFu) + rank[i];
    keys_out[to] = key[i];
    values_out[to] = values_in[at];
  }
}
#else
// A chunk's thread masks per digit, and per digit where the chunk's first key of it goes (the
// block's start from the scan, then past each chunk's keys of it). Once every thread has read
// both, the first key of each digit in a mask word clears that word and every key counts itself
// into `running`: at most a store and an atomic a key, where clearing and totalling all 256 x 8
// words had taken sixteen shared accesses a key (lavapipe makes each lane's shared access on its
// own). With the blocks' starts read once into `running`, the shared-memory sort of 1.5 million
// 24-bit keys took 0.75 times as long on lavapipe (with the copies to and from the device).
const uint kWords = kThreads / 32u;
shared uint digit_threads[kRadix][kWords];
shared uint running[kRadix];

void main() {
  const uint t = gl_LocalInvocationID.x, block = flat_workgroup();
  if (block >= pass.blocks) return;  // the last row's spare workgroups (dispatch.glsl)
  running[t] = counts[t * pass.blocks + block];
  for (uint w = 0u; w < kWords; ++w) digit_threads[t][w] = 0u;
  for (uint chunk = 0u; chunk < kItems; ++chunk) {
    // The last block's chunks past the keys: none of its threads has work (uniform).
    if (block * kBlockItems + chunk * kThreads >= pass.count) break;
    barrier();
    const uint at = block * kBlockItems + chunk * kThreads + t;
    const bool valid = at < pass.count;
    const uint key = valid ? keys_in[at] : 0u;
    const uint digit = digit_of(key);
    if (valid) atomicOr(digit_threads[digit][t / 32u], 1u << (t % 32u));
    barrier();
    // The key's peers of its digit before it in its mask word; the first of them (none before
    // it) clears the word, so that one thread writes it.
    uint below = 0u;
    if (valid) {
      below = uint(bitCount(digit_threads[digit][t / 32u] & ((1u << (t % 32u)) - 1u)));
      uint rank = below;
      for (uint w = 0u; w < t / 32u; ++w) rank += uint(bitCount(digit_threads[digit][w]));
      const uint to = running[digit] + rank;
      keys_out[to] = key;
      values_out[to] = values_in[at];
    }
    barrier();
    if (valid) {
      if (below == 0u) digit_threads[digit][t / 32u] = 0u;
      atomicAdd(running[digit], 1u);
    }
  }
}
#endif
