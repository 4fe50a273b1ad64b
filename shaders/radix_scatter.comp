#version 460
// Radix sort, pass 3 of 3 per digit: each workgroup moves its block's keys (and values) to their
// places. The block goes in chunks of kThreads keys in order; each chunk is sorted stably by digit
// in shared memory with one-bit splits (keys past the end sort last), so a key's rank among the
// chunk's keys of its digit is its distance from the first of them, and the block's running count
// per digit carries the order across chunks: the sort is stable.
#include "radix_sort.glsl"

layout(local_size_x = 256) in;

shared uint chunk_keys[kThreads];
shared uint chunk_values[kThreads];
shared uint scan[kThreads];
shared uint run_start[kRadix];
shared uint running[kRadix];

// Exclusive scan of one flag per thread (Hillis-Steele); total in `total_out`.
uint exclusive_scan(uint value, out uint total_out) {
  const uint t = gl_LocalInvocationID.x;
  scan[t] = value;
  barrier();
  for (uint offset = 1u; offset < kThreads; offset <<= 1u) {
    const uint add = t >= offset ? scan[t - offset] : 0u;
    barrier();
    scan[t] += add;
    barrier();
  }
  total_out = scan[kThreads - 1u];
  const uint inclusive = scan[t];
  barrier();
  return inclusive - value;
}

void main() {
  const uint t = gl_LocalInvocationID.x, block = gl_WorkGroupID.x;
  running[t] = 0u;
  barrier();
  for (uint chunk = 0u; chunk < kItems; ++chunk) {
    const uint at = block * kBlockItems + chunk * kThreads + t;
    const bool valid = at < pass.count;
    uint key = valid ? keys_in[at] : 0u;
    uint value = valid ? values_in[at] : 0u;
    // The sort key of the split: the digit, and bit 8 for keys past the end.
    uint sort_key = valid ? digit_of(key) : kRadix;
    for (uint bit = 0u; bit < 9u; ++bit) {
      const uint one = (sort_key >> bit) & 1u;
      uint ones;
      const uint ones_before = exclusive_scan(one, ones);
      const uint zeros = kThreads - ones;
      const uint place = one == 1u ? zeros + ones_before : t - ones_before;
      chunk_keys[place] = key;
      chunk_values[place] = value;
      scan[place] = sort_key;  // exclusive_scan is done with scan[] until the next call
      barrier();
      key = chunk_keys[t];
      value = chunk_values[t];
      sort_key = scan[t];
      barrier();
    }
    // Thread t now holds the chunk's t-th key in (digit, original order).
    scan[t] = sort_key;
    barrier();
    if (sort_key < kRadix && (t == 0u || scan[t - 1u] != sort_key)) run_start[sort_key] = t;
    barrier();
    if (sort_key < kRadix) {
      const uint rank = t - run_start[sort_key];
      const uint to = counts[sort_key * pass.blocks + block] + running[sort_key] + rank;
      keys_out[to] = key;
      values_out[to] = value;
    }
    barrier();
    // The last key of each run adds the run's length to its digit's running count.
    if (sort_key < kRadix && (t == kThreads - 1u || scan[t + 1u] != sort_key))
      running[sort_key] += t - run_start[sort_key] + 1u;
    barrier();
  }
}
