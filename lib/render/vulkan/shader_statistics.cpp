#include "render/vulkan/shader_statistics.hpp"

#include <algorithm>

#include "render/vulkan/shaders.hpp"
#include "render/vulkan/spirv_layout.hpp"

namespace linebake::vk {

std::vector<std::string> compute_shader_names() {
  std::vector<std::string> names;
  for (const std::string& name : embedded_shader_names())
    if (name.find(".comp") != std::string::npos) names.push_back(name);
  return names;
}

ReflectedPipeline::ReflectedPipeline(Context& context, const std::string& name,
                                     const SpirvLayout& layout, VkPipelineCreateFlags flags)
    : device_(context.device()), sets_(layout.set_count(), VK_NULL_HANDLE) {
  if (layout.stage != VK_SHADER_STAGE_COMPUTE_BIT)
    throw Error("shader " + name + " is not a compute shader");
  try {
    for (uint32_t set = 0; set < sets_.size(); ++set) {
      std::vector<VkDescriptorSetLayoutBinding> bindings;
      for (const SpirvBinding& b : layout.bindings)
        if (b.set == set)
          bindings.push_back({b.binding, b.type, b.count, VK_SHADER_STAGE_COMPUTE_BIT, nullptr});
      VkDescriptorSetLayoutCreateInfo create{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
      create.bindingCount = uint32_t(bindings.size());
      create.pBindings = bindings.data();
      check(vkCreateDescriptorSetLayout(device_, &create, nullptr, &sets_[set]),
            "vkCreateDescriptorSetLayout");
    }
    VkPhysicalDeviceProperties properties;
    vkGetPhysicalDeviceProperties(context.physical_device(), &properties);
    const VkPushConstantRange push{VK_SHADER_STAGE_COMPUTE_BIT, 0,
                                   properties.limits.maxPushConstantsSize};
    VkPipelineLayoutCreateInfo create{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    create.setLayoutCount = uint32_t(sets_.size());
    create.pSetLayouts = sets_.data();
    create.pushConstantRangeCount = layout.push_constants ? 1 : 0;
    create.pPushConstantRanges = &push;
    check(vkCreatePipelineLayout(device_, &create, nullptr, &layout_), "vkCreatePipelineLayout");
    pipeline_ = create_compute_pipeline(device_, layout_, name, nullptr, 0, flags);
  } catch (...) {
    release();
    throw;
  }
}

ReflectedPipeline::~ReflectedPipeline() {
  release();
}

void ReflectedPipeline::release() {
  vkDestroyPipeline(device_, pipeline_, nullptr);
  vkDestroyPipelineLayout(device_, layout_, nullptr);
  for (VkDescriptorSetLayout s : sets_) vkDestroyDescriptorSetLayout(device_, s, nullptr);
  pipeline_ = VK_NULL_HANDLE, layout_ = VK_NULL_HANDLE;
  sets_.clear();
}

std::vector<ShaderExecutable> compute_shader_statistics(Context& context, const std::string& name) {
  if (!context.info().shader_statistics)
    throw Error("Vulkan: " + context.info().name +
                " does not report compiler statistics (no VK_KHR_pipeline_executable_properties)");
  const SpirvLayout reflected = reflect_layout(shader_spirv(name), name);
  VkDevice device = context.device();
  const auto properties = reinterpret_cast<PFN_vkGetPipelineExecutablePropertiesKHR>(
      vkGetDeviceProcAddr(device, "vkGetPipelineExecutablePropertiesKHR"));
  const auto statistics = reinterpret_cast<PFN_vkGetPipelineExecutableStatisticsKHR>(
      vkGetDeviceProcAddr(device, "vkGetPipelineExecutableStatisticsKHR"));
  if (!properties || !statistics)
    throw Error("Vulkan: " + context.info().name + " has no vkGetPipelineExecutable*KHR");

  const ReflectedPipeline pipeline(context, name, reflected,
                                   VK_PIPELINE_CREATE_CAPTURE_STATISTICS_BIT_KHR);
  VkPipelineInfoKHR info{VK_STRUCTURE_TYPE_PIPELINE_INFO_KHR};
  info.pipeline = pipeline.pipeline();
  uint32_t count = 0;
  check(properties(device, &info, &count, nullptr), "vkGetPipelineExecutablePropertiesKHR");
  std::vector<VkPipelineExecutablePropertiesKHR> executables(
      count, {VK_STRUCTURE_TYPE_PIPELINE_EXECUTABLE_PROPERTIES_KHR});
  check(properties(device, &info, &count, executables.data()),
        "vkGetPipelineExecutablePropertiesKHR");
  std::vector<ShaderExecutable> result;
  for (uint32_t e = 0; e < count; ++e) {
    ShaderExecutable out{name, executables[e].name, executables[e].subgroupSize, {}};
    VkPipelineExecutableInfoKHR which{VK_STRUCTURE_TYPE_PIPELINE_EXECUTABLE_INFO_KHR};
    which.pipeline = pipeline.pipeline();
    which.executableIndex = e;
    uint32_t n = 0;
    check(statistics(device, &which, &n, nullptr), "vkGetPipelineExecutableStatisticsKHR");
    std::vector<VkPipelineExecutableStatisticKHR> values(
        n, {VK_STRUCTURE_TYPE_PIPELINE_EXECUTABLE_STATISTIC_KHR});
    check(statistics(device, &which, &n, values.data()), "vkGetPipelineExecutableStatisticsKHR");
    for (const VkPipelineExecutableStatisticKHR& v : values) {
      ShaderStatistic s{v.name, v.description};
      switch (v.format) {
        case VK_PIPELINE_EXECUTABLE_STATISTIC_FORMAT_BOOL32_KHR:
          s.value = v.value.b32;
          break;
        case VK_PIPELINE_EXECUTABLE_STATISTIC_FORMAT_INT64_KHR:
          s.value = double(v.value.i64);
          break;
        case VK_PIPELINE_EXECUTABLE_STATISTIC_FORMAT_UINT64_KHR:
          s.value = double(v.value.u64);
          break;
        default:
          s.value = v.value.f64, s.integer = false;
          break;
      }
      out.statistics.push_back(s);
    }
    result.push_back(std::move(out));
  }
  return result;
}

}  // namespace linebake::vk
