#include "render/vulkan/radix_sort.hpp"

#include <algorithm>
#include <array>
#include <string>

#include "core/error.hpp"
#include "render/vulkan/shaders.hpp"

namespace linebake::vk {
namespace {

// As shaders/radix_sort.glsl.
constexpr uint32_t kBlockItems = 256 * 16;
constexpr uint32_t kRadix = 256;
constexpr uint32_t kPartition = 1024;
constexpr uint32_t kSortBindings = 6;

struct PassConstants {
  uint32_t count, shift, blocks, total;
};

uint32_t blocks_for(uint64_t count) {
  return uint32_t(std::max<uint64_t>(1, (count + kBlockItems - 1) / kBlockItems));
}

}  // namespace

struct RadixSorter::State {
  Context& ctx;
  VkDescriptorSetLayout set_layout = VK_NULL_HANDLE;
  VkPipelineLayout layout = VK_NULL_HANDLE;
  VkDescriptorPool pool = VK_NULL_HANDLE;
  std::array<VkDescriptorSet, 2> sets{};  // keys -> scratch, scratch -> keys
  VkPipeline counting = VK_NULL_HANDLE, scatter = VK_NULL_HANDLE;
  std::array<VkPipeline, 3> scan{};
  Buffer keys2, values2, counts, partitions;
  const Buffer *bound_keys = nullptr, *bound_values = nullptr;

  explicit State(Context& c) : ctx(c) {}

  uint32_t subgroup_size = 0;  // 0: the shared-memory path

  // The pass's shader, its subgroup variant (shaders/CMakeLists.txt) with full subgroups where
  // the sort runs on subgroups.
  VkPipeline pipeline(const std::string& shader, const uint32_t* step) {
    const VkSpecializationMapEntry entry{0, 0, 4};
    const VkSpecializationInfo specialisation{1, &entry, 4, step};
    const bool subgroups = subgroup_size > 0;
    return create_compute_pipeline(
        ctx.device(), layout, subgroups ? shader + ":subgroups" : shader,
        step ? &specialisation : nullptr,
        subgroups ? VK_PIPELINE_SHADER_STAGE_CREATE_REQUIRE_FULL_SUBGROUPS_BIT : 0);
  }

