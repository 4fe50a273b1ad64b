#pragma once
// The header Vulkan writes in front of a serialised acceleration structure
// (vkCmdCopyAccelerationStructureToMemoryKHR): the driver UUID, the acceleration-structure
// compatibility UUID, the serialised and deserialised sizes and the count of BLAS handles that
// follow (0 for a BLAS). Parsing and the first compatibility check need no device, so a cached
// blob from another driver is turned down before anything is allocated.

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>

namespace linebake::vk {

struct SerializedAsHeader {
  std::array<uint8_t, 16> driver_uuid{};
  std::array<uint8_t, 16> compatibility{};
  uint64_t serialized_size = 0;    // the whole blob, header included
  uint64_t deserialized_size = 0;  // VkAccelerationStructureCreateInfoKHR::size on load
  uint64_t handle_count = 0;       // bottom-level handles after the header (0 for a BLAS)
};

constexpr uint64_t kSerializedAsHeaderBytes = 16 + 16 + 3 * 8;

// Throws Error naming the problem when the blob is shorter than its header says.
SerializedAsHeader parse_serialized_as(std::span<const uint8_t> blob);

// Why `blob` cannot be loaded on a device with `driver_uuid` (a one-line reason), or nullopt
// when the header allows it; the device's own compatibility query comes after this.
std::optional<std::string> serialized_as_problem(std::span<const uint8_t> blob,
                                                 const std::array<uint8_t, 16>& driver_uuid);

}  // namespace linebake::vk
