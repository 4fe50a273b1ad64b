#include "render/vulkan/raster_renderer.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <glm/gtc/matrix_transform.hpp>

#include "core/error.hpp"
#include "core/measure.hpp"
#include "render/vulkan/buffer_set.hpp"
#include "render/vulkan/raster_state.hpp"
#include "render/vulkan/shaders.hpp"
#include "render/vulkan/transfer_table.hpp"

namespace linebake::vk {
namespace {

void image_barrier(VkCommandBuffer cmd, VkImage image, VkImageAspectFlags aspect,
                   VkImageLayout from, VkImageLayout to, VkAccessFlags dst) {
  VkImageMemoryBarrier b{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER};
  b.oldLayout = from;
  b.newLayout = to;
  b.srcAccessMask = VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT;
  b.dstAccessMask = dst;
  b.srcQueueFamilyIndex = b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  b.image = image;
  b.subresourceRange = {aspect, 0, 1, 0, 1};
  vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT,
                       0, 0, nullptr, 0, nullptr, 1, &b);
}

std::string pipeline_key(const std::string& name, const std::vector<uint32_t>& constants) {
  std::string key = name;
  for (uint32_t c : constants) key += ":" + std::to_string(c);
  return key;
}

// Specialisation constants 0, 1, ... of one stage.
struct Specialisation {
  std::vector<VkSpecializationMapEntry> entries;
  VkSpecializationInfo info{};
  explicit Specialisation(const std::vector<uint32_t>& constants) {
    for (uint32_t i = 0; i < constants.size(); ++i) entries.push_back({i, 4 * i, 4});
    info = {uint32_t(entries.size()), entries.data(), constants.size() * 4, constants.data()};
  }
};

constexpr double kPi = 3.14159265358979323846;

// Monotonic along the unit circle from angle 0, as shaders/moments.glsl's circle_parameter().
double circle_parameter(double angle) {
  const double x = std::cos(angle), y = std::sin(angle);
  double r = std::abs(y) - std::abs(x);
  if (x < 0) r = 2 - r;
  if (y < 0) r = 6 - r;
  return r;
}

const char* const kTechniqueNames[] = {"opaque", "dp", "ll", "mlab", "mlabdb", "mboit", "wboit"};

}  // namespace

RasterTechnique parse_raster_technique(const std::string& name) {
  for (int i = 0; i < 7; ++i)
    if (name == kTechniqueNames[i]) return RasterTechnique(i);
  throw Error("unknown rasterisation technique '" + name +
              "' (opaque, dp, ll, mlab, mlabdb, mboit, wboit)");
}

bool is_raster_technique(const std::string& name) {
  return std::find(std::begin(kTechniqueNames), std::end(kTechniqueNames), name) !=
         std::end(kTechniqueNames);
}

const char* to_string(RasterTechnique t) {
  return kTechniqueNames[int(t)];
}

ListSort parse_list_sort(const std::string& name) {
  if (name == "insertion") return ListSort::Insertion;
  if (name == "shell") return ListSort::Shell;
  if (name == "heap") return ListSort::Heap;
  if (name == "quick-hybrid") return ListSort::QuickHybrid;
  throw Error("unknown linked-list sort '" + name + "' (insertion, shell, heap, quick-hybrid)");
}

MomentBasis parse_moment_basis(const std::string& name) {
  if (name == "power") return MomentBasis::Power;
  if (name == "trigonometric") return MomentBasis::Trigonometric;
  throw Error("unknown moment basis '" + name + "' (power, trigonometric)");
}

const char* to_string(MomentBasis basis) {
  return basis == MomentBasis::Power ? "power" : "trigonometric";
}

double default_moment_bias(MomentBasis basis, int moments) {
  const bool power = basis == MomentBasis::Power;
  if (moments <= 4) return power ? 5e-7 : 4e-7;
  if (moments <= 6) return power ? 5e-6 : 8e-6;
  return power ? 5e-5 : 1.5e-5;
}

const char* to_string(ListSort s) {
  switch (s) {
    case ListSort::Insertion:
      return "insertion";
    case ListSort::Shell:
      return "shell";
    case ListSort::Heap:
      return "heap";
    case ListSort::QuickHybrid:
      return "quick-hybrid";
  }
  return "?";
}

void barrier_all(VkCommandBuffer cmd) {
  VkMemoryBarrier b{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  b.srcAccessMask = VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT;
  b.dstAccessMask =
      VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT | VK_ACCESS_HOST_READ_BIT;
  vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT,
                       VK_PIPELINE_STAGE_ALL_COMMANDS_BIT | VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &b, 0,
                       nullptr, 0, nullptr);
}