  // Scratch for `count` pairs: grown, never shrunk; descriptor sets rewritten when it or the
  // caller's buffers change.
  void prepare(const Buffer& keys, const Buffer& values, uint32_t count) {
    const uint64_t pair_bytes = std::max<uint64_t>(4, uint64_t(count) * 4);
    const uint64_t count_bytes = uint64_t(kRadix) * blocks_for(count) * 4;
    const uint64_t partition_bytes =
        std::max<uint64_t>(4, (count_bytes / 4 + kPartition - 1) / kPartition * 4);
    // Always rebound: a caller may reallocate its buffers under the same Buffer object.
    bool rebind = true;
    const auto grow = [&](Buffer& b, uint64_t bytes,
                          VkBufferUsageFlags usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT) {
      if (b.size >= bytes) return;
      ctx.destroy(b);
      b = ctx.create_buffer(bytes, usage, false);
      rebind = true;
    };
    grow(keys2, pair_bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT);
    grow(values2, pair_bytes,
         VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT);
    grow(counts, count_bytes);
    grow(partitions, partition_bytes);
    if (!rebind) return;
    bound_keys = &keys, bound_values = &values;
    const std::array<std::array<const Buffer*, 4>, 2> pairs = {
        {{&keys, &values, &keys2, &values2}, {&keys2, &values2, &keys, &values}}};
    for (size_t s = 0; s < 2; ++s) {
      std::array<VkDescriptorBufferInfo, kSortBindings> infos{};
      std::array<VkWriteDescriptorSet, kSortBindings> writes{};
      for (uint32_t i = 0; i < kSortBindings; ++i) {
        const Buffer* b = i < 4 ? pairs[s][i] : i == 4 ? &counts : &partitions;
        infos[i] = {b->buffer, 0, VK_WHOLE_SIZE};
        writes[i] = {VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
        writes[i].dstSet = sets[s];
        writes[i].dstBinding = i;
        writes[i].descriptorCount = 1;
        writes[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
        writes[i].pBufferInfo = &infos[i];
      }
      vkUpdateDescriptorSets(ctx.device(), kSortBindings, writes.data(), 0, nullptr);
    }
  }

  ~State() {
    VkDevice d = ctx.device();
    vkDeviceWaitIdle(d);
    for (Buffer* b : {&keys2, &values2, &counts, &partitions}) ctx.destroy(*b);
    for (VkPipeline p : {counting, scatter, scan[0], scan[1], scan[2]})
      if (p) vkDestroyPipeline(d, p, nullptr);
    if (pool) vkDestroyDescriptorPool(d, pool, nullptr);
    if (layout) vkDestroyPipelineLayout(d, layout, nullptr);
    if (set_layout) vkDestroyDescriptorSetLayout(d, set_layout, nullptr);
  }
};

bool RadixSorter::subgroups_supported(const DeviceInfo& info) {
  // At most kThreads / 8 subgroups: the shaders' shared arrays (radix_sort.glsl), and whole
  // subgroups in a workgroup of kThreads.
  const uint32_t size = info.subgroup_size;
  return info.subgroup_ballot_arithmetic && info.compute_full_subgroups && size >= 8 &&
         size <= 128 && (size & (size - 1)) == 0;
}

uint32_t RadixSorter::subgroup_size() const {
  return state_->subgroup_size;
}

RadixSorter::RadixSorter(Context& context, bool use_subgroups)
    : state_(std::make_unique<State>(context)) {
  State& s = *state_;
  if (use_subgroups && subgroups_supported(context.info()))
    s.subgroup_size = context.info().subgroup_size;
  VkDevice d = context.device();
  std::array<VkDescriptorSetLayoutBinding, kSortBindings> bindings{};
  for (uint32_t i = 0; i < kSortBindings; ++i)
    bindings[i] = {i, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr};
  VkDescriptorSetLayoutCreateInfo set_info{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
  set_info.bindingCount = kSortBindings;
  set_info.pBindings = bindings.data();
  check(vkCreateDescriptorSetLayout(d, &set_info, nullptr, &s.set_layout), "radix sort layout");
  const VkPushConstantRange range{VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(PassConstants)};
  VkPipelineLayoutCreateInfo layout_info{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
  layout_info.setLayoutCount = 1;
  layout_info.pSetLayouts = &s.set_layout;
  layout_info.pushConstantRangeCount = 1;
  layout_info.pPushConstantRanges = &range;
  check(vkCreatePipelineLayout(d, &layout_info, nullptr, &s.layout), "radix sort pipeline layout");
  const VkDescriptorPoolSize size{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 2 * kSortBindings};
  VkDescriptorPoolCreateInfo pool_info{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  pool_info.maxSets = 2;
  pool_info.poolSizeCount = 1;
  pool_info.pPoolSizes = &size;
  check(vkCreateDescriptorPool(d, &pool_info, nullptr, &s.pool), "radix sort pool");
  const std::array<VkDescriptorSetLayout, 2> layouts{s.set_layout, s.set_layout};
  VkDescriptorSetAllocateInfo alloc{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
  alloc.descriptorPool = s.pool;
  alloc.descriptorSetCount = 2;
  alloc.pSetLayouts = layouts.data();
  check(vkAllocateDescriptorSets(d, &alloc, s.sets.data()), "radix sort sets");
  s.counting = s.pipeline("radix_count.comp", nullptr);
  s.scatter = s.pipeline("radix_scatter.comp", nullptr);
  for (uint32_t step = 0; step < 3; ++step) s.scan[step] = s.pipeline("radix_scan.comp", &step);
}

RadixSorter::~RadixSorter() = default;

uint64_t RadixSorter::scratch_bytes(uint64_t count) {
  const uint64_t counts = uint64_t(kRadix) * blocks_for(count);
  return 8 * count + 4 * counts + 4 * ((counts + kPartition - 1) / kPartition);
}

void RadixSorter::record(VkCommandBuffer cmd, const Buffer& keys, const Buffer& values,
                         uint32_t count, uint32_t bits, uint32_t dispatch_row) {
  State& s = *state_;
  if (uint64_t(count) * 4 > keys.size || uint64_t(count) * 4 > values.size)
    throw Error("radix sort: " + std::to_string(count) + " pairs do not fit the buffers");
  s.prepare(keys, values, count);
  if (count <= 1) return;
  const uint32_t passes = std::min<uint32_t>(4, (std::max<uint32_t>(bits, 1) + 7) / 8);
  const uint32_t blocks = blocks_for(count);
  const uint32_t total = kRadix * blocks;
  const uint32_t partitions = (total + kPartition - 1) / kPartition;
  const auto barrier = [&] {
    VkMemoryBarrier b{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    b.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
    b.dstAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                         VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1, &b, 0, nullptr, 0, nullptr);
  };
  for (uint32_t pass = 0; pass < passes; ++pass) {
    const PassConstants c{count, 8 * pass, blocks, total};
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, s.layout, 0, 1, &s.sets[pass % 2],
                            0, nullptr);
    vkCmdPushConstants(cmd, s.layout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof c, &c);
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, s.counting);
    dispatch_workgroups(cmd, blocks, dispatch_row);
    barrier();
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, s.scan[0]);
    dispatch_workgroups(cmd, partitions, dispatch_row);
    barrier();
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, s.scan[1]);
    vkCmdDispatch(cmd, 1, 1, 1);
    barrier();
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, s.scan[2]);
    dispatch_workgroups(cmd, partitions, dispatch_row);
    barrier();
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, s.scatter);
    dispatch_workgroups(cmd, blocks, dispatch_row);
    barrier();
  }
  // An odd number of passes ends in the scratch pair: copied back, a small part of a pass (it
  // was one more pass by the last digit, so 24-bit keys cost as much as 32-bit ones).
  if (passes % 2 == 1) {
    const VkBufferCopy region{0, 0, uint64_t(count) * 4};
    vkCmdCopyBuffer(cmd, s.keys2.buffer, keys.buffer, 1, &region);
    vkCmdCopyBuffer(cmd, s.values2.buffer, values.buffer, 1, &region);
    VkMemoryBarrier b{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    b.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    b.dstAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT |
                      VK_ACCESS_TRANSFER_READ_BIT | VK_ACCESS_HOST_READ_BIT;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT,
                         VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT |
                             VK_PIPELINE_STAGE_HOST_BIT,
                         0, 1, &b, 0, nullptr, 0, nullptr);
  }
}

void RadixSorter::sort(std::vector<uint32_t>& keys, std::vector<uint32_t>& values, uint32_t bits,
                       uint32_t dispatch_row) {
  if (keys.size() != values.size()) throw Error("radix sort: keys and values differ in length");
  if (keys.size() > UINT32_MAX) throw Error("radix sort: more than 2^32 - 1 pairs");
  Context& ctx = state_->ctx;
  const uint64_t bytes = std::max<uint64_t>(4, keys.size() * 4);
  const VkBufferUsageFlags usage =
      VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
  Buffer k = ctx.create_buffer(bytes, usage, true), v;
  try {
    v = ctx.create_buffer(bytes, usage, true);
  } catch (...) {
    ctx.destroy(k);
    throw;
  }
  // std::copy, not memcpy: an empty vector's data() may be null, which memcpy may not take.
  std::copy(keys.begin(), keys.end(), static_cast<uint32_t*>(k.mapped));
  std::copy(values.begin(), values.end(), static_cast<uint32_t*>(v.mapped));
  ctx.submit([&](VkCommandBuffer cmd) {
    record(cmd, k, v, uint32_t(keys.size()), bits, dispatch_row);
    VkMemoryBarrier b{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    b.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
    b.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0,
                         1, &b, 0, nullptr, 0, nullptr);
  });
  std::copy_n(static_cast<const uint32_t*>(k.mapped), keys.size(), keys.begin());
  std::copy_n(static_cast<const uint32_t*>(v.mapped), values.size(), values.begin());
  state_->bound_keys = state_->bound_values = nullptr;  // the buffers go now
  ctx.destroy(k);
  ctx.destroy(v);
}

}  // namespace linebake::vk
