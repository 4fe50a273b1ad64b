#pragma once
// What a Vulkan driver's compiler made of each embedded compute shader, as the driver reports it
// through VK_KHR_pipeline_executable_properties: registers, spills, scratch, occupancy,
// instructions (the names and meanings are the driver's own). On a GPU the registers a shader
// needs bound how many of its workgroups run at once, so this is where a register-hungry pass
// shows before it is timed.

#include <cstdint>
#include <string>
#include <vector>

#include "render/vulkan/context.hpp"
#include "render/vulkan/spirv_layout.hpp"

namespace linebake::vk {

struct ShaderStatistic {
  std::string name, description;  // the driver's
  double value = 0;
  bool integer = true;  // reported as an integer or a boolean (else a float)
};

// One executable of a pipeline (a compute pipeline has one; a driver may report more).
struct ShaderExecutable {
  std::string shader;      // the embedded shader's name, e.g. "tiles_composite.comp:exits"
  std::string executable;  // the driver's name for it, e.g. "Compute Shader"
  uint32_t subgroup_size = 0;
  std::vector<ShaderStatistic> statistics;
};

// The embedded compute shaders' names (variants included), in the build's table order.
std::vector<std::string> compute_shader_names();

// A compute pipeline of embedded shader `name` built with `layout` (reflect_layout's, where its
// own renderer is not there to give one): descriptor set layouts and a pipeline layout made
// from it (push constants: the device's whole range; specialisation constants: their
// defaults), all destroyed with it. Throws naming the shader.
class ReflectedPipeline {
 public:
  ReflectedPipeline(Context& context, const std::string& name, const SpirvLayout& layout,
                    VkPipelineCreateFlags flags = 0);
  ReflectedPipeline(const ReflectedPipeline&) = delete;
  ReflectedPipeline& operator=(const ReflectedPipeline&) = delete;
  ~ReflectedPipeline();
  VkPipeline pipeline() const { return pipeline_; }

 private:
  void release();
  VkDevice device_;
  std::vector<VkDescriptorSetLayout> sets_;
  VkPipelineLayout layout_ = VK_NULL_HANDLE;
  VkPipeline pipeline_ = VK_NULL_HANDLE;
};

// Compiles embedded compute shader `name` into a ReflectedPipeline with its own layout and
// returns the driver's statistics of it. Needs a Context made with
// ContextOptions::shader_statistics on a device that has them (DeviceInfo::shader_statistics).
std::vector<ShaderExecutable> compute_shader_statistics(Context& context, const std::string& name);

}  // namespace linebake::vk
