#include "render/vulkan/buffer_set.hpp"

namespace linebake::vk {
namespace {

VkDescriptorType binding_type(uint32_t binding) {
  return binding == 0 ? VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER : VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
}

}  // namespace

BufferSet create_buffer_set(VkDevice device, uint32_t count, VkShaderStageFlags stages,
                            const std::vector<uint32_t>& arrays) {
  BufferSet b;
  std::vector<VkDescriptorSetLayoutBinding> bindings;
  for (uint32_t i = 0; i < count; ++i) bindings.push_back({i, binding_type(i), 1, stages, nullptr});
  uint32_t array_count = 0;
  for (uint32_t a = 0; a < arrays.size(); ++a) {
    bindings.push_back({count + a, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, arrays[a], stages, nullptr});
    array_count += arrays[a];
  }
  VkDescriptorSetLayoutCreateInfo set_info{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
  set_info.bindingCount = uint32_t(bindings.size());
  set_info.pBindings = bindings.data();
  check(vkCreateDescriptorSetLayout(device, &set_info, nullptr, &b.set_layout),
        "descriptor layout");
  VkPipelineLayoutCreateInfo layout_info{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
  layout_info.setLayoutCount = 1;
  layout_info.pSetLayouts = &b.set_layout;
  check(vkCreatePipelineLayout(device, &layout_info, nullptr, &b.layout), "pipeline layout");
  const VkDescriptorPoolSize sizes[] = {
      {VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1},
      {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, count - 1 + array_count}};
  VkDescriptorPoolCreateInfo pool_info{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  pool_info.maxSets = 1;
  pool_info.poolSizeCount = 2;
  pool_info.pPoolSizes = sizes;
  check(vkCreateDescriptorPool(device, &pool_info, nullptr, &b.pool), "descriptor pool");
  VkDescriptorSetAllocateInfo alloc{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
  alloc.descriptorPool = b.pool;
  alloc.descriptorSetCount = 1;
  alloc.pSetLayouts = &b.set_layout;
  check(vkAllocateDescriptorSets(device, &alloc, &b.set), "descriptor set");
  return b;
}

void write_buffer_set(VkDevice device, VkDescriptorSet set,
                      const std::vector<const Buffer*>& buffers) {
  std::vector<VkDescriptorBufferInfo> infos(buffers.size());
  std::vector<VkWriteDescriptorSet> writes(buffers.size());
  for (uint32_t i = 0; i < buffers.size(); ++i) {
    infos[i] = {buffers[i]->buffer, 0, VK_WHOLE_SIZE};
    writes[i] = {VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
    writes[i].dstSet = set;
    writes[i].dstBinding = i;
    writes[i].descriptorCount = 1;
    writes[i].descriptorType = binding_type(i);
    writes[i].pBufferInfo = &infos[i];
  }
  vkUpdateDescriptorSets(device, uint32_t(writes.size()), writes.data(), 0, nullptr);
}

void write_buffer_array(VkDevice device, VkDescriptorSet set, uint32_t binding,
                        const std::vector<const Buffer*>& buffers) {
  std::vector<VkDescriptorBufferInfo> infos(buffers.size());
  for (size_t i = 0; i < buffers.size(); ++i) infos[i] = {buffers[i]->buffer, 0, VK_WHOLE_SIZE};
  VkWriteDescriptorSet write{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
  write.dstSet = set;
  write.dstBinding = binding;
  write.descriptorCount = uint32_t(infos.size());
  write.descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
  write.pBufferInfo = infos.data();
  vkUpdateDescriptorSets(device, 1, &write, 0, nullptr);
}

}  // namespace linebake::vk