RasterRenderer::State::~State() {
  VkDevice d = ctx.device();
  vkDeviceWaitIdle(d);
  for (ChunkBuffers& c : chunks)
    for (Buffer* b : {&c.positions, &c.normals, &c.attribute, &c.indices}) ctx.destroy(*b);
  release_frame();
  for (auto& [name, p] : pipelines) vkDestroyPipeline(d, p, nullptr);
  if (queries) vkDestroyQueryPool(d, queries, nullptr);
  if (pool) vkDestroyDescriptorPool(d, pool, nullptr);
  if (layout) vkDestroyPipelineLayout(d, layout, nullptr);
  if (set_layout) vkDestroyDescriptorSetLayout(d, set_layout, nullptr);
}

void RasterRenderer::State::destroy_image(Image2D& i) {
  VkDevice d = ctx.device();
  if (i.view) vkDestroyImageView(d, i.view, nullptr);
  if (i.image) vkDestroyImage(d, i.image, nullptr);
  ctx.free_memory(i.memory, i.host_bytes);
  i = Image2D{};
}

void RasterRenderer::State::release_frame() {
  for (Buffer* b : {&uniforms, &pixel_state, &nodes}) ctx.destroy(*b);
  for (ResultBuffer* b : {&counter, &output, &stats}) ctx.destroy(*b);
  for (Image2D* i : {&colour, &scalar, &colour2, &depth}) destroy_image(*i);
  release_pages();
  width = height = 0;
  pixel_state_bytes = node_bytes = 0;
}

