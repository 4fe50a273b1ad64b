#version 460
// Radix sort, pass 3 of 3 per digit: each workgroup moves its block's keys (and values) to their
// places. The block goes in chunks of kThreads keys in order. Per chunk, each digit gets a bit
// mask of the threads holding a key of it, so a key's rank among the chunk's keys of its digit
// is the count of bits before its thread's; the block's running count per digit carries the
// order across chunks: the sort is stable. Three barriers a chunk: on lavapipe a barrier
// switches every SIMD batch of the workgroup, and a split sort's scans (seven dozen of them a
// chunk, an earlier version of this file) took most of the sort's time.
#include "radix_sort.glsl"

layout(local_size_x = 256) in;

// Thread t clears and totals digit t: one thread per digit.
const uint kWords = kThreads / 32u;
shared uint digit_threads[kRadix][kWords];
shared uint running[kRadix];

void main() {
  const uint t = gl_LocalInvocationID.x, block = gl_WorkGroupID.x;
  running[t] = 0u;
  for (uint chunk = 0u; chunk < kItems; ++chunk) {
    for (uint w = 0u; w < kWords; ++w) digit_threads[t][w] = 0u;
    barrier();
    const uint at = block * kBlockItems + chunk * kThreads + t;
    const bool valid = at < pass.count;
    const uint key = valid ? keys_in[at] : 0u;
    const uint digit = digit_of(key);
    if (valid) atomicOr(digit_threads[digit][t / 32u], 1u << (t % 32u));
    barrier();
    if (valid) {
      uint rank = uint(bitCount(digit_threads[digit][t / 32u] & ((1u << (t % 32u)) - 1u)));
      for (uint w = 0u; w < t / 32u; ++w) rank += uint(bitCount(digit_threads[digit][w]));
      const uint to = counts[digit * pass.blocks + block] + running[digit] + rank;
      keys_out[to] = key;
      values_out[to] = values_in[at];
    }
    barrier();
    uint keys_of_digit = 0u;
    for (uint w = 0u; w < kWords; ++w) keys_of_digit += uint(bitCount(digit_threads[t][w]));
    running[t] += keys_of_digit;
  }
}
