#pragma once
// A GPU radix sort of 32-bit keys with 32-bit values in core Vulkan compute: the sort of the
// `tiles` renderer's (tile, depth) keys. Stable, 8 bits per pass from the least significant; per
// pass a count, a three-step scan and a scatter (shaders/radix_*.comp; the design and its
// credit are in shaders/radix_sort.glsl). Runs wherever Vulkan compute does, lavapipe included;
// where the device has the subgroup operations for it, a subgroup path of the same passes (the
// same results, bit for bit).

#include <cstdint>
#include <memory>
#include <vector>

#include "render/vulkan/context.hpp"
#include "render/vulkan/shaders.hpp"

namespace linebake::vk {

class RadixSorter {
 public:
  // `use_subgroups` false keeps the shared-memory path on every device (tests, comparisons).
  explicit RadixSorter(Context& context, bool use_subgroups = true);
  ~RadixSorter();
  RadixSorter(const RadixSorter&) = delete;
  RadixSorter& operator=(const RadixSorter&) = delete;

  // Whether a device runs the subgroup path: compute subgroups of 8 to 128 invocations with
  // basic, ballot and arithmetic operations, and pipelines that may require full subgroups.
  static bool subgroups_supported(const DeviceInfo& info);
  // The subgroup size the passes run with; 0 on the shared-memory path.
  uint32_t subgroup_size() const;

  // Scratch the sort of `count` keys needs besides the keys and values (bytes): the ping-pong
  // copies of both and the per-block digit counts.
  static uint64_t scratch_bytes(uint64_t count);
  // Records into `cmd` the sort of the first `count` pairs of `keys`/`values` by their low
  // `bits` bits (8 per pass, rounded up); the result is back in `keys`/`values`. The buffers
  // are storage buffers that may be copied into (TRANSFER_DST: an odd number of passes ends
  // in the scratch, which is copied back); the scratch is made (or grown) here and reused.
  // Its passes' workgroups go in rows of `dispatch_row` (vk::dispatch_workgroups; tests lower
  // it).
  void record(VkCommandBuffer cmd, const Buffer& keys, const Buffer& values, uint32_t count,
              uint32_t bits = 32, uint32_t dispatch_row = kDispatchRow);
  // Host arrays through the device (tests and benchmarks): sorts `keys` and permutes `values`
  // alike (equal keys keep their order).
  void sort(std::vector<uint32_t>& keys, std::vector<uint32_t>& values, uint32_t bits = 32,
            uint32_t dispatch_row = kDispatchRow);

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace linebake::vk
