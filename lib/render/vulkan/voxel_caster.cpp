#include "render/vulkan/voxel_caster.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>

#include "core/error.hpp"
#include "core/interrupt.hpp"
#include "core/measure.hpp"
#include "render/vulkan/buffer_set.hpp"
#include "render/vulkan/pixel_readback.hpp"
#include "render/vulkan/shaders.hpp"
#include "render/vulkan/transfer_table.hpp"
#include "render/vulkan/view_uniforms.hpp"

namespace linebake::vk {
namespace {

constexpr int kMaxLevels = 16;  // shaders/vrc.comp

// std140 mirror of VrcUniforms in shaders/vrc.comp.
struct VrcUniforms {
  float eye[4], forward[4], right[4], up[4];
  float shading[4], background[4], ranges[4];
  uint32_t size[4], tf_counts[4];
  float params[4], origin[4];
  uint32_t grid[4], levels[4];
  float eye_grid[4];
  uint32_t slicing[4];
  uint32_t band[4];
  uint32_t level_resolution[kMaxLevels][4];
  float colours[kMaxTfPoints][4];
  float opacities[kMaxTfPoints][4];
};

constexpr uint32_t kVrcBindings = 7;  // uniforms, offsets, chords, occupancy, output, hits, slices
constexpr uint32_t kGridPages = 8;    // bindings 7 and 8: offsets and chords split (vrc.comp)
constexpr uint32_t kStateBytes = 48;  // a sliced walk's pixel between dispatches (vrc.comp)
constexpr uint32_t kSliceCounters = 16;  // cut_short, unfinished and two spare words
constexpr uint32_t kFirstSliceSteps = 256;
// gallivm's limiter (Mesa 22.3: LP_MAX_TGSI_LOOP_ITERATIONS): a loop that must run longer than
// what is left of it after a cut tells; twice this leaves no doubt.
constexpr uint32_t kSentinel = 2;

uint32_t log2_floor(uint64_t v) {
  uint32_t l = 0;
  while ((uint64_t{2} << l) <= v) ++l;
  return l;
}

}  // namespace

struct VoxelCaster::State {
  Context& ctx;
  const VoxelGrid& grid;
  std::array<uint32_t, 4> grid_info{};
  std::array<float, 4> origin{};
  float voxel_size = 1;
  std::array<float, 2> attribute_range{};
  std::vector<std::array<uint32_t, 4>> levels;
  Buffer uniforms, offsets, chords, occupancy;
  Buffer slices;              // counters and, for a sliced walk, a band's pixel states
  uint64_t slices_bytes = 0;  // what `slices` holds
  uint64_t max_buffer = 0;    // one storage buffer's bytes at most
  uint32_t slice_steps = 0;   // 0: one walk (lavapipe: until its limit cuts one short)
  uint32_t band_rows = 0;     // rows of a sliced walk's band at most (0: one buffer's worth)
  // Split offsets and chords (empty when each fits one buffer): pages of 2^shift units.
  std::vector<Buffer> offset_pages, chord_pages;
  uint32_t offset_shift = 0, chord_shift = 0;
  PixelTargets targets;
  VkDescriptorSetLayout set_layout = VK_NULL_HANDLE;
  VkPipelineLayout layout = VK_NULL_HANDLE;
  VkDescriptorPool pool = VK_NULL_HANDLE;
  VkDescriptorSet set = VK_NULL_HANDLE;
  VkPipeline pipeline = VK_NULL_HANDLE;
  VkQueryPool queries = VK_NULL_HANDLE;
  double gpu_ms = 0;

  State(Context& c, const VoxelGrid& g) : ctx(c), grid(g) {}

