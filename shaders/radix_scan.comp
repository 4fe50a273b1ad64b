#version 460
// Radix sort, pass 2 of 3 per digit: the exclusive prefix sum of counts[] (digit-major, so each
// entry becomes where that block's keys of that digit start). Three steps, chosen by `kStep`:
// 0 sums each partition of kPartition counts, 1 scans the partition sums (one workgroup), 2 scans
// each partition and adds its partition's start.
#include "radix_sort.glsl"

layout(local_size_x = 256) in;
layout(constant_id = 0) const uint kStep = 0u;

#ifdef LINEBAKE_SUBGROUPS
shared uint subgroup_sums[kMaxSubgroups];

// Exclusive scan of one value per thread across the workgroup, in thread_index() order: within
// each subgroup, then over the subgroups' sums. Returns the thread's prefix and leaves the
// workgroup's total in `total_out`.
uint workgroup_exclusive_scan(uint value, out uint total_out) {
  const uint inclusive = subgroupInclusiveAdd(value);
  if (gl_SubgroupInvocationID == gl_SubgroupSize - 1u) subgroup_sums[gl_SubgroupID] = inclusive;
  barrier();
  uint before = 0u, total = 0u;
  for (uint s = 0u; s < gl_NumSubgroups; ++s) {
    const uint sum = subgroup_sums[s];
    if (s < gl_SubgroupID) before += sum;
    total += sum;
  }
  total_out = total;
  barrier();
  return before + inclusive - value;
}
#else
shared uint scratch[kThreads];

// Exclusive scan of one value per thread across the workgroup (Hillis-Steele); returns the
// thread's prefix and leaves the workgroup's total in `total_out`.
uint workgroup_exclusive_scan(uint value, out uint total_out) {
  const uint t = gl_LocalInvocationID.x;
  scratch[t] = value;
  barrier();
  for (uint offset = 1u; offset < kThreads; offset <<= 1u) {
    const uint add = t >= offset ? scratch[t - offset] : 0u;
    barrier();
    scratch[t] += add;
    barrier();
  }
  const uint inclusive = scratch[t];
  total_out = scratch[kThreads - 1u];
  barrier();
  return inclusive - value;
}
#endif

void main() {
  const uint t = thread_index(), p = flat_workgroup();
  // The last row's spare workgroups (dispatch.glsl); step 1 is one workgroup.
  if (p >= (pass.total + kPartition - 1u) / kPartition) return;
  const uint per_thread = kPartition / kThreads;
  if (kStep == 0u) {
    uint sum = 0u;
    for (uint i = 0u; i < per_thread; ++i) {
      const uint at = p * kPartition + t * per_thread + i;
      if (at < pass.total) sum += counts[at];
    }
    uint total;
    workgroup_exclusive_scan(sum, total);
    if (t == 0u) partition_sums[p] = total;
  } else if (kStep == 1u) {
    const uint partitions = (pass.total + kPartition - 1u) / kPartition;
    uint carry = 0u;
    for (uint first = 0u; first < partitions; first += kThreads) {
      const uint at = first + t;
      const uint value = at < partitions ? partition_sums[at] : 0u;
      uint total;
      const uint prefix = workgroup_exclusive_scan(value, total);
      if (at < partitions) partition_sums[at] = carry + prefix;
      carry += total;
    }
  } else {
    uint values[kPartition / kThreads];
    uint sum = 0u;
    for (uint i = 0u; i < per_thread; ++i) {
      const uint at = p * kPartition + t * per_thread + i;
      values[i] = at < pass.total ? counts[at] : 0u;
      sum += values[i];
    }
    uint total;
    uint running = partition_sums[p] + workgroup_exclusive_scan(sum, total);
    for (uint i = 0u; i < per_thread; ++i) {
      const uint at = p * kPartition + t * per_thread + i;
      if (at < pass.total) counts[at] = running;
      running += values[i];
    }
  }
}
