#include "render/vulkan/rt_renderer.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cstring>

#include "core/error.hpp"
#include "core/measure.hpp"
#include "render/vulkan/pixel_readback.hpp"
#include "render/vulkan/rt_functions.hpp"
#include "render/vulkan/shaders.hpp"
#include "render/vulkan/transfer_table.hpp"
#include "render/vulkan/view_uniforms.hpp"

namespace linebake::vk {
namespace {

// std140 mirror of RtUniforms in shaders/rtx_common.glsl.
struct RtUniforms {
  float eye[4], forward[4], right[4], up[4];
  float shading[4], background[4], ranges[4];
  uint32_t size[4], tf_counts[4];
  float params[4];
  float colours[kMaxTfPoints][4];
  float opacities[kMaxTfPoints][4];
};

// Binding 0 the TLAS, 1 uniforms, 2 chunk table, 3 output, 4 hit counts, 5 counters.
constexpr uint32_t kRtBindings = 6;
constexpr VkShaderStageFlags kHitStages = VK_SHADER_STAGE_CLOSEST_HIT_BIT_KHR |
                                          VK_SHADER_STAGE_ANY_HIT_BIT_KHR |
                                          VK_SHADER_STAGE_INTERSECTION_BIT_KHR;

}  // namespace

struct RtRenderer::State {
  Context& ctx;
  RtFunctions fn;
  VkDescriptorSetLayout set_layout = VK_NULL_HANDLE;
  VkPipelineLayout layout = VK_NULL_HANDLE;
  VkDescriptorPool pool = VK_NULL_HANDLE;
  VkDescriptorSet set = VK_NULL_HANDLE;
  VkPipeline pipeline = VK_NULL_HANDLE;
  VkQueryPool queries = VK_NULL_HANDLE;
  Buffer uniforms, sbt;
  ResultBuffer counters;  // back hits, truncated pixels, traces, seam hits
  PixelTargets targets;
  VkStridedDeviceAddressRegionKHR raygen{}, miss{}, hit{}, callable{};

  explicit State(Context& c) : ctx(c), fn(RtFunctions::load(c.device())) {}

  ~State() {
    VkDevice d = ctx.device();
    vkDeviceWaitIdle(d);
    for (Buffer* b : {&uniforms, &sbt}) ctx.destroy(*b);
    ctx.destroy(counters);
    targets.release(ctx);
    if (queries) vkDestroyQueryPool(d, queries, nullptr);
    if (pipeline) vkDestroyPipeline(d, pipeline, nullptr);
    if (pool) vkDestroyDescriptorPool(d, pool, nullptr);
    if (layout) vkDestroyPipelineLayout(d, layout, nullptr);
    if (set_layout) vkDestroyDescriptorSetLayout(d, set_layout, nullptr);
  }