Image2D RasterRenderer::State::make_image(VkFormat format, VkImageUsageFlags usage,
                                          VkImageAspectFlags aspect) {
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
  alloc.memoryTypeIndex = ctx.memory_type(req.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
  try {
    i.memory = ctx.allocate_memory(alloc, i.host_bytes);
    check(vkBindImageMemory(ctx.device(), i.image, i.memory, 0), "vkBindImageMemory");
  } catch (...) {
    destroy_image(i);
    throw;
  }
  VkImageViewCreateInfo view{VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO};
  view.image = i.image;
  view.viewType = VK_IMAGE_VIEW_TYPE_2D;
  view.format = format;
  view.subresourceRange = {aspect, 0, 1, 0, 1};
  check(vkCreateImageView(ctx.device(), &view, nullptr, &i.view), "vkCreateImageView");
  return i;
}

void RasterRenderer::State::upload(const TubeChunk& chunk) {
  include_points(bounds, std::span<const float>(chunk.positions.data(), chunk.positions.size()));
  if (chunk.triangle_count() == 0) return;
  const VkBufferUsageFlags vertex = VK_BUFFER_USAGE_VERTEX_BUFFER_BIT;
  // In the list before its buffers, so that the destructor frees them if one is refused.
  ChunkBuffers& b = chunks.emplace_back();
  const uint64_t n = chunk.vertex_count();
  // Device-local, filled piece by piece (Context::create_filled): every pass reads the mesh.
  b.positions = ctx.upload(chunk.positions.data(), chunk.positions.bytes(), vertex);
  b.normals = ctx.create_filled(n * 12, vertex, [&](void* dst, uint64_t offset, uint64_t count) {
    auto* out = static_cast<float*>(dst);
    for (uint64_t f = offset / 4; f < (offset + count) / 4; ++f) {
      const uint64_t v = f / 3, k = f % 3;
      if (!chunk.normals.empty()) {
        *out++ = chunk.normals[f];
      } else {
        const auto d = decode_octahedral(chunk.normals_oct[2 * v], chunk.normals_oct[2 * v + 1]);
        *out++ = d[size_t(k)];
      }
    }
  });
  if (chunk.attribute.empty())
    b.attribute = ctx.create_filled(
        n * 2, vertex, [](void* dst, uint64_t, uint64_t count) { std::memset(dst, 0, count); });
  else
    b.attribute = ctx.upload(chunk.attribute.data(), n * 2, vertex);
  b.indices =
      ctx.upload(chunk.indices.data(), chunk.indices.bytes(), VK_BUFFER_USAGE_INDEX_BUFFER_BIT);
  b.index_count = uint32_t(chunk.indices.size());
  mesh_bytes += b.positions.size + b.normals.size + b.attribute.size + b.indices.size;
}

void RasterRenderer::State::create_layout() {
  VkDevice d = ctx.device();
  const BufferSet b = create_buffer_set(
      d, kBindings,
      VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT | VK_SHADER_STAGE_COMPUTE_BIT,
      {kPages});
  set_layout = b.set_layout, layout = b.layout, pool = b.pool, set = b.set;
  if (ctx.timestamps()) {
    VkQueryPoolCreateInfo q{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
    q.queryType = VK_QUERY_TYPE_TIMESTAMP;
    q.queryCount = kQueries;
    check(vkCreateQueryPool(d, &q, nullptr, &queries), "query pool");
  }
}

// Tube pipelines cull back faces, as the ray tracers reject back hits. The tube builder winds
// triangles counter-clockwise seen from outside; with the y-flipped projection they stay
// counter-clockwise in Vulkan's framebuffer terms (checked against the CPU reference's hits).
VkPipeline RasterRenderer::State::graphics(const DrawSetup& setup) {
  const std::string key = pipeline_key(setup.fragment + "/" + std::to_string(setup.targets) +
                                           (setup.depth ? "d" : "") + (setup.additive ? "+" : ""),
                                       setup.constants);
  if (auto it = pipelines.find(key); it != pipelines.end()) return it->second;
  const VkFormat formats[3] = {VK_FORMAT_R32G32B32A32_SFLOAT, VK_FORMAT_R32_SFLOAT,
                               VK_FORMAT_R32G32B32A32_SFLOAT};
  if (setup.additive)
    for (uint32_t t = 0; t < setup.targets; ++t) {
      VkFormatProperties props;
      vkGetPhysicalDeviceFormatProperties(ctx.physical_device(), formats[t], &props);
      if (!(props.optimalTilingFeatures & VK_FORMAT_FEATURE_COLOR_ATTACHMENT_BLEND_BIT))
        throw Error(setup.fragment + ": " + ctx.info().name +
                    " cannot blend 32-bit float colour attachments");
    }
  VkDevice d = ctx.device();
  VkShaderModule vs = create_shader_module(d, "tube.vert"),
                 fs = create_shader_module(d, setup.fragment);
  const Specialisation spec(setup.constants);
  VkPipelineShaderStageCreateInfo stages[2] = {
      {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO},
      {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO}};
  stages[0].stage = VK_SHADER_STAGE_VERTEX_BIT;
  stages[0].module = vs;
  stages[0].pName = "main";
  stages[1].stage = VK_SHADER_STAGE_FRAGMENT_BIT;
  stages[1].module = fs;
  stages[1].pName = "main";
  stages[1].pSpecializationInfo = &spec.info;
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
  VkPipelineViewportStateCreateInfo viewport{VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO};
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
  depth_state.depthTestEnable = setup.depth;
  depth_state.depthWriteEnable = setup.depth;
  depth_state.depthCompareOp = VK_COMPARE_OP_LESS;
  VkPipelineColorBlendAttachmentState blend_attachments[3] = {};
  for (VkPipelineColorBlendAttachmentState& b : blend_attachments) {
    b.colorWriteMask = VK_COLOR_COMPONENT_R_BIT | VK_COLOR_COMPONENT_G_BIT |
                       VK_COLOR_COMPONENT_B_BIT | VK_COLOR_COMPONENT_A_BIT;
    b.blendEnable = setup.additive;
    b.srcColorBlendFactor = b.dstColorBlendFactor = VK_BLEND_FACTOR_ONE;
    b.srcAlphaBlendFactor = b.dstAlphaBlendFactor = VK_BLEND_FACTOR_ONE;
    b.colorBlendOp = b.alphaBlendOp = VK_BLEND_OP_ADD;
  }
  VkPipelineColorBlendStateCreateInfo blend{
      VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO};
  blend.attachmentCount = setup.targets;
  blend.pAttachments = blend_attachments;
  const VkDynamicState dynamic_states[] = {VK_DYNAMIC_STATE_VIEWPORT, VK_DYNAMIC_STATE_SCISSOR};
  VkPipelineDynamicStateCreateInfo dynamic{VK_STRUCTURE_TYPE_PIPELINE_DYNAMIC_STATE_CREATE_INFO};
  dynamic.dynamicStateCount = 2;
  dynamic.pDynamicStates = dynamic_states;
  VkPipelineRenderingCreateInfo rendering{VK_STRUCTURE_TYPE_PIPELINE_RENDERING_CREATE_INFO};
  rendering.colorAttachmentCount = setup.targets;
  rendering.pColorAttachmentFormats = formats;
  if (setup.depth) rendering.depthAttachmentFormat = VK_FORMAT_D32_SFLOAT;
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
  pipelines[key] = pipeline;
  return pipeline;
}

VkPipeline RasterRenderer::State::compute(const std::string& name,
                                          const std::vector<uint32_t>& constants) {
  const std::string key = pipeline_key(name, constants);
  if (auto it = pipelines.find(key); it != pipelines.end()) return it->second;
  const Specialisation spec(constants);
  const VkPipeline pipeline = create_compute_pipeline(ctx.device(), layout, name, &spec.info);
  pipelines[key] = pipeline;
  return pipeline;
}

void RasterRenderer::State::write_descriptors() {
  write_buffer_set(ctx.device(), set,
                   {&uniforms, &pixel_state, &nodes, &counter.gpu, &output.gpu, &stats.gpu});
  // Pages the pool does not use point at the counter: bound, never read.
  std::vector<const Buffer*> bound;
  for (uint32_t i = 0; i < kPages; ++i)
    bound.push_back(i < pages.size() ? &pages[i] : &counter.gpu);
  write_buffer_array(ctx.device(), set, kBindings, bound);
}

void RasterRenderer::State::release_pages() {
  for (Buffer& b : pages) ctx.destroy(b);
  pages.clear();
  page_units = pool_units = list_capacity = 0;
}

void RasterRenderer::State::prepare_pages(uint64_t units, uint32_t unit_bytes,
                                          uint64_t max_buffer_bytes, const char* technique) {
  VkPhysicalDeviceProperties props;
  vkGetPhysicalDeviceProperties(ctx.physical_device(), &props);
  uint64_t limit = props.limits.maxStorageBufferRange;
  if (max_buffer_bytes > 0) limit = std::min(limit, max_buffer_bytes);
  // A power of two of whole units per page (the shaders shift instead of dividing), at most 2^31.
  uint64_t per_page = 0;
  for (uint64_t p = 1; p <= limit / unit_bytes && p <= (uint64_t{1} << 31); p <<= 1) per_page = p;
  if (per_page == 0)
    throw Error(std::string(technique) + ": a storage buffer must hold at least one node");
  units = std::max<uint64_t>(units, 1);
  const uint64_t count = (units + per_page - 1) / per_page;
  if (count > kPages)
    throw Error(std::string(technique) + ": the frame needs " +
                std::to_string(units * unit_bytes >> 20) + " MiB of nodes, more than " +
                std::to_string(kPages) + " storage buffers of " + std::to_string(limit >> 20) +
                " MiB hold on " + ctx.info().name + "; render a smaller size" +
                (std::string(technique) == "ll" && unit_bytes == 24
                     ? " or use 12-byte nodes (--node-bytes 12)"
                     : ""));
  if (unit_bytes == page_unit_bytes && per_page == page_units && units <= pool_units) return;
  vkDeviceWaitIdle(ctx.device());
  const uint64_t keep_capacity = list_capacity;
  release_pages();
  list_capacity = keep_capacity;
  const VkBufferUsageFlags storage =
      VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
  for (uint64_t first = 0; first < units; first += per_page)
    pages.push_back(
        ctx.create_buffer(std::min(per_page, units - first) * unit_bytes, storage, false));
  page_units = per_page;
  page_unit_bytes = unit_bytes;
  pool_units = units;
  write_descriptors();
}

void RasterRenderer::State::fill_pages(VkCommandBuffer cmd, uint64_t first, uint64_t count,
                                       uint32_t word) {
  for (uint64_t p = first / page_units; count > 0 && p < pages.size(); ++p) {
    const uint64_t begin = first - p * page_units;
    const uint64_t n = std::min(count, page_units - begin);
    vkCmdFillBuffer(cmd, pages[p].buffer, begin * page_unit_bytes, n * page_unit_bytes, word);
    first += n, count -= n;
  }
}

void RasterRenderer::State::prepare_frame(int w, int h, uint64_t pixel_state_wanted,
                                          uint64_t nodes_wanted, const char* technique) {
  pixel_state_wanted = std::max<uint64_t>(pixel_state_wanted, 4);
  nodes_wanted = std::max<uint64_t>(nodes_wanted, 4);
  if (w == width && h == height && pixel_state_wanted <= pixel_state_bytes &&
      nodes_wanted <= node_bytes)
    return;
  VkPhysicalDeviceProperties props;
  vkGetPhysicalDeviceProperties(ctx.physical_device(), &props);
  const uint64_t limit = props.limits.maxStorageBufferRange;
  if (nodes_wanted > limit || pixel_state_wanted > limit)
    throw Error(std::string(technique) + ": the frame needs a " +
                std::to_string(std::max(nodes_wanted, pixel_state_wanted) >> 20) +
                " MiB storage buffer, more than one may hold on " + ctx.info().name + " (" +
                std::to_string(limit >> 20) + " MiB); render a smaller size");
  // Keep what the other buffer already had at this size, so switching techniques does not thrash.
  if (w == width && h == height) {
    pixel_state_wanted = std::max(pixel_state_wanted, pixel_state_bytes);
    nodes_wanted = std::max(nodes_wanted, node_bytes);
  }
  vkDeviceWaitIdle(ctx.device());
  release_frame();
  width = w, height = h;
  pixel_state_bytes = pixel_state_wanted, node_bytes = nodes_wanted;
  const VkBufferUsageFlags storage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
                                     VK_BUFFER_USAGE_TRANSFER_DST_BIT |
                                     VK_BUFFER_USAGE_TRANSFER_SRC_BIT;
  uniforms = ctx.create_buffer(sizeof(FrameUniforms), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, true);
  pixel_state = ctx.create_buffer(pixel_state_bytes, storage, false);
  nodes = ctx.create_buffer(node_bytes, storage, false);
  counter = ctx.create_result(4, storage);
  output = ctx.create_result(pixels() * 16, storage);
  stats = ctx.create_result(4 + pixels() * 4, storage);
  const VkImageUsageFlags target =
      VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
  colour = make_image(VK_FORMAT_R32G32B32A32_SFLOAT, target, VK_IMAGE_ASPECT_COLOR_BIT);
  scalar = make_image(VK_FORMAT_R32_SFLOAT, target, VK_IMAGE_ASPECT_COLOR_BIT);
  colour2 = make_image(VK_FORMAT_R32G32B32A32_SFLOAT, target, VK_IMAGE_ASPECT_COLOR_BIT);
  depth = make_image(VK_FORMAT_D32_SFLOAT, VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT,
                     VK_IMAGE_ASPECT_DEPTH_BIT);
  write_descriptors();
}

void RasterRenderer::State::fill_uniforms(const Camera& camera, const TransferFunction& tf_in,
                                          const RasterOptions& o) {
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
  u.size[2] = uint32_t(std::min<uint64_t>(list_capacity, 0xFFFFFFFFu));
  uint32_t shift = 0;  // page_units = 2^shift (shaders/pages.glsl)
  while (page_units > (uint64_t{1} << shift)) ++shift;
  u.size[3] = shift;
  write_transfer_table(tf, u.colours, u.opacities, u.tf_counts);
  u.tf_counts[2] = o.early_termination ? 1u : 0u;
  u.termination[0] = float(o.termination_alpha);
  // The data's view-depth range (its box corners, widened by 10 % and clamped to the camera's
  // near/far) for the logarithmic depth of MLABDB and MBOIT.
  const glm::dvec3 forward = camera.forward();
  double z_lo = 1e300, z_hi = -1e300;
  for (int corner = 0; corner < 8; ++corner) {
    const glm::dvec3 p{bounds.min[0] + (corner & 1 ? bounds.max[0] - bounds.min[0] : 0.0),
                       bounds.min[1] + (corner & 2 ? bounds.max[1] - bounds.min[1] : 0.0),
                       bounds.min[2] + (corner & 4 ? bounds.max[2] - bounds.min[2] : 0.0)};
    const double z = glm::dot(p - camera.eye, forward);
    z_lo = std::min(z_lo, z), z_hi = std::max(z_hi, z);
  }
  const double margin = 0.1 * std::max(z_hi - z_lo, 1e-6);
  z_lo = std::clamp(z_lo - margin, camera.near, camera.far);
  z_hi = std::clamp(z_hi + margin, z_lo * (1 + 1e-6), camera.far);
  for (int k = 0; k < 3; ++k) u.view_dir[k] = float(forward[k]);
  u.depth_params[0] = float(std::log(z_lo)), u.depth_params[1] = float(std::log(z_hi));
  u.depth_params[2] = float(o.tau_alpha), u.depth_params[3] = float(o.tau_opaque);
  u.oit_params[0] = float(o.mboit_bias.value_or(default_moment_bias(o.moment_basis, o.moments)));
  u.oit_params[1] = float(o.mboit_beta);
  // Trigonometric moments: the phase runs over [0, 2 pi - zone] and roots inside the wrapping
  // zone (the last 0.1 pi of the circle) get a linear ramp of weight, as in MBOIT's code.
  const double zone = 0.1 * kPi;
  u.moment_params[0] = float(kPi - 0.5 * zone);
  const double zone_end = 7, zone_begin = circle_parameter(2 * kPi - zone);
  u.moment_params[1] = float(1 / (zone_end - zone_begin));
  u.moment_params[2] = float(1 - zone_end / (zone_end - zone_begin));
  u.oit_counts[0] = uint32_t(std::max(o.layers, 0));
  u.oit_counts[1] = uint32_t(o.wboit_weight);
  std::memcpy(uniforms.mapped, &u, sizeof u);
  std::memcpy(background, u.background, sizeof background);
}

void RasterRenderer::State::begin_timing(VkCommandBuffer cmd) {
  pass_names.clear();
  next_query = 0;
  if (!queries) return;
  vkCmdResetQueryPool(cmd, queries, 0, kQueries);
  vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, queries, next_query++);
}

void RasterRenderer::State::mark(VkCommandBuffer cmd, const std::string& pass_name) {
  if (!queries || next_query >= kQueries) return;
  vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, queries, next_query++);
  pass_names.push_back(pass_name);
}

