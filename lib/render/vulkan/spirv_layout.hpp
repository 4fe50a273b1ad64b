#pragma once
// The descriptor bindings a SPIR-V module's entry point declares, read from the module itself
// (the SPIR-V specification's logical layout: OpDecorate DescriptorSet/Binding on OpVariables, the
// variables' storage classes and types). Enough to build a pipeline layout a driver accepts for a
// shader whose own renderer is not there to give one: the compiler statistics of `bench shaders`.

#include <vulkan/vulkan.h>

#include <cstdint>
#include <string>
#include <vector>

#include "render/vulkan/shaders.hpp"

namespace linebake::vk {

struct SpirvBinding {
  uint32_t set = 0, binding = 0;
  VkDescriptorType type = VK_DESCRIPTOR_TYPE_MAX_ENUM;
  uint32_t count = 1;  // an array of descriptors: its length
  // A buffer block whose last member is a runtime array: that array's ArrayStride, the bytes of
  // one element as the compiler laid it out (std430 for storage buffers); else 0.
  uint32_t array_stride = 0;
};

struct SpirvLayout {
  VkShaderStageFlagBits stage = VK_SHADER_STAGE_COMPUTE_BIT;  // of the first entry point
  std::vector<SpirvBinding> bindings;                         // by (set, binding)
  bool push_constants = false;
  uint32_t set_count() const;  // highest set + 1 (0: none)
};

// Throws linebake::Error naming `name` (the shader, for the message) for a module that is not
// SPIR-V or declares a resource kind this reader does not know.
SpirvLayout reflect_layout(const Spirv& code, const std::string& name);

}  // namespace linebake::vk
