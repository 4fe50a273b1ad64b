#pragma once
// The VK_KHR_acceleration_structure and VK_KHR_ray_tracing_pipeline entry points, which the
// Vulkan loader does not export: fetched once per device with vkGetDeviceProcAddr.

#include <vulkan/vulkan.h>

#include <cstdint>

namespace linebake::vk {

struct RtFunctions {
  PFN_vkGetAccelerationStructureBuildSizesKHR get_build_sizes = nullptr;
  PFN_vkCreateAccelerationStructureKHR create_as = nullptr;
  PFN_vkDestroyAccelerationStructureKHR destroy_as = nullptr;
  PFN_vkCmdBuildAccelerationStructuresKHR cmd_build = nullptr;
  PFN_vkGetAccelerationStructureDeviceAddressKHR get_as_address = nullptr;
  PFN_vkCmdWriteAccelerationStructuresPropertiesKHR cmd_write_properties = nullptr;
  PFN_vkCmdCopyAccelerationStructureKHR cmd_copy = nullptr;
  PFN_vkCmdCopyAccelerationStructureToMemoryKHR cmd_serialize = nullptr;
  PFN_vkCmdCopyMemoryToAccelerationStructureKHR cmd_deserialize = nullptr;
  PFN_vkGetDeviceAccelerationStructureCompatibilityKHR get_compatibility = nullptr;
  PFN_vkCreateRayTracingPipelinesKHR create_pipelines = nullptr;
  PFN_vkGetRayTracingShaderGroupHandlesKHR get_group_handles = nullptr;
  PFN_vkCmdTraceRaysKHR cmd_trace_rays = nullptr;

  // Throws Error naming the first entry point the device does not provide.
  static RtFunctions load(VkDevice device);
};

// `value` rounded up to a multiple of `alignment` (shader binding table strides, scratch and
// acceleration structure offsets); 0 or 1: as it is.
inline uint64_t align_up(uint64_t value, uint64_t alignment) {
  return alignment > 1 ? (value + alignment - 1) / alignment * alignment : value;
}

}  // namespace linebake::vk