void RasterRenderer::State::read_timings(RasterStats& s) {
  s.pass_ms.clear();
  if (!queries || next_query < 2) return;
  uint64_t ticks[kQueries] = {};
  if (vkGetQueryPoolResults(ctx.device(), queries, 0, next_query, sizeof ticks, ticks, 8,
                            VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT) != VK_SUCCESS)
    return;
  for (uint32_t i = 1; i < next_query; ++i)
    s.pass_ms.emplace_back(pass_names[i - 1],
                           double(ticks[i] - ticks[i - 1]) * ctx.timestamp_period_ns() * 1e-6);
}

void RasterRenderer::State::fill(VkCommandBuffer cmd, const Buffer& buffer, uint64_t offset,
                                 uint64_t size, uint32_t word) {
  vkCmdFillBuffer(cmd, buffer.buffer, offset, size, word);
}

void RasterRenderer::State::draw(VkCommandBuffer cmd, const DrawSetup& setup) {
  VkPipeline pipeline = graphics(setup);
  VkRenderingAttachmentInfo targets[3] = {{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO},
                                          {VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO},
                                          {VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO}};
  const Image2D* images[3] = {&colour, &scalar, &colour2};
  for (uint32_t t = 0; t < setup.targets; ++t) {
    image_barrier(cmd, images[t]->image, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                  VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
                  VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT | VK_ACCESS_COLOR_ATTACHMENT_READ_BIT);
    targets[t].imageView = images[t]->view;
    targets[t].imageLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
    targets[t].loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
    targets[t].storeOp = VK_ATTACHMENT_STORE_OP_STORE;
  }
  targets[0].clearValue.color = {{setup.clear[0], setup.clear[1], setup.clear[2], setup.clear[3]}};
  targets[1].clearValue.color = {{setup.clear_scalar, 0, 0, 0}};
  targets[2].clearValue.color = {{0, 0, 0, 0}};
  VkRenderingAttachmentInfo depth_target{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
  if (setup.depth) {
    image_barrier(
        cmd, depth.image, VK_IMAGE_ASPECT_DEPTH_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
        VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL,
        VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT | VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_READ_BIT);
    depth_target.imageView = depth.view;
    depth_target.imageLayout = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL;
    depth_target.loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
    depth_target.storeOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
    depth_target.clearValue.depthStencil = {1, 0};
  }
  VkRenderingInfo info{VK_STRUCTURE_TYPE_RENDERING_INFO};
  info.renderArea = {{0, 0}, {uint32_t(width), uint32_t(height)}};
  info.layerCount = 1;
  info.colorAttachmentCount = setup.targets;
  info.pColorAttachments = targets;
  if (setup.depth) info.pDepthAttachment = &depth_target;
  vkCmdBeginRendering(cmd, &info);
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
  vkCmdEndRendering(cmd);
  barrier_all(cmd);
}

void RasterRenderer::State::copy_targets(VkCommandBuffer cmd, VkBuffer buffer,
                                         const std::vector<uint64_t>& offsets) {
  const Image2D* images[3] = {&colour, &scalar, &colour2};
  for (size_t t = 0; t < offsets.size() && t < 3; ++t) {
    image_barrier(cmd, images[t]->image, VK_IMAGE_ASPECT_COLOR_BIT,
                  VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                  VK_ACCESS_TRANSFER_READ_BIT);
    VkBufferImageCopy copy{};
    copy.bufferOffset = offsets[t];
    copy.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    copy.imageExtent = {uint32_t(width), uint32_t(height), 1};
    vkCmdCopyImageToBuffer(cmd, images[t]->image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, buffer, 1,
                           &copy);
  }
  barrier_all(cmd);
}

void RasterRenderer::State::dispatch(VkCommandBuffer cmd, VkPipeline pipeline) {
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline);
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout, 0, 1, &set, 0, nullptr);
  vkCmdDispatch(cmd, uint32_t(width + 7) / 8, uint32_t(height + 7) / 8, 1);
  barrier_all(cmd);
}

