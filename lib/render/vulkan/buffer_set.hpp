#pragma once
// The one descriptor set every linebake shader binds: binding 0 a uniform buffer, bindings
// 1 .. count-1 storage buffers (whole buffers), and the pipeline layout over it.

#include <vulkan/vulkan.h>

#include <cstdint>
#include <vector>

#include "render/vulkan/context.hpp"

namespace linebake::vk {

struct BufferSet {
  VkDescriptorSetLayout set_layout = VK_NULL_HANDLE;
  VkPipelineLayout layout = VK_NULL_HANDLE;
  VkDescriptorPool pool = VK_NULL_HANDLE;
  VkDescriptorSet set = VK_NULL_HANDLE;
};

// The caller destroys the layouts and the pool. Each entry of `arrays` adds a binding after
// them (count, count + 1, ...): an array of that many storage buffers.
BufferSet create_buffer_set(VkDevice device, uint32_t count, VkShaderStageFlags stages,
                            const std::vector<uint32_t>& arrays = {});
// Points binding i at buffers[i].
void write_buffer_set(VkDevice device, VkDescriptorSet set,
                      const std::vector<const Buffer*>& buffers);
// Points the elements of array binding `binding` at `buffers`.
void write_buffer_array(VkDevice device, VkDescriptorSet set, uint32_t binding,
                        const std::vector<const Buffer*>& buffers);

}  // namespace linebake::vk
