#include "render/vulkan/tile_renderer.hpp"

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>

#include "core/error.hpp"
#include "render/vulkan/buffer_set.hpp"
#include "render/vulkan/pixel_readback.hpp"
#include "render/vulkan/radix_sort.hpp"
#include "render/vulkan/shaders.hpp"
#include "render/vulkan/transfer_table.hpp"
#include "render/vulkan/view_uniforms.hpp"

namespace linebake::vk {
namespace {

constexpr uint32_t kTile = 16;
// 0 uniforms, 1 points, 2 segments, 3 keys, 4 values, 5 counters, 6 ranges, 7 pixels, 8 hit
// counts, 9 stats, 10 the slice, 11 pixel states (shaders/tiles.glsl, tiles_composite.comp).
constexpr uint32_t kBindings = 12;
// A pixel's state between slices (tiles_composite.comp PixelState, std430).
constexpr uint64_t kPixelStateBytes = 16 + 16 + 16 * 4 + 16 * 16;
// Keys per tile per dispatch where the driver caps an invocation's loop iterations (lavapipe's
// gallivm: 65535 in all): each key costs up to about 60 (window, transfer function, crossings).
constexpr uint32_t kCappedSliceKeys = 512;

struct TileUniforms {
  float eye[4], forward[4], right[4], up[4];
  float shading[4], background[4], ranges[4];
  uint32_t size[4], tf_counts[4];
  float params[4];
  uint32_t tiles[4];
  float colours[kMaxTfPoints][4];
  float opacities[kMaxTfPoints][4];
};

struct Counters {
  uint32_t key_count, binned;
};
struct CompositeStats {
  uint32_t window_overflows;
};
struct SliceInfo {
  uint32_t slice, slice_keys, first, last;
};

}  // namespace

struct TileRenderer::State {
  Context& ctx;
  RadixSorter sorter;
  uint64_t segment_count = 0;
  uint64_t max_buffer = 0;
  std::array<float, 2> attribute_range{};
  glm::dvec3 centre{};
  double extent = 0;  // radius of the bounding sphere, capsules included
  float radius = 0;
  Buffer uniforms, points, segments, keys, values, counters, ranges, stats, slice, states;
  uint32_t slice_keys = 0;  // 0: a tile's keys in one dispatch
  PixelTargets targets;
  BufferSet set;
  std::array<VkPipeline, 3> pipelines{};  // bin, ranges, composite
  VkQueryPool queries = VK_NULL_HANDLE;

  State(Context& c) : ctx(c), sorter(c) {}

  void bind() {
    write_buffer_set(ctx.device(), set.set,
                     {&uniforms, &points, &segments, &keys, &values, &counters, &ranges,
                      &targets.rgba, &targets.counts, &stats, &slice, &states});
  }