void RasterRenderer::State::read_output(RasterFrame& frame) {
  const auto* rgba = static_cast<const float*>(ctx.read_back(output));
  frame.image = Image(width, height, 3);
  frame.alpha.resize(pixels());
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const size_t p = size_t(y) * size_t(width) + size_t(x);
      for (int k = 0; k < 3; ++k) frame.image.at(x, y, k) = rgba[4 * p + size_t(k)];
      frame.alpha[p] = rgba[4 * p + 3];
    }
}

void RasterRenderer::State::read_depth_complexity(RasterFrame& frame) {
  const auto* counts = static_cast<const uint32_t*>(ctx.read_back(stats)) + 1;
  frame.depth_complexity.assign(counts, counts + pixels());
  uint64_t total = 0;
  for (uint32_t d : frame.depth_complexity) {
    frame.stats.max_depth_complexity = std::max(frame.stats.max_depth_complexity, d);
    total += d;
  }
  frame.stats.mean_depth_complexity = double(total) / double(pixels());
  if (frame.stats.fragments == 0) frame.stats.fragments = total;  // ll counted its own already
}

void RasterRenderer::State::render_opaque(RasterFrame& frame) {
  ctx.submit([&](VkCommandBuffer cmd) {
    begin_timing(cmd);
    DrawSetup setup{"opaque.frag", 1, true};
    setup.clear = {background[0], background[1], background[2], 0};
    draw(cmd, setup);
    mark(cmd, "draw");
    copy_targets(cmd, output.gpu.buffer, {0});
  });
  read_timings(frame.stats);
  read_output(frame);
  frame.stats.frame_bytes = pixels() * (16 + 4);  // colour + depth attachments
}