  void create_layout() {
    VkDevice d = ctx.device();
    std::array<VkDescriptorSetLayoutBinding, kRtBindings> b{};
    const VkDescriptorType types[kRtBindings] = {VK_DESCRIPTOR_TYPE_ACCELERATION_STRUCTURE_KHR,
                                                 VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER,
                                                 VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
                                                 VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
                                                 VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
                                                 VK_DESCRIPTOR_TYPE_STORAGE_BUFFER};
    const VkShaderStageFlags stages[kRtBindings] = {
        VK_SHADER_STAGE_RAYGEN_BIT_KHR,
        VK_SHADER_STAGE_RAYGEN_BIT_KHR | kHitStages | VK_SHADER_STAGE_MISS_BIT_KHR,
        VK_SHADER_STAGE_RAYGEN_BIT_KHR | kHitStages,
        VK_SHADER_STAGE_RAYGEN_BIT_KHR,
        VK_SHADER_STAGE_RAYGEN_BIT_KHR,
        VK_SHADER_STAGE_RAYGEN_BIT_KHR};
    for (uint32_t i = 0; i < kRtBindings; ++i) {
      b[i].binding = i;
      b[i].descriptorType = types[i];
      b[i].descriptorCount = 1;
      b[i].stageFlags = stages[i];
    }
    VkDescriptorSetLayoutCreateInfo info{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
    info.bindingCount = kRtBindings;
    info.pBindings = b.data();
    check(vkCreateDescriptorSetLayout(d, &info, nullptr, &set_layout), "descriptor set layout");
    VkPipelineLayoutCreateInfo pl{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    pl.setLayoutCount = 1;
    pl.pSetLayouts = &set_layout;
    check(vkCreatePipelineLayout(d, &pl, nullptr, &layout), "pipeline layout");
    const VkDescriptorPoolSize sizes[] = {{VK_DESCRIPTOR_TYPE_ACCELERATION_STRUCTURE_KHR, 1},
                                          {VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1},
                                          {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 4}};
    VkDescriptorPoolCreateInfo p{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
    p.maxSets = 1;
    p.poolSizeCount = 3;
    p.pPoolSizes = sizes;
    check(vkCreateDescriptorPool(d, &p, nullptr, &pool), "descriptor pool");
    VkDescriptorSetAllocateInfo a{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
    a.descriptorPool = pool;
    a.descriptorSetCount = 1;
    a.pSetLayouts = &set_layout;
    check(vkAllocateDescriptorSets(d, &a, &set), "descriptor set");
  }

  void create_pipeline() {
    VkDevice d = ctx.device();
    const char* names[] = {
        "rtx.rgen",          "rtx.rmiss",          "rtx_triangles.rchit", "rtx_triangles.rahit",
        "rtx_capsules.rint", "rtx_capsules.rchit", "rtx_capsules.rahit"};
    const VkShaderStageFlagBits kinds[] = {
        VK_SHADER_STAGE_RAYGEN_BIT_KHR,       VK_SHADER_STAGE_MISS_BIT_KHR,
        VK_SHADER_STAGE_CLOSEST_HIT_BIT_KHR,  VK_SHADER_STAGE_ANY_HIT_BIT_KHR,
        VK_SHADER_STAGE_INTERSECTION_BIT_KHR, VK_SHADER_STAGE_CLOSEST_HIT_BIT_KHR,
        VK_SHADER_STAGE_ANY_HIT_BIT_KHR};
    std::array<VkPipelineShaderStageCreateInfo, 7> stages{};
    for (size_t i = 0; i < stages.size(); ++i) {
      stages[i] = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
      stages[i].stage = kinds[i];
      stages[i].module = create_shader_module(d, names[i]);
      stages[i].pName = "main";
    }
    // Groups: 0 ray generation, 1 miss, 2 triangles hit group, 3 capsules hit group. The ray
    // flags pick closest hit (stepping) or any hit (filter) within a group.
    std::array<VkRayTracingShaderGroupCreateInfoKHR, 4> groups{};
    for (auto& g : groups) {
      g = {VK_STRUCTURE_TYPE_RAY_TRACING_SHADER_GROUP_CREATE_INFO_KHR};
      g.generalShader = g.closestHitShader = g.anyHitShader = g.intersectionShader =
          VK_SHADER_UNUSED_KHR;
    }
    groups[0].type = groups[1].type = VK_RAY_TRACING_SHADER_GROUP_TYPE_GENERAL_KHR;
    groups[0].generalShader = 0;
    groups[1].generalShader = 1;
    groups[2].type = VK_RAY_TRACING_SHADER_GROUP_TYPE_TRIANGLES_HIT_GROUP_KHR;
    groups[2].closestHitShader = 2;
    groups[2].anyHitShader = 3;
    groups[3].type = VK_RAY_TRACING_SHADER_GROUP_TYPE_PROCEDURAL_HIT_GROUP_KHR;
    groups[3].intersectionShader = 4;
    groups[3].closestHitShader = 5;
    groups[3].anyHitShader = 6;
    VkRayTracingPipelineCreateInfoKHR create{
        VK_STRUCTURE_TYPE_RAY_TRACING_PIPELINE_CREATE_INFO_KHR};
    create.stageCount = uint32_t(stages.size());
    create.pStages = stages.data();
    create.groupCount = uint32_t(groups.size());
    create.pGroups = groups.data();
    create.maxPipelineRayRecursionDepth = 1;  // only the ray generation shader traces
    create.layout = layout;
    const VkResult made =
        fn.create_pipelines(d, VK_NULL_HANDLE, VK_NULL_HANDLE, 1, &create, nullptr, &pipeline);
    for (auto& s : stages) vkDestroyShaderModule(d, s.module, nullptr);
    check(made, "vkCreateRayTracingPipelinesKHR");
    create_binding_table(uint32_t(groups.size()));
  }

  // The shader binding table: ray generation, miss, then the two hit groups (an instance's
  // record offset picks one).
  void create_binding_table(uint32_t group_count) {
    VkPhysicalDeviceRayTracingPipelinePropertiesKHR rt{
        VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_RAY_TRACING_PIPELINE_PROPERTIES_KHR};
    VkPhysicalDeviceProperties2 props{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2, &rt};
    vkGetPhysicalDeviceProperties2(ctx.physical_device(), &props);
    const uint64_t handle = rt.shaderGroupHandleSize;
    const uint64_t stride = align_up(handle, rt.shaderGroupHandleAlignment);
    const uint64_t base = std::max<uint64_t>(rt.shaderGroupBaseAlignment, 1);
    std::vector<uint8_t> handles(group_count * handle);
    check(fn.get_group_handles(ctx.device(), pipeline, 0, group_count, handles.size(),
                               handles.data()),
          "vkGetRayTracingShaderGroupHandlesKHR");
    const uint64_t raygen_size = align_up(stride, base), miss_size = align_up(stride, base);
    const uint64_t hit_size = align_up(2 * stride, base);
    std::vector<uint8_t> table(raygen_size + miss_size + hit_size + base, 0);
    sbt = ctx.create_buffer(
        table.size(),
        VK_BUFFER_USAGE_SHADER_BINDING_TABLE_BIT_KHR | VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT,
        true);
    const VkDeviceAddress address = ctx.address(sbt);
    const VkDeviceAddress start = align_up(address, base);
    auto* bytes = static_cast<uint8_t*>(sbt.mapped) + (start - address);
    std::memcpy(bytes, &handles[0], handle);
    std::memcpy(bytes + raygen_size, &handles[handle], handle);
    std::memcpy(bytes + raygen_size + miss_size, &handles[2 * handle], handle);
    std::memcpy(bytes + raygen_size + miss_size + stride, &handles[3 * handle], handle);
    raygen = {start, raygen_size, raygen_size};
    miss = {start + raygen_size, stride, miss_size};
    hit = {start + raygen_size + miss_size, stride, hit_size};
    callable = {0, 0, 0};
  }

  void write_descriptors(const RtScene& scene) {
    VkAccelerationStructureKHR tlas = scene.tlas();
    VkWriteDescriptorSetAccelerationStructureKHR as{
        VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET_ACCELERATION_STRUCTURE_KHR};
    as.accelerationStructureCount = 1;
    as.pAccelerationStructures = &tlas;
    const Buffer* buffers[kRtBindings] = {
        nullptr,           &uniforms,           &scene.chunk_table(),
        &targets.rgba.gpu, &targets.counts.gpu, &counters.gpu};
    std::array<VkDescriptorBufferInfo, kRtBindings> infos{};
    std::array<VkWriteDescriptorSet, kRtBindings> writes{};
    for (uint32_t i = 0; i < kRtBindings; ++i) {
      writes[i] = {VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
      writes[i].dstSet = set;
      writes[i].dstBinding = i;
      writes[i].descriptorCount = 1;
      if (i == 0) {
        writes[i].descriptorType = VK_DESCRIPTOR_TYPE_ACCELERATION_STRUCTURE_KHR;
        writes[i].pNext = &as;
        continue;
      }
      infos[i] = {buffers[i]->buffer, 0, VK_WHOLE_SIZE};
      writes[i].descriptorType =
          i == 1 ? VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER : VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
      writes[i].pBufferInfo = &infos[i];
    }
    vkUpdateDescriptorSets(ctx.device(), kRtBindings, writes.data(), 0, nullptr);
  }
};

RtHits parse_rt_hits(const std::string& name) {
  if (name == "filter") return RtHits::Filter;
  if (name == "stepping") return RtHits::Stepping;
  throw Error("unknown rtx hit collection '" + name + "' (filter, stepping)");
}

const char* to_string(RtHits hits) {
  return hits == RtHits::Filter ? "filter" : "stepping";
}

RtRenderer::RtRenderer(Context& context) : state_(std::make_unique<State>(context)) {
  State& s = *state_;
  if (!context.ray_tracing())
    throw Error("rtx: the Vulkan context was created without ray tracing");
  s.uniforms = context.create_buffer(sizeof(RtUniforms), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, true);
  s.counters = context.create_result(16, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  s.create_layout();
  s.create_pipeline();
  s.queries = context.create_timestamp_pair();
}

RtRenderer::~RtRenderer() = default;

RtFrame RtRenderer::render(const RtScene& scene, const Camera& camera,
                           const TransferFunction& tf_in, const RtOptions& o) {
  if (o.width < 1 || o.height < 1) throw Error("rtx: empty image size");
  if (!scene.built()) throw Error("rtx: the scene has no acceleration structure yet");
  if (o.max_iterations < 1) throw Error("rtx: at least one trace per pixel");
  const auto start = std::chrono::steady_clock::now();
  State& s = *state_;
  s.targets.resize(s.ctx, o.width, o.height);
  s.write_descriptors(scene);
  TransferFunction tf = tf_in;
  const auto range = scene.attribute_range();
  if (tf.range[0] == 0 && tf.range[1] == 0) tf.range = {double(range[0]), double(range[1])};
  RtUniforms u{};
  write_view(u, camera, o.width, o.height, o.shading);
  u.ranges[0] = range[0], u.ranges[1] = range[1];
  u.ranges[2] = float(tf.range[0]), u.ranges[3] = float(tf.range[1]);
  u.size[0] = uint32_t(o.width), u.size[1] = uint32_t(o.height);
  u.size[2] = o.early_termination ? 1u : 0u, u.size[3] = o.max_iterations;
  u.params[0] = float(o.termination_alpha), u.params[1] = scene.capsule_radius();
  u.params[2] = scene.geometry() == RtGeometry::Capsules ? 1.0f : 0.0f;
  write_transfer_table(tf, u.colours, u.opacities, u.tf_counts);
  u.tf_counts[2] = o.hits == RtHits::Stepping ? 1u : 0u;
  std::memcpy(s.uniforms.mapped, &u, sizeof u);
  s.ctx.submit([&](VkCommandBuffer cmd) {
    vkCmdFillBuffer(cmd, s.counters.gpu.buffer, 0, VK_WHOLE_SIZE, 0);
    VkMemoryBarrier cleared{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    cleared.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    cleared.dstAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT,
                         VK_PIPELINE_STAGE_RAY_TRACING_SHADER_BIT_KHR, 0, 1, &cleared, 0, nullptr,
                         0, nullptr);
    if (s.queries) {
      vkCmdResetQueryPool(cmd, s.queries, 0, 2);
      vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, s.queries, 0);
    }
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_RAY_TRACING_KHR, s.pipeline);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_RAY_TRACING_KHR, s.layout, 0, 1, &s.set, 0,
                            nullptr);
    s.fn.cmd_trace_rays(cmd, &s.raygen, &s.miss, &s.hit, &s.callable, uint32_t(o.width),
                        uint32_t(o.height), 1);
    if (s.queries) vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, s.queries, 1);
    VkMemoryBarrier barrier{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    barrier.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
    barrier.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_RAY_TRACING_SHADER_BIT_KHR,
                         VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &barrier, 0, nullptr, 0, nullptr);
  });
  RtFrame frame;
  frame.stats.gpu_ms = s.ctx.elapsed_ms(s.queries);
  const uint64_t pixels = uint64_t(o.width) * uint64_t(o.height);
  PixelReadback read = s.targets.read(s.ctx);
  frame.image = std::move(read.image);
  frame.alpha = std::move(read.alpha);
  frame.depth_complexity = std::move(read.counts);
  frame.stats.hits = read.total;
  frame.stats.max_depth_complexity = read.maximum;
  const auto* c = static_cast<const uint32_t*>(s.ctx.read_back(s.counters));
  frame.stats.back_hits = c[0];
  frame.stats.truncated_pixels = c[1];
  frame.stats.traces = c[2];
  frame.stats.seam_hits = c[3];
  frame.stats.frame_bytes = pixels * (16 + 4);
  frame.stats.seconds = seconds_since(start);
  return frame;
}

}  // namespace linebake::vk
