#pragma once
// Internal to the Vulkan rasteriser: the device resources every technique shares (uploaded mesh,
// one descriptor set, per-frame buffers and attachments, pipelines by name) and the few recording
// steps the techniques are made of. Each technique's passes live in their own file
// (raster_lists.cpp, raster_peeling.cpp, raster_mlab.cpp, raster_moments.cpp).
//
// Descriptor set 0, shared by every shader:
//   0 FrameUniforms   1 per-pixel state (list heads, peeled depth, locks, bucket depths)
//   2 nodes / copies of the colour attachments   3 counter   4 output (vec4 per pixel)
//   5 stats {longest list, depth complexity per pixel}
//   6 pages: kPages storage buffers (shaders/pages.glsl) for ll's nodes and mlab's planes

#include <map>
#include <string>
#include <vector>

#include "lines/line_set.hpp"
#include "render/vulkan/raster_renderer.hpp"
#include "render/vulkan/transfer_table.hpp"

namespace linebake::vk {

constexpr uint32_t kBindings = 6;  // then binding 6, the node pages
constexpr uint32_t kPages = 16;    // shaders/pages.glsl

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
  float view_dir[4];
  float depth_params[4];
  float oit_params[4];
  uint32_t oit_counts[4];
  float moment_params[4];
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
  uint64_t host_bytes = 0;  // Context::allocate_memory's
};

// How one pass draws the tubes. Colour targets: 1 = RGBA32F, 2 = RGBA32F + R32F,
// 3 = RGBA32F + R32F + RGBA32F.
struct DrawSetup {
  std::string fragment;
  uint32_t targets = 0;
  bool depth = false;                      // depth attachment: test LESS, write
  bool additive = false;                   // additive blending on every target
  std::vector<uint32_t> constants;         // fragment specialisation constants 0, 1, ...
  std::array<float, 4> clear{0, 0, 0, 0};  // target 0
  float clear_scalar = 0;                  // target 1 (target 2 clears to zero)
};

struct RasterRenderer::State {
  Context& ctx;
  std::vector<ChunkBuffers> chunks;
  std::array<float, 2> attribute_range{0, 0};
  Bounds bounds;
  uint64_t mesh_bytes = 0;

  VkDescriptorSetLayout set_layout = VK_NULL_HANDLE;
  VkPipelineLayout layout = VK_NULL_HANDLE;
  VkDescriptorPool pool = VK_NULL_HANDLE;
  VkDescriptorSet set = VK_NULL_HANDLE;
  std::map<std::string, VkPipeline> pipelines;
  VkQueryPool queries = VK_NULL_HANDLE;
  static constexpr uint32_t kQueries = 8;
  uint32_t next_query = 0;
  std::vector<std::string> pass_names;  // pass_names[i] ends at timestamp query i + 1

  // Per-frame resources, kept while the size fits.
  int width = 0, height = 0;
  uint64_t pixel_state_bytes = 0, node_bytes = 0;
  uint64_t list_capacity = 0;  // ll: nodes the gather may write
  Buffer uniforms, pixel_state, nodes;
  // What the host reads back: ll's node counter, the resolved RGBA, and `longest` followed by
  // the depth complexity per pixel (Context::read_back).
  ResultBuffer counter, output, stats;
  // The frame's background, kept here: the uniform buffer may be device memory the host should
  // not read.
  float background[4] = {0, 0, 0, 0};
  // Storage past one buffer (shaders/pages.glsl): pages of page_units units (ll: nodes; mlab:
  // words; a power of two) of page_unit_bytes each, pool_units in all.
  std::vector<Buffer> pages;
  uint64_t page_units = 0, pool_units = 0;
  uint32_t page_unit_bytes = 24;
  Image2D colour, scalar, colour2, depth;

  explicit State(Context& c) : ctx(c) {}
  ~State();

  uint64_t pixels() const { return uint64_t(width) * uint64_t(height); }

  void upload(const TubeChunk& chunk);  // one chunk's buffers, its positions into `bounds`
  void create_layout();
  VkPipeline graphics(const DrawSetup& setup);
  VkPipeline compute(const std::string& name, const std::vector<uint32_t>& constants = {});

  // (Re)allocates the frame's buffers when the size changes or they are too small.
  void prepare_frame(int w, int h, uint64_t pixel_state_wanted, uint64_t nodes_wanted,
                     const char* technique);
  void release_frame();
  // A pool of `units` units of `unit_bytes` in pages of at most max_buffer_bytes (0: the device's
  // maxStorageBufferRange), kept when it already holds them in this layout; at most kPages.
  void prepare_pages(uint64_t units, uint32_t unit_bytes, uint64_t max_buffer_bytes,
                     const char* technique);
  void release_pages();
  // Specialisation constant 2 of the shaders that use the pages (shaders/pages.glsl).
  uint32_t paged() const { return pages.size() > 1 ? 1u : 0u; }
  // vkCmdFillBuffer over units [first, first + count) of the pool, across pages.
  void fill_pages(VkCommandBuffer cmd, uint64_t first, uint64_t count, uint32_t word);
  void fill_uniforms(const Camera& camera, const TransferFunction& tf, const RasterOptions& o);

  // Recording steps.
  void begin_timing(VkCommandBuffer cmd);
  void mark(VkCommandBuffer cmd, const std::string& pass_name);
  void fill(VkCommandBuffer cmd, const Buffer& buffer, uint64_t offset, uint64_t size,
            uint32_t word);
  void draw(VkCommandBuffer cmd, const DrawSetup& setup);
  // Copies the first offsets.size() targets of the last draw into `buffer`, target t at
  // offsets[t].
  void copy_targets(VkCommandBuffer cmd, VkBuffer buffer, const std::vector<uint64_t>& offsets);
  void dispatch(VkCommandBuffer cmd, VkPipeline pipeline);

  // After the submission: timings, the output image, the depth-complexity counts.
  void read_timings(RasterStats& stats);
  void read_output(RasterFrame& frame);
  void read_depth_complexity(RasterFrame& frame);

  // The techniques (one file each).
  void render_opaque(RasterFrame& frame);
  void render_lists(const Camera& camera, const TransferFunction& tf, const RasterOptions& o,
                    RasterFrame& frame);
  void render_peeling(const RasterOptions& o, RasterFrame& frame);
  void render_mlab(const RasterOptions& o, RasterFrame& frame);
  void render_moments(const RasterOptions& o, RasterFrame& frame);
  void render_weighted(RasterFrame& frame);
  void count_fragments(RasterFrame& frame);

 private:
  Image2D make_image(VkFormat format, VkImageUsageFlags usage, VkImageAspectFlags aspect);
  void destroy_image(Image2D& image);
  void write_descriptors();
};

// Full memory dependency between consecutive passes (and to host reads at the end).
void barrier_all(VkCommandBuffer cmd);

}  // namespace linebake::vk
