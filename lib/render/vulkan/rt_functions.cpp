#include "render/vulkan/rt_functions.hpp"

#include <string>

#include "core/error.hpp"

namespace linebake::vk {
namespace {

template <class Pfn>
void fetch(VkDevice device, const char* name, Pfn& out) {
  out = reinterpret_cast<Pfn>(vkGetDeviceProcAddr(device, name));
  if (!out) throw Error(std::string("Vulkan: the device does not provide ") + name);
}

}  // namespace

RtFunctions RtFunctions::load(VkDevice device) {
  RtFunctions f;
  fetch(device, "vkGetAccelerationStructureBuildSizesKHR", f.get_build_sizes);
  fetch(device, "vkCreateAccelerationStructureKHR", f.create_as);
  fetch(device, "vkDestroyAccelerationStructureKHR", f.destroy_as);
  fetch(device, "vkCmdBuildAccelerationStructuresKHR", f.cmd_build);
  fetch(device, "vkGetAccelerationStructureDeviceAddressKHR", f.get_as_address);
  fetch(device, "vkCmdWriteAccelerationStructuresPropertiesKHR", f.cmd_write_properties);
  fetch(device, "vkCmdCopyAccelerationStructureKHR", f.cmd_copy);
  fetch(device, "vkCmdCopyAccelerationStructureToMemoryKHR", f.cmd_serialize);
  fetch(device, "vkCmdCopyMemoryToAccelerationStructureKHR", f.cmd_deserialize);
  fetch(device, "vkGetDeviceAccelerationStructureCompatibilityKHR", f.get_compatibility);
  fetch(device, "vkCreateRayTracingPipelinesKHR", f.create_pipelines);
  fetch(device, "vkGetRayTracingShaderGroupHandlesKHR", f.get_group_handles);
  fetch(device, "vkCmdTraceRaysKHR", f.cmd_trace_rays);
  return f;
}

}  // namespace linebake::vk
