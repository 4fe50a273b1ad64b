#pragma once
// The SPIR-V of shaders/, compiled by glslc at build time and embedded in the binary.

#include <vulkan/vulkan.h>

#include <cstddef>
#include <cstdint>
#include <string>

namespace linebake::vk {

struct Spirv {
  const uint32_t* words = nullptr;
  size_t size_bytes = 0;
};

// By source file name, e.g. "tube.vert" or "ll_resolve.comp"; throws for other names.
Spirv shader_spirv(const std::string& name);
// A shader module of one embedded shader (the caller destroys it).
VkShaderModule create_shader_module(VkDevice device, const std::string& name);

}  // namespace linebake::vk
