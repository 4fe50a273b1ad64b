#include "render/vulkan/shaders.hpp"

#include <algorithm>
#include <string>

#include "core/error.hpp"
#include "render/vulkan/context.hpp"

namespace linebake::vk {
namespace {

struct Embedded {
  const char* name;
  Spirv code;
};

template <size_t N>
constexpr Spirv view(const uint32_t (&words)[N]) {
  return {words, sizeof(words)};
}

#include "embedded_shaders.inc"

const Embedded kShaders[] = {LINEBAKE_EMBEDDED_SHADERS};

}  // namespace

Spirv shader_spirv(const std::string& name) {
  for (const Embedded& e : kShaders)
    if (name == e.name) return e.code;
  throw Error("no embedded shader named '" + name + "'");
}

std::vector<std::string> embedded_shader_names() {
  std::vector<std::string> names;
  for (const Embedded& e : kShaders) names.push_back(e.name);
  return names;
}

VkShaderModule create_shader_module(VkDevice device, const std::string& name) {
  const Spirv code = shader_spirv(name);
  VkShaderModuleCreateInfo create{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
  create.codeSize = code.size_bytes;
  create.pCode = code.words;
  VkShaderModule module;
  check(vkCreateShaderModule(device, &create, nullptr, &module), "vkCreateShaderModule");
  return module;
}

VkPipeline create_compute_pipeline(VkDevice device, VkPipelineLayout layout,
                                   const std::string& name,
                                   const VkSpecializationInfo* specialisation,
                                   VkPipelineShaderStageCreateFlags stage_flags,
                                   VkPipelineCreateFlags pipeline_flags) {
  VkShaderModule module = create_shader_module(device, name);
  VkComputePipelineCreateInfo create{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
  create.flags = pipeline_flags;
  create.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
  create.stage.flags = stage_flags;
  create.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
  create.stage.module = module;
  create.stage.pName = "main";
  create.stage.pSpecializationInfo = specialisation;
  create.layout = layout;
  VkPipeline pipeline = VK_NULL_HANDLE;
  const VkResult made =
      vkCreateComputePipelines(device, VK_NULL_HANDLE, 1, &create, nullptr, &pipeline);
  vkDestroyShaderModule(device, module, nullptr);
  check(made, ("vkCreateComputePipelines (" + name + ")").c_str());
  return pipeline;
}

void dispatch_workgroups(VkCommandBuffer cmd, uint64_t groups, uint32_t row) {
  if (groups == 0) return;
  row = std::clamp<uint32_t>(row, 1, kDispatchRow);
  const uint64_t rows = (groups + row - 1) / row;
  if (rows > kDispatchRow)
    throw Error("a dispatch of " + std::to_string(groups) + " workgroups takes more than " +
                std::to_string(kDispatchRow) + " rows of " + std::to_string(row));
  vkCmdDispatch(cmd, uint32_t(std::min<uint64_t>(groups, row)), uint32_t(rows), 1);
}

}  // namespace linebake::vk