  // Device-local; Vulkan has no zero-sized buffers: an empty array becomes one unused word.
  Buffer upload(const void* data, uint64_t bytes) {
    return ctx.upload(data, bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  }

  void write_descriptors() {
    write_buffer_set(ctx.device(), set,
                     {&uniforms, &offsets, &chords, &occupancy, &targets.rgba.gpu,
                      &targets.counts.gpu, &slices});
    for (auto [binding, pages] :
         {std::pair{kVrcBindings, &offset_pages}, std::pair{kVrcBindings + 1, &chord_pages}}) {
      std::vector<const Buffer*> bound;
      for (uint32_t i = 0; i < kGridPages; ++i)
        bound.push_back(i < pages->size() ? &(*pages)[i] : &occupancy);
      write_buffer_array(ctx.device(), set, binding, bound);
    }
  }

  // `bytes` of `data` in pages of 2^shift units of `unit` bytes.
  std::vector<Buffer> upload_pages(const void* data, uint64_t bytes, uint32_t unit,
                                   uint32_t shift) {
    std::vector<Buffer> pages;
    const uint64_t page = (uint64_t{1} << shift) * unit;
    try {
      for (uint64_t first = 0; first < bytes; first += page)
        pages.push_back(ctx.upload(static_cast<const uint8_t*>(data) + first,
                                   std::min(page, bytes - first),
                                   VK_BUFFER_USAGE_STORAGE_BUFFER_BIT));
    } catch (...) {  // a page refused (the memory budget): the pages before it go too
      for (Buffer& b : pages) ctx.destroy(b);
      throw;
    }
    return pages;
  }

  void resize(int w, int h) {
    if (targets.resize(ctx, w, h)) write_descriptors();
  }

  // The slices buffer at `bytes` at least (host-visible: its counters are read after each
  // dispatch).
  // A refused one leaves the counters alone in its place (the next frame's whole walk reads
  // them; it had written through a null mapping), and throws.
  void hold_slices(uint64_t bytes) {
    if (slices.buffer != VK_NULL_HANDLE && slices_bytes >= bytes) return;
    vkDeviceWaitIdle(ctx.device());
    ctx.destroy(slices);
    slices_bytes = 0;
    try {
      slices = ctx.create_buffer(bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
      slices_bytes = bytes;
    } catch (...) {
      {
        const Context::ReservedAllocations counters_only(ctx);  // 16 bytes the budget had held
        slices = ctx.create_buffer(kSliceCounters, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
      }
      slices_bytes = kSliceCounters;
      if (targets.width > 0) write_descriptors();
      throw;
    }
    if (targets.width > 0) write_descriptors();  // else the first resize writes them
  }

  ~State() {
    VkDevice d = ctx.device();
    vkDeviceWaitIdle(d);
    for (Buffer* b : {&uniforms, &offsets, &chords, &occupancy, &slices}) ctx.destroy(*b);
    for (auto* pages : {&offset_pages, &chord_pages})
      for (Buffer& b : *pages) ctx.destroy(b);
    targets.release(ctx);
    if (queries) vkDestroyQueryPool(d, queries, nullptr);
    if (pipeline) vkDestroyPipeline(d, pipeline, nullptr);
    if (pool) vkDestroyDescriptorPool(d, pool, nullptr);
    if (layout) vkDestroyPipelineLayout(d, layout, nullptr);
    if (set_layout) vkDestroyDescriptorSetLayout(d, set_layout, nullptr);
  }
};

VoxelCaster::VoxelCaster(Context& context, const VoxelGrid& grid, const OccupancyPyramid& occupancy,
                         uint64_t max_buffer_bytes)
    : state_(std::make_unique<State>(context, grid)) {
  State& s = *state_;
  if (occupancy.levels() > size_t(kMaxLevels) || occupancy.levels() == 0)
    throw Error("vrc: the occupancy pyramid needs 1 to 16 levels, not " +
                std::to_string(occupancy.levels()));
  if (grid.offsets.size() != grid.voxel_count() + 1)
    throw Error("vrc: the voxel grid's offsets do not match its resolution");
  s.grid_info = {grid.resolution[0], grid.resolution[1], grid.resolution[2], grid.quantization};
  s.origin = {grid.origin[0], grid.origin[1], grid.origin[2], 0};
  s.voxel_size = grid.voxel_size;
  s.attribute_range = grid.attribute_range;
  for (size_t k = 0; k < occupancy.levels(); ++k)
    s.levels.push_back({occupancy.resolution[k][0], occupancy.resolution[k][1],
                        occupancy.resolution[k][2], uint32_t(occupancy.first_word[k])});
  VkPhysicalDeviceProperties props;
  vkGetPhysicalDeviceProperties(context.physical_device(), &props);
  uint64_t limit = props.limits.maxStorageBufferRange;
  if (max_buffer_bytes > 0) limit = std::min(limit, max_buffer_bytes);
  s.max_buffer = limit;
  // Past one buffer, offsets (4-byte units) and chords (8-byte units) go to pages of a power of
  // two of units, so the shader shifts instead of dividing.
  const bool paged = grid.offsets.bytes() > limit || grid.chords.bytes() > limit;
  if (paged) {
    if (limit < 8) throw Error("vrc: a storage buffer must hold at least one chord");
    s.offset_shift = log2_floor(limit / 4);
    s.chord_shift = log2_floor(limit / 8);
    for (const auto& [name, bytes, unit, shift] :
         {std::tuple{"offsets", grid.offsets.bytes(), 4u, s.offset_shift},
          std::tuple{"chords", grid.chords.bytes(), 8u, s.chord_shift}}) {
      const uint64_t page = (uint64_t{1} << shift) * unit;
      if ((bytes + page - 1) / page > kGridPages)
        throw Error(std::string("vrc: the grid's ") + name + " take " +
                    std::to_string(bytes >> 20) + " MiB, more than " + std::to_string(kGridPages) +
                    " storage buffers of " + std::to_string(page >> 20) + " MiB hold on " +
                    context.info().name + "; use --on cpu or a coarser grid");
    }
    s.offset_pages = s.upload_pages(grid.offsets.data(), grid.offsets.bytes(), 4, s.offset_shift);
    s.chord_pages = s.upload_pages(grid.chords.data(), grid.chords.bytes(), 8, s.chord_shift);
  }
  s.uniforms = context.create_buffer(sizeof(VrcUniforms), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, true);
  // Split: bindings 1 and 2 hold one word each (bound, never read).
  s.offsets = paged ? s.upload(nullptr, 0) : s.upload(grid.offsets.data(), grid.offsets.bytes());
  s.chords = paged ? s.upload(nullptr, 0) : s.upload(grid.chords.data(), grid.chords.bytes());
  s.occupancy = s.upload(occupancy.words.data(), occupancy.bytes());
  s.hold_slices(kSliceCounters);
  VkDevice d = context.device();
  const BufferSet b =
      create_buffer_set(d, kVrcBindings, VK_SHADER_STAGE_COMPUTE_BIT, {kGridPages, kGridPages});
  s.set_layout = b.set_layout, s.layout = b.layout, s.pool = b.pool, s.set = b.set;
  const uint32_t paged_constant = paged ? 1u : 0u;  // vrc.comp kPaged
  const VkSpecializationMapEntry entry{0, 0, 4};
  const VkSpecializationInfo specialisation{1, &entry, 4, &paged_constant};
  s.pipeline = create_compute_pipeline(d, s.layout, "vrc.comp", &specialisation);
  s.queries = context.create_timestamp_pair();
}

VoxelCaster::~VoxelCaster() = default;

double VoxelCaster::last_gpu_ms() const {
  return state_->gpu_ms;
}

void VoxelCaster::set_slice_steps(uint32_t steps, uint32_t band_rows) {
  state_->slice_steps = steps;
  state_->band_rows = band_rows;
}

uint32_t VoxelCaster::grid_buffers() const {
  const State& s = *state_;
  return s.offset_pages.empty() ? 2u : uint32_t(s.offset_pages.size() + s.chord_pages.size());
}

uint64_t VoxelCaster::grid_bytes() const {
  const State& s = *state_;
  uint64_t bytes = s.offsets.size + s.chords.size + s.occupancy.size;
  for (const auto* pages : {&s.offset_pages, &s.chord_pages})
    for (const Buffer& b : *pages) bytes += b.size;
  return bytes;
}

VrcFrame VoxelCaster::render(const Camera& camera, const TransferFunction& tf_in,
                             const VrcOptions& o) {
  if (o.width < 1 || o.height < 1) throw Error("vrc: empty image size");
  const auto start = std::chrono::steady_clock::now();
  State& s = *state_;
  s.resize(o.width, o.height);
  TransferFunction tf = tf_in;
  if (tf.range[0] == 0 && tf.range[1] == 0)
    tf.range = {double(s.attribute_range[0]), double(s.attribute_range[1])};
  VrcUniforms u{};
  write_view(u, camera, o.width, o.height, o.shading);
  for (int k = 0; k < 3; ++k) {
    u.origin[k] = s.origin[size_t(k)];
    u.grid[k] = s.grid_info[size_t(k)];
  }
  u.grid[3] = s.grid_info[3];
  u.ranges[0] = s.attribute_range[0], u.ranges[1] = s.attribute_range[1];
  u.ranges[2] = float(tf.range[0]), u.ranges[3] = float(tf.range[1]);
  u.size[0] = uint32_t(o.width), u.size[1] = uint32_t(o.height);
  u.size[2] = o.early_termination ? 1u : 0u, u.size[3] = o.skip_empty_space ? 1u : 0u;
  write_transfer_table(tf, u.colours, u.opacities, u.tf_counts);
  VrcFrame frame;
  frame.stats.radius = vrc_radius(s.grid, o.radius);
  frame.stats.radius_clamped = o.radius > double(s.voxel_size);
  u.params[0] = float(o.termination_alpha), u.params[1] = float(frame.stats.radius);
  u.params[2] = s.voxel_size;
  u.levels[0] = uint32_t(s.levels.size());
  u.levels[1] = s.offset_shift, u.levels[2] = s.chord_shift;
  for (size_t k = 0; k < s.levels.size(); ++k)
    for (size_t c = 0; c < 4; ++c) u.level_resolution[k][c] = s.levels[k][c];
  // The eye's place in the grid in double: float32 world coordinates far from the origin, or of
  // a grid a millionth of a unit across, lose the ray's start.
  for (int k = 0; k < 3; ++k)
    u.eye_grid[k] = float((camera.eye[k] - double(s.origin[size_t(k)])) / double(s.voxel_size));
  const bool lavapipe = s.ctx.info().lavapipe;
  u.slicing[2] = lavapipe ? kSentinel : 0u;
  uint32_t* counters = static_cast<uint32_t*>(s.slices.mapped);
  // One dispatch over rows [first, first + rows) with the uniforms as set; the counters after it.
  const auto dispatch = [&](uint32_t first, uint32_t rows) {
    u.slicing[3] = first;
    u.band[0] = rows;
    std::memcpy(s.uniforms.mapped, &u, sizeof u);
    counters = static_cast<uint32_t*>(s.slices.mapped);
    counters[0] = counters[1] = 0;
    s.gpu_ms += s.ctx.timed_submit(s.queries, [&](VkCommandBuffer cmd) {
      vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, s.pipeline);
      vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, s.layout, 0, 1, &s.set, 0,
                              nullptr);
      vkCmdDispatch(cmd, uint32_t(o.width + 7) / 8, (rows + 7) / 8, 1);
      VkMemoryBarrier barrier{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
      barrier.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
      barrier.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
      vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0,
                           1, &barrier, 0, nullptr, 0, nullptr);
    });
    ++frame.stats.gpu_slices;
    return std::pair<uint32_t, uint32_t>{counters[0], counters[1]};  // cut short, unfinished
  };
  // The whole frame with walks of at most `steps` a dispatch (0: whole walks); false where the
  // loop limit cut one short.
  const auto walk = [&](uint32_t steps) {
    u.slicing[0] = steps;
    const uint64_t row_bytes = uint64_t(o.width) * kStateBytes;
    uint64_t most = s.band_rows > 0 ? s.band_rows : uint64_t(o.height);
    if (steps > 0) {
      most = std::min(most, (s.max_buffer - kSliceCounters) / row_bytes);
      // Bands of what the memory budget leaves (the state buffer there now goes first).
      if (const uint64_t left = s.ctx.host_bytes_left(); left != Context::kNoHostLimit) {
        const uint64_t room = left + s.slices.host_bytes;
        most = std::min(most, room > kSliceCounters ? (room - kSliceCounters) / row_bytes : 0);
      }
    }
    const uint32_t band = uint32_t(std::clamp<uint64_t>(most, 1, uint64_t(o.height)));
    if (steps > 0) try {
        s.hold_slices(kSliceCounters + uint64_t(band) * row_bytes);
      } catch (const HostBudgetExceeded& e) {
        throw HostBudgetExceeded(std::string("the walks' state between slices (lavapipe's loop "
                                             "limit cut a walk short): ") +
                                 e.what());
      }
    // A walk takes at most a step a voxel it crosses (a skip leaves its cell through a face):
    // more dispatches than that would be a fault, not slow work.
    const uint64_t most_slices =
        steps == 0 ? 1
                   : (uint64_t(s.grid_info[0]) + s.grid_info[1] + s.grid_info[2] + 2) / steps + 2;
    for (uint32_t first = 0; first < uint32_t(o.height); first += band) {
      const uint32_t rows = std::min(band, uint32_t(o.height) - first);
      u.slicing[1] = 1;  // the first slice starts every walk at the eye
      for (uint64_t slice = 0;; ++slice) {
        throw_if_interrupted();
        if (slice == most_slices)
          throw Error("vrc --on gpu: walks of rows " + std::to_string(first) + " to " +
                      std::to_string(first + rows - 1) + " did not end in " +
                      std::to_string(most_slices) + " slices of " + std::to_string(steps) +
                      " steps, more than a walk through the grid takes");
        const auto [cut_short, unfinished] = dispatch(first, rows);
        if (cut_short > 0) return false;
        if (unfinished == 0) break;
        u.slicing[1] = 0;
      }
    }
    return true;
  };
  // The GPU time and dispatches of walks cut short count: the frame took them.
  s.gpu_ms = 0;
  uint32_t steps = s.slice_steps;
  while (!walk(steps)) {
    if (steps == 1)
      throw Error("vrc --on gpu: " + s.ctx.info().name +
                  "'s loop limit cuts even one voxel step short; use --on cpu");
    steps = steps == 0 ? kFirstSliceSteps : steps / 2;
  }
  s.slice_steps = steps;  // later frames start from what this one needed
  frame.stats.gpu_slice_steps = steps;
  const uint64_t pixels = uint64_t(o.width) * uint64_t(o.height);
  PixelReadback read = s.targets.read(s.ctx);
  frame.image = std::move(read.image);
  frame.alpha = std::move(read.alpha);
  frame.depth_complexity = std::move(read.counts);
  frame.stats.hits = read.total;
  frame.stats.max_depth_complexity = read.maximum;
  frame.stats.frame_bytes = pixels * (16 + 4) + s.slices_bytes;
  frame.stats.seconds = seconds_since(start);
  return frame;
}

}  // namespace linebake::vk