void RasterRenderer::State::count_fragments(RasterFrame& frame) {
  ctx.submit([&](VkCommandBuffer cmd) {
    begin_timing(cmd);
    fill(cmd, stats.gpu, 0, VK_WHOLE_SIZE, 0);
    barrier_all(cmd);
    draw(cmd, DrawSetup{"count.frag"});
    mark(cmd, "count");
  });
  read_timings(frame.stats);
  read_depth_complexity(frame);
}

// The chunks' arrays are shared, not copied (Array's copies are views of one owner).
RasterRenderer::RasterRenderer(Context& context, const TubeMesh& mesh)
    : RasterRenderer(context, mesh, [&mesh](size_t c) { return mesh.chunks[c]; }) {}

RasterRenderer::RasterRenderer(Context& context, const TubeMesh& description,
                               const std::function<TubeChunk(size_t)>& chunk)
    : state_(std::make_unique<State>(context)) {
  state_->attribute_range = description.attribute_range;
  for (size_t c = 0; c < description.chunks.size(); ++c) state_->upload(chunk(c));
  state_->create_layout();
}

RasterRenderer::~RasterRenderer() = default;

uint64_t RasterRenderer::mesh_bytes() const {
  return state_->mesh_bytes;
}

Bounds RasterRenderer::bounds() const {
  return state_->bounds;
}

