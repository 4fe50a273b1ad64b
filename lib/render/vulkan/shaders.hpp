#pragma once
// The SPIR-V of shaders/, compiled by glslc at build time and embedded in the binary.

#include <vulkan/vulkan.h>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace linebake::vk {

struct Spirv {
  const uint32_t* words = nullptr;
  size_t size_bytes = 0;
};

// By source file name, e.g. "tube.vert" or "ll_resolve.comp"; throws for other names.
Spirv shader_spirv(const std::string& name);
// Every embedded shader's name, variants ("NAME:variant", shaders/CMakeLists.txt) included.
std::vector<std::string> embedded_shader_names();
// A shader module of one embedded shader (the caller destroys it).
VkShaderModule create_shader_module(VkDevice device, const std::string& name);
// A compute pipeline of one embedded shader's `main` with `layout` and, where given, its
// specialisation constants, stage flags and pipeline flags (the caller destroys it). Throws naming
// the shader.
VkPipeline create_compute_pipeline(VkDevice device, VkPipelineLayout layout,
                                   const std::string& name,
                                   const VkSpecializationInfo* specialisation = nullptr,
                                   VkPipelineShaderStageCreateFlags stage_flags = 0,
                                   VkPipelineCreateFlags pipeline_flags = 0);

// The most workgroups Vulkan promises along one dimension of a dispatch
// (maxComputeWorkGroupCount's least allowed value: lavapipe's and Intel's).
constexpr uint32_t kDispatchRow = 65535;
// Records a dispatch of `groups` workgroups along x, in rows of at most `row` (tests make rows
// of a few) when there are more; the shader takes its index from flat_workgroup()
// (shaders/dispatch.glsl) and skips those past `groups` in the last row. Throws past 65,535 rows.
void dispatch_workgroups(VkCommandBuffer cmd, uint64_t groups, uint32_t row = kDispatchRow);

}  // namespace linebake::vk