  ~State() {
    VkDevice d = ctx.device();
    vkDeviceWaitIdle(d);
    for (Buffer* b : {&uniforms, &points, &segments, &keys, &values, &counters, &ranges, &stats,
                      &slice, &states})
      ctx.destroy(*b);
    targets.release(ctx);
    for (VkPipeline p : pipelines)
      if (p) vkDestroyPipeline(d, p, nullptr);
    if (queries) vkDestroyQueryPool(d, queries, nullptr);
    if (set.pool) vkDestroyDescriptorPool(d, set.pool, nullptr);
    if (set.layout) vkDestroyPipelineLayout(d, set.layout, nullptr);
    if (set.set_layout) vkDestroyDescriptorSetLayout(d, set.set_layout, nullptr);
  }
};

TileRenderer::TileRenderer(Context& context, const CapsuleSegments& capsules,
                           uint64_t max_buffer_bytes, uint32_t slice_keys)
    : state_(std::make_unique<State>(context)) {
  State& s = *state_;
  s.radius = capsules.radius;
  s.attribute_range = capsules.attribute_range;
  // One array of points and one of segment words over all chunks (words re-based).
  std::vector<float> points;
  std::vector<uint32_t> words;
  for (const CapsuleChunk& chunk : capsules.chunks) {
    const uint64_t base = points.size() / 4;
    if (base + chunk.points.size() / 4 >= (uint64_t{1} << 30))
      throw Error("tiles: more than 2^30 points; not supported yet");
    points.insert(points.end(), chunk.points.begin(), chunk.points.end());
    for (uint32_t w : chunk.segments)
      words.push_back((((w >> 2) + uint32_t(base)) << 2) | (w & 3u));
  }
  s.segment_count = words.size();
  glm::dvec3 lo(1e300), hi(-1e300);
  for (size_t i = 0; i + 3 < points.size() + 1; i += 4)
    for (int k = 0; k < 3; ++k)
      lo[k] = std::min(lo[k], double(points[i + size_t(k)])),
      hi[k] = std::max(hi[k], double(points[i + size_t(k)]));
  if (points.empty()) lo = hi = glm::dvec3(0);
  s.centre = 0.5 * (lo + hi);
  s.extent = 0.5 * glm::length(hi - lo) + capsules.radius;
  VkPhysicalDeviceProperties props;
  vkGetPhysicalDeviceProperties(context.physical_device(), &props);
  s.max_buffer = props.limits.maxStorageBufferRange;
  if (max_buffer_bytes > 0) s.max_buffer = std::min(s.max_buffer, max_buffer_bytes);
  const VkBufferUsageFlags storage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
  s.points = context.upload(points.data(), points.size() * 4, storage);
  s.segments = context.upload(words.data(), words.size() * 4, storage);
  s.uniforms =
      context.create_buffer(sizeof(TileUniforms), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, true);
  s.counters = context.create_buffer(sizeof(Counters), storage, true);
  s.stats = context.create_buffer(sizeof(CompositeStats), storage, true);
  s.keys = context.create_buffer(4, storage, false);
  s.values = context.create_buffer(4, storage, false);
  s.ranges = context.create_buffer(8, storage, true);
  s.slice =
      context.create_buffer(sizeof(SliceInfo), storage | VK_BUFFER_USAGE_TRANSFER_DST_BIT, false);
  s.states = context.create_buffer(4, storage, false);
  s.slice_keys = slice_keys > 0 ? slice_keys
                 : context.info().driver.find("llvmpipe") != std::string::npos ||
                         context.info().name.find("llvmpipe") != std::string::npos
                     ? kCappedSliceKeys
                     : 0;
  VkDevice d = context.device();
  s.set = create_buffer_set(d, kBindings, VK_SHADER_STAGE_COMPUTE_BIT);
  const char* shaders[] = {"tiles_bin.comp", "tiles_ranges.comp", "tiles_composite.comp"};
  for (size_t i = 0; i < 3; ++i) {
    VkShaderModule module = create_shader_module(d, shaders[i]);
    VkComputePipelineCreateInfo create{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
    create.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
    create.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
    create.stage.module = module;
    create.stage.pName = "main";
    create.layout = s.set.layout;
    const VkResult made =
        vkCreateComputePipelines(d, VK_NULL_HANDLE, 1, &create, nullptr, &s.pipelines[i]);
    vkDestroyShaderModule(d, module, nullptr);
    check(made, shaders[i]);
  }
  s.queries = context.create_timestamp_pair();
}

TileRenderer::~TileRenderer() = default;

TileFrame TileRenderer::render(const Camera& camera, const TransferFunction& tf_in,
                               const TileOptions& o) {
  if (o.width < 1 || o.height < 1) throw Error("tiles: empty image size");
  const auto start = std::chrono::steady_clock::now();
  State& s = *state_;
  Context& ctx = s.ctx;
  const bool resized = s.targets.resize(ctx, o.width, o.height);
  const uint32_t tiles_x = (uint32_t(o.width) + kTile - 1) / kTile;
  const uint32_t tiles_y = (uint32_t(o.height) + kTile - 1) / kTile;
  const uint32_t tiles = tiles_x * tiles_y;
  // At least one tile bit: shifts by 32 are undefined in SPIR-V.
  const uint32_t tile_bits = std::max(1u, uint32_t(std::bit_width(tiles - 1)));
  const uint32_t depth_bits = 32 - tile_bits;
  if (resized || s.ranges.size < uint64_t(tiles) * 8) {
    ctx.destroy(s.ranges);
    s.ranges = ctx.create_buffer(uint64_t(tiles) * 8, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
  }
  s.bind();
  TransferFunction tf = tf_in;
  if (tf.range[0] == 0 && tf.range[1] == 0)
    tf.range = {double(s.attribute_range[0]), double(s.attribute_range[1])};
  TileUniforms u{};
  write_view(u, camera, o.width, o.height, o.shading);
  const glm::dvec3 forward = camera.image_plane(o.width, o.height).forward;
  u.ranges[2] = float(tf.range[0]), u.ranges[3] = float(tf.range[1]);
  u.size[0] = uint32_t(o.width), u.size[1] = uint32_t(o.height);
  u.size[2] = o.early_termination ? 1u : 0u, u.size[3] = uint32_t(s.segment_count);
  // The keys' depth span: the data's bounding sphere along the view.
  const double middle = glm::dot(s.centre - camera.eye, forward);
  const double near = std::max(0.0, middle - s.extent), far = middle + s.extent;
  u.params[0] = float(o.termination_alpha), u.params[1] = s.radius;
  u.params[2] = float(near), u.params[3] = float(std::max(far, near + 1e-6));
  u.tiles[0] = tiles_x, u.tiles[1] = tiles_y, u.tiles[2] = depth_bits;
  write_transfer_table(tf, u.colours, u.opacities, u.tf_counts);
  const auto barrier = [](VkCommandBuffer cmd, VkAccessFlags dst, VkPipelineStageFlags stage) {
    VkMemoryBarrier b{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    b.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT;
    b.dstAccessMask = dst;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                         stage, 0, 1, &b, 0, nullptr, 0, nullptr);
  };
  TileFrame frame;
  TileStats& st = frame.stats;
  st.segments = s.segment_count;
  st.tiles = tiles;
  // Binning, again with room for every key when the first pass ran out of it.
  uint64_t capacity = s.keys.size / 4;
  for (;;) {
    u.tiles[3] = uint32_t(std::min<uint64_t>(capacity, UINT32_MAX));
    std::memcpy(s.uniforms.mapped, &u, sizeof u);
    std::memset(s.counters.mapped, 0, sizeof(Counters));
    ctx.submit([&](VkCommandBuffer cmd) {
      if (s.queries) {
        vkCmdResetQueryPool(cmd, s.queries, 0, 2);
        vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, s.queries, 0);
      }
      vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, s.set.layout, 0, 1, &s.set.set,
                              0, nullptr);
      vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, s.pipelines[0]);
      vkCmdDispatch(cmd, uint32_t((s.segment_count + 255) / 256), 1, 1);
      if (s.queries) vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, s.queries, 1);
      barrier(cmd, VK_ACCESS_HOST_READ_BIT, VK_PIPELINE_STAGE_HOST_BIT);
    });
    st.bin_ms += ctx.elapsed_ms(s.queries);
    Counters c;
    std::memcpy(&c, s.counters.mapped, sizeof c);
    st.keys = c.key_count;
    st.binned_segments = c.binned;
    if (c.key_count <= capacity) break;
    // Room for all keys, within one storage buffer each for keys and values.
    const uint64_t needed = uint64_t(c.key_count) + c.key_count / 8;
    if (needed * 4 > s.max_buffer)
      throw BudgetExceeded("tiles: " + std::to_string(c.key_count) + " (tile, segment) keys need " +
                           std::to_string(needed * 4 >> 20) +
                           " MiB, more than one storage buffer holds on " + ctx.info().name + " (" +
                           std::to_string(s.max_buffer >> 20) + " MiB); a smaller image renders");
    ctx.destroy(s.keys);
    ctx.destroy(s.values);
    s.keys = ctx.create_buffer(needed * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);
    s.values = ctx.create_buffer(needed * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);
    s.bind();
    capacity = needed;
    ++st.rebins;
  }
  // Sort and ranges.
  std::memset(s.stats.mapped, 0, sizeof(CompositeStats));
  std::memset(s.ranges.mapped, 0, s.ranges.size);
  ctx.submit([&](VkCommandBuffer cmd) {
    if (s.queries) {
      vkCmdResetQueryPool(cmd, s.queries, 0, 2);
      vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, s.queries, 0);
    }
    s.sorter.record(cmd, s.keys, s.values, uint32_t(st.keys), 32);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, s.set.layout, 0, 1, &s.set.set, 0,
                            nullptr);
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, s.pipelines[1]);
    vkCmdDispatch(cmd, uint32_t((st.keys + 255) / 256) + 1, 1, 1);
    if (s.queries) vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, s.queries, 1);
    barrier(cmd, VK_ACCESS_HOST_READ_BIT, VK_PIPELINE_STAGE_HOST_BIT);
  });
  st.sort_ms = ctx.elapsed_ms(s.queries);
  // The composite pass in slices of each tile's keys where the device needs them.
  uint32_t longest = 0;
  const auto* ranges = static_cast<const uint32_t*>(s.ranges.mapped);
  for (uint32_t t = 0; t < tiles; ++t)
    longest = std::max(longest, ranges[2 * t + 1] - ranges[2 * t]);
  const uint32_t slice_keys = s.slice_keys > 0 ? s.slice_keys : std::max<uint32_t>(longest, 1);
  const uint32_t slices = std::max<uint32_t>(1, (longest + slice_keys - 1) / slice_keys);
  st.slices = slices;
  if (slices > 1 && s.states.size < uint64_t(o.width) * uint64_t(o.height) * kPixelStateBytes) {
    const uint64_t bytes = uint64_t(o.width) * uint64_t(o.height) * kPixelStateBytes;
    if (bytes > s.max_buffer)
      throw BudgetExceeded("tiles: rendering in slices on " + ctx.info().name + " keeps " +
                           std::to_string(bytes >> 20) + " MiB of pixel state, more than one " +
                           "storage buffer holds (" + std::to_string(s.max_buffer >> 20) +
                           " MiB); a smaller image renders");
    ctx.destroy(s.states);
    s.states = ctx.create_buffer(bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);
    s.bind();
  }
  ctx.submit([&](VkCommandBuffer cmd) {
    if (s.queries) {
      vkCmdResetQueryPool(cmd, s.queries, 0, 2);
      vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, s.queries, 0);
    }
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, s.set.layout, 0, 1, &s.set.set, 0,
                            nullptr);
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, s.pipelines[2]);
    for (uint32_t k = 0; k < slices; ++k) {
      const SliceInfo info{k, slice_keys, k == 0 ? 1u : 0u, k + 1 == slices ? 1u : 0u};
      vkCmdUpdateBuffer(cmd, s.slice.buffer, 0, sizeof info, &info);
      barrier(cmd, VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT,
              VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT);
      vkCmdDispatch(cmd, tiles_x, tiles_y, 1);
      barrier(cmd,
              VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT,
              VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT);
    }
    if (s.queries) vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, s.queries, 1);
    barrier(cmd, VK_ACCESS_HOST_READ_BIT, VK_PIPELINE_STAGE_HOST_BIT);
  });
  st.composite_ms = ctx.elapsed_ms(s.queries);
  CompositeStats cs;
  std::memcpy(&cs, s.stats.mapped, sizeof cs);
  st.window_overflows = cs.window_overflows;
  PixelReadback read = s.targets.read();
  frame.image = std::move(read.image);
  frame.depth_complexity = std::move(read.counts);
  st.hits = read.total;
  st.max_depth_complexity = read.maximum;
  st.frame_bytes = s.keys.size + s.values.size + RadixSorter::scratch_bytes(st.keys) +
                   s.ranges.size + s.targets.rgba.size + s.targets.counts.size +
                   (slices > 1 ? s.states.size : 0);
  st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return frame;
}

}  // namespace linebake::vk
