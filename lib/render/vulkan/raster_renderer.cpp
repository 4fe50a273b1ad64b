#include "render/vulkan/raster_renderer.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <glm/gtc/matrix_transform.hpp>

#include "core/error.hpp"
#include "core/measure.hpp"
#include "render/vulkan/shaders.hpp"

namespace linebake::vk {
namespace {

constexpr int kMaxTfPoints = 32;  // shaders/frame.glsl
constexpr uint32_t kNodeBytes = 24;
constexpr uint32_t kEmptyList = 0xFFFFFFFFu;

// std140 mirror of FrameUniforms in shaders/frame.glsl.
struct FrameUniforms {
  float view_projection[16];
  float eye[4];
  float shading[4];
  float background[4];
  float ranges[4];
  uint32_t size[4];
  uint32_t tf_counts[4];
  float termination[4];
  float colours[kMaxTfPoints][4];
  float opacities[kMaxTfPoints][4];
};

struct ChunkBuffers {
  Buffer positions, normals, attribute, indices;
  uint32_t index_count = 0;
};

struct Image2D {
  VkImage image = VK_NULL_HANDLE;
  VkDeviceMemory memory = VK_NULL_HANDLE;
  VkImageView view = VK_NULL_HANDLE;
};

VkShaderModule make_module(VkDevice device, const std::string& name) {
  const Spirv code = shader_spirv(name);
  VkShaderModuleCreateInfo create{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
  create.codeSize = code.size_bytes;
  create.pCode = code.words;
  VkShaderModule module;
  check(vkCreateShaderModule(device, &create, nullptr, &module), "vkCreateShaderModule");
  return module;
}

void barrier(VkCommandBuffer cmd, VkPipelineStageFlags from, VkAccessFlags from_access,
             VkPipelineStageFlags to, VkAccessFlags to_access) {
  VkMemoryBarrier b{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  b.srcAccessMask = from_access;
  b.dstAccessMask = to_access;
  vkCmdPipelineBarrier(cmd, from, to, 0, 1, &b, 0, nullptr, 0, nullptr);
}

void image_barrier(VkCommandBuffer cmd, VkImage image, VkImageAspectFlags aspect,
                   VkImageLayout from, VkImageLayout to, VkPipelineStageFlags src_stage,
                   VkAccessFlags src, VkPipelineStageFlags dst_stage, VkAccessFlags dst) {
  VkImageMemoryBarrier b{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER};
  b.oldLayout = from;
  b.newLayout = to;
  b.srcAccessMask = src;
  b.dstAccessMask = dst;
  b.srcQueueFamilyIndex = b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  b.image = image;
  b.subresourceRange = {aspect, 0, 1, 0, 1};
  vkCmdPipelineBarrier(cmd, src_stage, dst_stage, 0, 0, nullptr, 0, nullptr, 1, &b);
}

uint64_t next_power_of_two(uint64_t v) {
  uint64_t p = 1;
  while (p < v) p <<= 1;
  return p;
}

}  // namespace

RasterTechnique parse_raster_technique(const std::string& name) {
  if (name == "opaque") return RasterTechnique::Opaque;
  if (name == "ll") return RasterTechnique::LinkedLists;
  throw Error("unknown rasterisation technique '" + name + "' (opaque, ll)");
}

const char* to_string(RasterTechnique t) {
  return t == RasterTechnique::Opaque ? "opaque" : "ll";
}

ListSort parse_list_sort(const std::string& name) {
  if (name == "insertion") return ListSort::Insertion;
  if (name == "shell") return ListSort::Shell;
  if (name == "heap") return ListSort::Heap;
  throw Error("unknown linked-list sort '" + name + "' (insertion, shell, heap)");
}

const char* to_string(ListSort s) {
  switch (s) {
    case ListSort::Insertion:
      return "insertion";
    case ListSort::Shell:
      return "shell";
    case ListSort::Heap:
      return "heap";
  }
  return "?";
}

struct RasterRenderer::State {
  Context& ctx;
  std::vector<ChunkBuffers> chunks;
  std::array<float, 2> attribute_range{0, 0};
  uint64_t mesh_bytes = 0;

  VkDescriptorSetLayout set_layout = VK_NULL_HANDLE;
  VkPipelineLayout layout = VK_NULL_HANDLE;
  VkDescriptorPool pool = VK_NULL_HANDLE;
  VkDescriptorSet set = VK_NULL_HANDLE;
  VkPipeline opaque = VK_NULL_HANDLE, gather = VK_NULL_HANDLE;
  VkPipeline resolve = VK_NULL_HANDLE;
  uint32_t resolve_max = 0;
  ListSort resolve_sort = ListSort::Heap;
  VkQueryPool queries = VK_NULL_HANDLE;

  // Per-frame resources, kept while the size and capacity stay the same.
  int width = 0, height = 0;
  uint64_t capacity = 0;
  Buffer uniforms, heads, nodes, counter, output, stats;
  Image2D colour, depth;
  Buffer readback;

  explicit State(Context& c) : ctx(c) {}

  ~State() {
    VkDevice d = ctx.device();
    vkDeviceWaitIdle(d);
    for (ChunkBuffers& c : chunks)
      for (Buffer* b : {&c.positions, &c.normals, &c.attribute, &c.indices}) ctx.destroy(*b);
    release_frame();
    for (VkPipeline p : {opaque, gather, resolve})
      if (p) vkDestroyPipeline(d, p, nullptr);
    if (queries) vkDestroyQueryPool(d, queries, nullptr);
    if (pool) vkDestroyDescriptorPool(d, pool, nullptr);
    if (layout) vkDestroyPipelineLayout(d, layout, nullptr);
    if (set_layout) vkDestroyDescriptorSetLayout(d, set_layout, nullptr);
  }

  void destroy_image(Image2D& i) {
    VkDevice d = ctx.device();
    if (i.view) vkDestroyImageView(d, i.view, nullptr);
    if (i.image) vkDestroyImage(d, i.image, nullptr);
    if (i.memory) vkFreeMemory(d, i.memory, nullptr);
    i = Image2D{};
  }

  void release_frame() {
    for (Buffer* b : {&uniforms, &heads, &nodes, &counter, &output, &stats, &readback})
      ctx.destroy(*b);
    destroy_image(colour);
    destroy_image(depth);
    width = height = 0;
    capacity = 0;
  }

  Image2D make_image(VkFormat format, VkImageUsageFlags usage, VkImageAspectFlags aspect) {
    Image2D i;
    VkImageCreateInfo create{VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO};
    create.imageType = VK_IMAGE_TYPE_2D;
    create.format = format;
    create.extent = {uint32_t(width), uint32_t(height), 1};
    create.mipLevels = create.arrayLayers = 1;
    create.samples = VK_SAMPLE_COUNT_1_BIT;
    create.tiling = VK_IMAGE_TILING_OPTIMAL;
    create.usage = usage;
    create.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
    check(vkCreateImage(ctx.device(), &create, nullptr, &i.image), "vkCreateImage");
    VkMemoryRequirements req;
    vkGetImageMemoryRequirements(ctx.device(), i.image, &req);
    VkMemoryAllocateInfo alloc{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
    alloc.allocationSize = req.size;
    alloc.memoryTypeIndex =
        ctx.memory_type(req.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
    check(vkAllocateMemory(ctx.device(), &alloc, nullptr, &i.memory), "vkAllocateMemory");
    check(vkBindImageMemory(ctx.device(), i.image, i.memory, 0), "vkBindImageMemory");
    VkImageViewCreateInfo view{VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO};
    view.image = i.image;
    view.viewType = VK_IMAGE_VIEW_TYPE_2D;
    view.format = format;
    view.subresourceRange = {aspect, 0, 1, 0, 1};
    check(vkCreateImageView(ctx.device(), &view, nullptr, &i.view), "vkCreateImageView");
    return i;
  }

  void upload(const TubeMesh& mesh) {
    attribute_range = mesh.attribute_range;
    const VkBufferUsageFlags vertex = VK_BUFFER_USAGE_VERTEX_BUFFER_BIT;
    for (const TubeChunk& chunk : mesh.chunks) {
      if (chunk.triangle_count() == 0) continue;
      ChunkBuffers b;
      const uint64_t n = chunk.vertex_count();
      b.positions = ctx.create_buffer(chunk.positions.bytes(), vertex, true);
      std::memcpy(b.positions.mapped, chunk.positions.data(), chunk.positions.bytes());
      b.normals = ctx.create_buffer(n * 12, vertex, true);
      auto* normals = static_cast<float*>(b.normals.mapped);
      for (uint64_t v = 0; v < n; ++v) {
        if (!chunk.normals.empty()) {
          for (int k = 0; k < 3; ++k) normals[3 * v + k] = chunk.normals[3 * v + k];
        } else {
          const auto d = decode_octahedral(chunk.normals_oct[2 * v], chunk.normals_oct[2 * v + 1]);
          for (int k = 0; k < 3; ++k) normals[3 * v + k] = d[size_t(k)];
        }
      }
      b.attribute = ctx.create_buffer(n * 2, vertex, true);
      if (chunk.attribute.empty())
        std::memset(b.attribute.mapped, 0, n * 2);
      else
        std::memcpy(b.attribute.mapped, chunk.attribute.data(), n * 2);
      b.indices = ctx.create_buffer(chunk.indices.bytes(), VK_BUFFER_USAGE_INDEX_BUFFER_BIT, true);
      std::memcpy(b.indices.mapped, chunk.indices.data(), chunk.indices.bytes());
      b.index_count = uint32_t(chunk.indices.size());
      mesh_bytes += b.positions.size + b.normals.size + b.attribute.size + b.indices.size;
      chunks.push_back(b);
    }
  }

  void create_layout() {
    VkDevice d = ctx.device();
    std::vector<VkDescriptorSetLayoutBinding> bindings;
    for (uint32_t i = 0; i <= 5; ++i)
      bindings.push_back(
          {i, i == 0 ? VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER : VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1,
           VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT | VK_SHADER_STAGE_COMPUTE_BIT,
           nullptr});
    VkDescriptorSetLayoutCreateInfo set_info{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
    set_info.bindingCount = uint32_t(bindings.size());
    set_info.pBindings = bindings.data();
    check(vkCreateDescriptorSetLayout(d, &set_info, nullptr, &set_layout), "descriptor layout");
    VkPipelineLayoutCreateInfo layout_info{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    layout_info.setLayoutCount = 1;
    layout_info.pSetLayouts = &set_layout;
    check(vkCreatePipelineLayout(d, &layout_info, nullptr, &layout), "pipeline layout");
    const VkDescriptorPoolSize sizes[] = {{VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1},
                                          {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 5}};
    VkDescriptorPoolCreateInfo pool_info{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
    pool_info.maxSets = 1;
    pool_info.poolSizeCount = 2;
    pool_info.pPoolSizes = sizes;
    check(vkCreateDescriptorPool(d, &pool_info, nullptr, &pool), "descriptor pool");
    VkDescriptorSetAllocateInfo alloc{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
    alloc.descriptorPool = pool;
    alloc.descriptorSetCount = 1;
    alloc.pSetLayouts = &set_layout;
    check(vkAllocateDescriptorSets(d, &alloc, &set), "descriptor set");
    if (ctx.timestamps()) {
      VkQueryPoolCreateInfo q{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
      q.queryType = VK_QUERY_TYPE_TIMESTAMP;
      q.queryCount = 4;
      check(vkCreateQueryPool(d, &q, nullptr, &queries), "query pool");
    }
  }

  // Tube pipeline: back faces culled, as the ray tracers reject back hits. The tube builder winds
  // triangles counter-clockwise seen from outside; with the y-flipped projection they stay
  // counter-clockwise in Vulkan's framebuffer terms (checked against the CPU reference's hits).
  VkPipeline make_graphics(const std::string& fragment, bool with_attachments) {
    VkDevice d = ctx.device();
    VkShaderModule vs = make_module(d, "tube.vert"), fs = make_module(d, fragment);
    VkPipelineShaderStageCreateInfo stages[2] = {
        {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO},
        {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO}};
    stages[0].stage = VK_SHADER_STAGE_VERTEX_BIT;
    stages[0].module = vs;
    stages[0].pName = "main";
    stages[1].stage = VK_SHADER_STAGE_FRAGMENT_BIT;
    stages[1].module = fs;
    stages[1].pName = "main";
    const VkVertexInputBindingDescription vertex_bindings[] = {{0, 12, VK_VERTEX_INPUT_RATE_VERTEX},
                                                               {1, 12, VK_VERTEX_INPUT_RATE_VERTEX},
                                                               {2, 2, VK_VERTEX_INPUT_RATE_VERTEX}};
    const VkVertexInputAttributeDescription attributes[] = {{0, 0, VK_FORMAT_R32G32B32_SFLOAT, 0},
                                                            {1, 1, VK_FORMAT_R32G32B32_SFLOAT, 0},
                                                            {2, 2, VK_FORMAT_R16_UNORM, 0}};
    VkPipelineVertexInputStateCreateInfo input{
        VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO};
    input.vertexBindingDescriptionCount = 3;
    input.pVertexBindingDescriptions = vertex_bindings;
    input.vertexAttributeDescriptionCount = 3;
    input.pVertexAttributeDescriptions = attributes;
    VkPipelineInputAssemblyStateCreateInfo assembly{
        VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO};
    assembly.topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST;
    VkPipelineViewportStateCreateInfo viewport{
        VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO};
    viewport.viewportCount = viewport.scissorCount = 1;
    VkPipelineRasterizationStateCreateInfo raster{
        VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO};
    raster.polygonMode = VK_POLYGON_MODE_FILL;
    raster.cullMode = VK_CULL_MODE_BACK_BIT;
    raster.frontFace = VK_FRONT_FACE_COUNTER_CLOCKWISE;
    raster.lineWidth = 1;
    VkPipelineMultisampleStateCreateInfo multisample{
        VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO};
    multisample.rasterizationSamples = VK_SAMPLE_COUNT_1_BIT;
    VkPipelineDepthStencilStateCreateInfo depth_state{
        VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO};
    depth_state.depthTestEnable = with_attachments;
    depth_state.depthWriteEnable = with_attachments;
    depth_state.depthCompareOp = VK_COMPARE_OP_LESS;
    VkPipelineColorBlendAttachmentState blend_attachment{};
    blend_attachment.colorWriteMask = VK_COLOR_COMPONENT_R_BIT | VK_COLOR_COMPONENT_G_BIT |
                                      VK_COLOR_COMPONENT_B_BIT | VK_COLOR_COMPONENT_A_BIT;
    VkPipelineColorBlendStateCreateInfo blend{
        VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO};
    blend.attachmentCount = with_attachments ? 1 : 0;
    blend.pAttachments = &blend_attachment;
    const VkDynamicState dynamic_states[] = {VK_DYNAMIC_STATE_VIEWPORT, VK_DYNAMIC_STATE_SCISSOR};
    VkPipelineDynamicStateCreateInfo dynamic{VK_STRUCTURE_TYPE_PIPELINE_DYNAMIC_STATE_CREATE_INFO};
    dynamic.dynamicStateCount = 2;
    dynamic.pDynamicStates = dynamic_states;
    const VkFormat colour_format = VK_FORMAT_R32G32B32A32_SFLOAT;
    VkPipelineRenderingCreateInfo rendering{VK_STRUCTURE_TYPE_PIPELINE_RENDERING_CREATE_INFO};
    if (with_attachments) {
      rendering.colorAttachmentCount = 1;
      rendering.pColorAttachmentFormats = &colour_format;
      rendering.depthAttachmentFormat = VK_FORMAT_D32_SFLOAT;
    }
    VkGraphicsPipelineCreateInfo create{VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO};
    create.pNext = &rendering;
    create.stageCount = 2;
    create.pStages = stages;
    create.pVertexInputState = &input;
    create.pInputAssemblyState = &assembly;
    create.pViewportState = &viewport;
    create.pRasterizationState = &raster;
    create.pMultisampleState = &multisample;
    create.pDepthStencilState = &depth_state;
    create.pColorBlendState = &blend;
    create.pDynamicState = &dynamic;
    create.layout = layout;
    VkPipeline pipeline;
    const VkResult r = vkCreateGraphicsPipelines(d, VK_NULL_HANDLE, 1, &create, nullptr, &pipeline);
    vkDestroyShaderModule(d, vs, nullptr);
    vkDestroyShaderModule(d, fs, nullptr);
    check(r, "vkCreateGraphicsPipelines");
    return pipeline;
  }

  void make_resolve(uint32_t max_fragments, ListSort sort) {
    VkDevice d = ctx.device();
    if (resolve) vkDestroyPipeline(d, resolve, nullptr);
    resolve = VK_NULL_HANDLE;
    VkShaderModule cs = make_module(d, "ll_resolve.comp");
    const uint32_t constants[2] = {max_fragments, uint32_t(sort)};
    const VkSpecializationMapEntry entries[2] = {{0, 0, 4}, {1, 4, 4}};
    VkSpecializationInfo spec{2, entries, sizeof constants, constants};
    VkComputePipelineCreateInfo create{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
    create.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
    create.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
    create.stage.module = cs;
    create.stage.pName = "main";
    create.stage.pSpecializationInfo = &spec;
    create.layout = layout;
    const VkResult r = vkCreateComputePipelines(d, VK_NULL_HANDLE, 1, &create, nullptr, &resolve);
    vkDestroyShaderModule(d, cs, nullptr);
    check(r, "vkCreateComputePipelines");
    resolve_max = max_fragments;
    resolve_sort = sort;
  }

  void write_descriptors() {
    const Buffer* buffers[6] = {&uniforms, &heads, &nodes, &counter, &output, &stats};
    VkDescriptorBufferInfo infos[6];
    VkWriteDescriptorSet writes[6];
    for (uint32_t i = 0; i < 6; ++i) {
      infos[i] = {buffers[i]->buffer, 0, VK_WHOLE_SIZE};
      writes[i] = {VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
      writes[i].dstSet = set;
      writes[i].dstBinding = i;
      writes[i].descriptorCount = 1;
      writes[i].descriptorType =
          i == 0 ? VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER : VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
      writes[i].pBufferInfo = &infos[i];
    }
    vkUpdateDescriptorSets(ctx.device(), 6, writes, 0, nullptr);
  }

  // (Re)allocates what a frame of this size and node capacity needs.
  void prepare_frame(int w, int h, uint64_t nodes_wanted) {
    if (w == width && h == height && nodes_wanted == capacity) return;
    VkPhysicalDeviceProperties props;
    vkGetPhysicalDeviceProperties(ctx.physical_device(), &props);
    const uint64_t limit = props.limits.maxStorageBufferRange;
    if (nodes_wanted * kNodeBytes > limit)
      throw Error("ll: the frame needs " + std::to_string(nodes_wanted) + " fragment nodes (" +
                  std::to_string(nodes_wanted * kNodeBytes >> 20) + " MiB), more than one " +
                  "storage buffer may hold on " + ctx.info().name + " (" +
                  std::to_string(limit >> 20) + " MiB); render a smaller size");
    vkDeviceWaitIdle(ctx.device());
    release_frame();
    width = w, height = h, capacity = nodes_wanted;
    const uint64_t pixels = uint64_t(w) * uint64_t(h);
    const VkBufferUsageFlags storage =
        VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
    uniforms = ctx.create_buffer(sizeof(FrameUniforms), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, true);
    heads = ctx.create_buffer(pixels * 4, storage, false);
    nodes = ctx.create_buffer(std::max<uint64_t>(capacity, 1) * kNodeBytes, storage, false);
    counter = ctx.create_buffer(4, storage, true);
    output = ctx.create_buffer(pixels * 16, storage, true);
    stats = ctx.create_buffer(4 + pixels * 4, storage, true);
    colour = make_image(VK_FORMAT_R32G32B32A32_SFLOAT,
                        VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT,
                        VK_IMAGE_ASPECT_COLOR_BIT);
    depth = make_image(VK_FORMAT_D32_SFLOAT, VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT,
                       VK_IMAGE_ASPECT_DEPTH_BIT);
    readback = ctx.create_buffer(pixels * 16, VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
    write_descriptors();
  }

  void fill_uniforms(const Camera& camera, const TransferFunction& tf_in, const RasterOptions& o) {
    FrameUniforms u{};
    const double aspect = double(o.width) / double(o.height);
    glm::dmat4 projection =
        glm::perspectiveRH_ZO(glm::radians(camera.fov_y_degrees), aspect, camera.near, camera.far);
    projection[1][1] *= -1;  // Vulkan's framebuffer y points down, like image rows
    const glm::dmat4 vp = projection * glm::lookAtRH(camera.eye, camera.target, camera.up);
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) u.view_projection[4 * c + r] = float(vp[c][r]);
    u.eye[0] = float(camera.eye.x), u.eye[1] = float(camera.eye.y), u.eye[2] = float(camera.eye.z);
    const Shading& s = o.shading;
    u.shading[0] = float(s.ambient), u.shading[1] = float(s.diffuse);
    u.shading[2] = float(s.specular), u.shading[3] = float(s.shininess);
    for (int k = 0; k < 3; ++k) u.background[k] = float(s.background[size_t(k)]);
    TransferFunction tf = tf_in;
    if (tf.range[0] == 0 && tf.range[1] == 0) tf.range = {attribute_range[0], attribute_range[1]};
    u.ranges[0] = attribute_range[0], u.ranges[1] = attribute_range[1];
    u.ranges[2] = float(tf.range[0]), u.ranges[3] = float(tf.range[1]);
    u.size[0] = uint32_t(o.width), u.size[1] = uint32_t(o.height);
    u.size[2] = uint32_t(std::min<uint64_t>(capacity, 0xFFFFFFFFu));
    if (tf.colours.empty() || tf.opacities.empty() || tf.colours.size() > kMaxTfPoints ||
        tf.opacities.size() > kMaxTfPoints)
      throw Error("transfer function '" + tf.name + "': 1 to " + std::to_string(kMaxTfPoints) +
                  " colour and opacity points for the GPU techniques");
    u.tf_counts[0] = uint32_t(tf.colours.size()), u.tf_counts[1] = uint32_t(tf.opacities.size());
    u.tf_counts[2] = o.early_termination ? 1u : 0u;
    u.termination[0] = float(o.termination_alpha);
    for (size_t i = 0; i < tf.colours.size(); ++i) {
      u.colours[i][0] = float(tf.colours[i].x);
      for (int k = 0; k < 3; ++k) u.colours[i][k + 1] = float(tf.colours[i].srgb[size_t(k)]);
    }
    for (size_t i = 0; i < tf.opacities.size(); ++i) {
      u.opacities[i][0] = float(tf.opacities[i].x);
      u.opacities[i][1] = float(tf.opacities[i].opacity);
    }
    std::memcpy(uniforms.mapped, &u, sizeof u);
  }

  void draw_chunks(VkCommandBuffer cmd, VkPipeline pipeline) {
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, layout, 0, 1, &set, 0, nullptr);
    const VkViewport viewport{0, 0, float(width), float(height), 0, 1};
    const VkRect2D scissor{{0, 0}, {uint32_t(width), uint32_t(height)}};
    vkCmdSetViewport(cmd, 0, 1, &viewport);
    vkCmdSetScissor(cmd, 0, 1, &scissor);
    for (const ChunkBuffers& c : chunks) {
      const VkBuffer vbs[3] = {c.positions.buffer, c.normals.buffer, c.attribute.buffer};
      const VkDeviceSize offsets[3] = {0, 0, 0};
      vkCmdBindVertexBuffers(cmd, 0, 3, vbs, offsets);
      vkCmdBindIndexBuffer(cmd, c.indices.buffer, 0, VK_INDEX_TYPE_UINT32);
      vkCmdDrawIndexed(cmd, c.index_count, 1, 0, 0, 0);
    }
  }

  void timestamp(VkCommandBuffer cmd, uint32_t i, VkPipelineStageFlagBits stage) {
    if (queries) vkCmdWriteTimestamp(cmd, stage, queries, i);
  }

  std::vector<double> read_timestamps(uint32_t count) {
    std::vector<double> ms;
    if (!queries) return ms;
    uint64_t ticks[4] = {};
    if (vkGetQueryPoolResults(ctx.device(), queries, 0, count, sizeof ticks, ticks, 8,
                              VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT) != VK_SUCCESS)
      return ms;
    for (uint32_t i = 1; i < count; ++i)
      ms.push_back(double(ticks[i] - ticks[i - 1]) * ctx.timestamp_period_ns() * 1e-6);
    return ms;
  }

  void render_opaque(RasterFrame& frame) {
    ctx.submit([&](VkCommandBuffer cmd) {
      if (queries) vkCmdResetQueryPool(cmd, queries, 0, 4);
      image_barrier(cmd, colour.image, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                    VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, 0,
                    VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT,
                    VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT);
      image_barrier(cmd, depth.image, VK_IMAGE_ASPECT_DEPTH_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                    VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, 0,
                    VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT,
                    VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT);
      timestamp(cmd, 0, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT);
      const auto* bg = reinterpret_cast<const FrameUniforms*>(uniforms.mapped)->background;
      VkRenderingAttachmentInfo colour_attachment{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
      colour_attachment.imageView = colour.view;
      colour_attachment.imageLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
      colour_attachment.loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
      colour_attachment.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
      colour_attachment.clearValue.color = {{bg[0], bg[1], bg[2], 0}};
      VkRenderingAttachmentInfo depth_attachment{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
      depth_attachment.imageView = depth.view;
      depth_attachment.imageLayout = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL;
      depth_attachment.loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
      depth_attachment.storeOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
      depth_attachment.clearValue.depthStencil = {1, 0};
      VkRenderingInfo info{VK_STRUCTURE_TYPE_RENDERING_INFO};
      info.renderArea = {{0, 0}, {uint32_t(width), uint32_t(height)}};
      info.layerCount = 1;
      info.colorAttachmentCount = 1;
      info.pColorAttachments = &colour_attachment;
      info.pDepthAttachment = &depth_attachment;
      vkCmdBeginRendering(cmd, &info);
      draw_chunks(cmd, opaque);
      vkCmdEndRendering(cmd);
      timestamp(cmd, 1, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT);
      image_barrier(cmd, colour.image, VK_IMAGE_ASPECT_COLOR_BIT,
                    VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                    VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT,
                    VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                    VK_ACCESS_TRANSFER_READ_BIT);
      VkBufferImageCopy copy{};
      copy.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
      copy.imageExtent = {uint32_t(width), uint32_t(height), 1};
      vkCmdCopyImageToBuffer(cmd, colour.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                             readback.buffer, 1, &copy);
      barrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
              VK_PIPELINE_STAGE_HOST_BIT, VK_ACCESS_HOST_READ_BIT);
    });
    const auto ms = read_timestamps(2);
    if (!ms.empty()) frame.stats.pass_ms = {{"draw", ms[0]}};
    copy_pixels(static_cast<const float*>(readback.mapped), frame);
  }

  void copy_pixels(const float* rgba, RasterFrame& frame) {
    for (int y = 0; y < height; ++y)
      for (int x = 0; x < width; ++x)
        for (int k = 0; k < 3; ++k)
          frame.image.at(x, y, k) = rgba[4 * (size_t(y) * size_t(width) + size_t(x)) + size_t(k)];
  }

  // Gather and resolve in one submission; returns the nodes the frame needed.
  uint32_t gather_and_resolve() {
    ctx.submit([&](VkCommandBuffer cmd) {
      if (queries) vkCmdResetQueryPool(cmd, queries, 0, 4);
      timestamp(cmd, 0, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT);
      vkCmdFillBuffer(cmd, heads.buffer, 0, VK_WHOLE_SIZE, kEmptyList);
      vkCmdFillBuffer(cmd, counter.buffer, 0, VK_WHOLE_SIZE, 0);
      vkCmdFillBuffer(cmd, stats.buffer, 0, VK_WHOLE_SIZE, 0);
      barrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
              VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT | VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
              VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT);
      timestamp(cmd, 1, VK_PIPELINE_STAGE_TRANSFER_BIT);
      VkRenderingInfo info{VK_STRUCTURE_TYPE_RENDERING_INFO};
      info.renderArea = {{0, 0}, {uint32_t(width), uint32_t(height)}};
      info.layerCount = 1;
      vkCmdBeginRendering(cmd, &info);
      draw_chunks(cmd, gather);
      vkCmdEndRendering(cmd);
      timestamp(cmd, 2, VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT);
      barrier(cmd, VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT, VK_ACCESS_SHADER_WRITE_BIT,
              VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_HOST_BIT,
              VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_HOST_READ_BIT);
      record_resolve(cmd);
      timestamp(cmd, 3, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT);
    });
    return *static_cast<const uint32_t*>(counter.mapped);
  }

  void record_resolve(VkCommandBuffer cmd) {
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, resolve);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout, 0, 1, &set, 0, nullptr);
    vkCmdDispatch(cmd, uint32_t(width + 7) / 8, uint32_t(height + 7) / 8, 1);
    barrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_WRITE_BIT,
            VK_PIPELINE_STAGE_HOST_BIT, VK_ACCESS_HOST_READ_BIT);
  }

  void render_lists(const Camera& camera, const TransferFunction& tf, const RasterOptions& o,
                    RasterFrame& frame) {
    if (!gather) gather = make_graphics("ll_gather.frag", false);
    if (!resolve || resolve_sort != o.sort) make_resolve(std::max(resolve_max, 64u), o.sort);
    uint64_t needed = gather_and_resolve();
    // Overflow: grow the node buffer to what the frame needed and render it again.
    while (needed > capacity) {
      if (needed >= 0xFFFFFFFFull / 2)
        throw Error("ll: more than 2^31 fragments in one frame; use a smaller size");
      prepare_frame(width, height, needed + needed / 8);
      fill_uniforms(camera, tf, o);
      ++frame.stats.regrows;
      needed = gather_and_resolve();
    }
    const auto ms = read_timestamps(4);
    if (!ms.empty())
      frame.stats.pass_ms = {{"clear", ms[0]}, {"gather", ms[1]}, {"resolve", ms[2]}};
    // Lists longer than the resolve's local arrays: resolve again with room for them.
    const uint32_t longest = *static_cast<const uint32_t*>(stats.mapped);
    if (longest > resolve_max) {
      make_resolve(uint32_t(next_power_of_two(longest)), o.sort);
      ctx.submit([&](VkCommandBuffer cmd) { record_resolve(cmd); });
    }
    frame.stats.fragments = needed;
    const auto* counts = static_cast<const uint32_t*>(stats.mapped) + 1;
    frame.depth_complexity.assign(counts, counts + size_t(width) * size_t(height));
    copy_pixels(static_cast<const float*>(output.mapped), frame);
  }
};

RasterRenderer::RasterRenderer(Context& context, const TubeMesh& mesh)
    : state_(std::make_unique<State>(context)) {
  state_->upload(mesh);
  state_->create_layout();
}

RasterRenderer::~RasterRenderer() = default;

uint64_t RasterRenderer::mesh_bytes() const {
  return state_->mesh_bytes;
}

RasterFrame RasterRenderer::render(const Camera& camera, const TransferFunction& tf,
                                   const RasterOptions& o) {
  if (o.width < 1 || o.height < 1) throw Error("render: empty image size");
  const auto start = std::chrono::steady_clock::now();
  State& s = *state_;
  const uint64_t pixels = uint64_t(o.width) * uint64_t(o.height);
  uint64_t capacity = o.capacity;
  if (o.technique == RasterTechnique::LinkedLists) {
    if (capacity == 0) capacity = uint64_t(std::ceil(o.expected_depth_complexity * double(pixels)));
    // Keep a larger buffer from an earlier frame of this size.
    if (o.capacity == 0 && s.width == o.width && s.height == o.height)
      capacity = std::max(capacity, s.capacity);
  } else {
    capacity = 1;
  }
  s.prepare_frame(o.width, o.height, capacity);
  s.fill_uniforms(camera, tf, o);
  RasterFrame frame;
  frame.image = Image(o.width, o.height, 3);
  if (o.technique == RasterTechnique::Opaque) {
    if (!s.opaque) s.opaque = s.make_graphics("opaque.frag", true);
    s.render_opaque(frame);
    frame.stats.frame_bytes = pixels * (16 + 4);  // colour + depth attachments
  } else {
    s.render_lists(camera, tf, o, frame);
    frame.stats.frame_bytes = pixels * 4 + s.capacity * kNodeBytes + 4 + pixels * 16;
    frame.stats.capacity = s.capacity;
    uint64_t total = 0;
    for (uint32_t d : frame.depth_complexity) {
      frame.stats.max_depth_complexity = std::max(frame.stats.max_depth_complexity, d);
      total += d;
    }
    frame.stats.mean_depth_complexity = double(total) / double(pixels);
  }
  frame.stats.seconds = seconds_since(start);
  return frame;
}

}  // namespace linebake::vk