namespace {

// Bytes of the per-pixel state (binding 1) and of the nodes / target copies (binding 2).
std::pair<uint64_t, uint64_t> frame_layout(const RasterOptions& o, uint64_t pixels) {
  switch (o.technique) {
    case RasterTechnique::Opaque:
      return {4, 4};
    case RasterTechnique::DepthPeeling:
      return {pixels * 4, pixels * 20};  // peeled depth; layer colour + depth
    case RasterTechnique::LinkedLists:
      return {pixels * 4, 4};  // heads; the nodes are in their own pages
    case RasterTechnique::Mlab:
    case RasterTechnique::MlabBuckets:
      return {pixels * 12, 4};    // locks + bucket depths; the nodes are in pages
    case RasterTechnique::Mboit:  // moments (b0..b3, b_n, b4..b7 when n > 4) + accumulation
      return {4, pixels * ((o.moments > 4 ? 36 : 20) + 16)};
    case RasterTechnique::Wboit:
      return {4, pixels * 20};  // accumulation + absorbance
  }
  return {4, 4};
}

}  // namespace

int min_layers(RasterTechnique technique) {
  return technique == RasterTechnique::MlabBuckets ? 2 : technique == RasterTechnique::Mlab ? 1 : 0;
}

RasterFrame RasterRenderer::render(const Camera& camera, const TransferFunction& tf,
                                   const RasterOptions& options) {
  if (options.width < 1 || options.height < 1) throw Error("render: empty image size");
  RasterOptions o = options;
  const bool mlab = o.technique == RasterTechnique::Mlab;
  const bool buckets = o.technique == RasterTechnique::MlabBuckets;
  if (o.layers == 0) o.layers = buckets ? 4 : 8;
  // Options out of a technique's range are the command line's (exit 1; Python's UsageError).
  if ((mlab || buckets) && (o.layers < min_layers(o.technique) || o.layers > 64))
    throw UsageError(std::string("--layers: ") + to_string(o.technique) + " takes " +
                     (buckets ? "2 to 64 (1 front bucket and at least 1 back node)" : "1 to 64") +
                     ", not " + std::to_string(o.layers));
  if (o.technique == RasterTechnique::DepthPeeling && o.max_layers < 1)
    throw UsageError("--max-layers: dp peels at least 1 layer");
  if (o.technique == RasterTechnique::Mboit && o.moments != 4 && o.moments != 6 && o.moments != 8)
    throw UsageError("--moments: mboit takes 4, 6 or 8, not " + std::to_string(o.moments));
  if (o.technique == RasterTechnique::Wboit &&
      !(o.wboit_weight == 0 || (o.wboit_weight >= 7 && o.wboit_weight <= 9)))
    throw UsageError("--wboit-weight: 0, 7, 8 or 9, not " + std::to_string(o.wboit_weight));
  const auto start = std::chrono::steady_clock::now();
  State& s = *state_;
  const uint64_t pixels = uint64_t(o.width) * uint64_t(o.height);
  uint64_t list_capacity = 0;
  if (o.technique == RasterTechnique::LinkedLists) {
    list_capacity = o.capacity;
    if (list_capacity == 0)
      list_capacity = uint64_t(std::ceil(o.expected_depth_complexity * double(pixels)));
    // Keep a larger capacity from an earlier frame of this size.
    if (o.capacity == 0 && s.width == o.width && s.height == o.height)
      list_capacity = std::max(list_capacity, s.list_capacity);
  }
  const auto [pixel_state_bytes, node_bytes] = frame_layout(o, pixels);
  s.prepare_frame(o.width, o.height, pixel_state_bytes, node_bytes, to_string(o.technique));
  if (o.technique == RasterTechnique::LinkedLists) {
    if (o.node_bytes != 24 && o.node_bytes != 12)
      throw Error("ll: nodes are 24 or 12 bytes, not " + std::to_string(o.node_bytes));
    s.prepare_pages(list_capacity, o.node_bytes, o.max_buffer_bytes, "ll");
    s.list_capacity = list_capacity;
  }
  if ((mlab || buckets) && 5 * pixels * uint64_t(o.layers) > 0xFFFFFFFFull)
    throw Error(std::string(to_string(o.technique)) + ": " + std::to_string(o.layers) +
                " nodes per pixel at " + std::to_string(o.width) + "x" + std::to_string(o.height) +
                " need more than 2^32 words (the shaders index them "
                "with 32 bits); use fewer layers or a smaller size");
  if (mlab || buckets)  // five planes of k words per pixel: depth, r, g, b, T
    s.prepare_pages(5 * pixels * uint64_t(o.layers), 4, o.max_buffer_bytes, to_string(o.technique));
  s.fill_uniforms(camera, tf, o);
  RasterFrame frame;
  switch (o.technique) {
    case RasterTechnique::Opaque:
      s.render_opaque(frame);
      break;
    case RasterTechnique::DepthPeeling:
      s.render_peeling(o, frame);
      break;
    case RasterTechnique::LinkedLists:
      s.render_lists(camera, tf, o, frame);
      break;
    case RasterTechnique::Mlab:
    case RasterTechnique::MlabBuckets:
      s.render_mlab(o, frame);
      break;
    case RasterTechnique::Mboit:
      s.render_moments(o, frame);
      break;
    case RasterTechnique::Wboit:
      s.render_weighted(frame);
      break;
  }
  frame.stats.seconds = seconds_since(start);
  return frame;
}

RasterFrame RasterRenderer::count_fragments(const Camera& camera, const TransferFunction& tf,
                                            int width, int height) {
  if (width < 1 || height < 1) throw Error("depth complexity: empty image size");
  const auto start = std::chrono::steady_clock::now();
  RasterOptions o;
  o.width = width, o.height = height;
  State& s = *state_;
  s.prepare_frame(width, height, 4, 4, "depth complexity");
  s.fill_uniforms(camera, tf, o);
  RasterFrame frame;
  s.count_fragments(frame);
  frame.stats.frame_bytes = 4 + s.pixels() * 4;
  frame.stats.seconds = seconds_since(start);
  return frame;
}

}  // namespace linebake::vk
