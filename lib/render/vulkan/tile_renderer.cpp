#include "render/vulkan/tile_renderer.hpp"

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <functional>
#include <limits>
#include <numeric>
#include <span>
#include <string>
#include <tuple>

#include "core/error.hpp"
#include "render/vulkan/buffer_set.hpp"
#include "render/vulkan/pixel_readback.hpp"
#include "render/vulkan/radix_sort.hpp"
#include "render/vulkan/shaders.hpp"
#include "render/vulkan/spirv_layout.hpp"
#include "render/vulkan/transfer_table.hpp"
#include "render/vulkan/view_uniforms.hpp"

namespace linebake::vk {
namespace {

constexpr uint32_t kTile = 16;
// 0 uniforms, 1 points, 2 segments, 3 keys, 4 values, 5 counters, 6 ranges, 7 pixels, 8 hit
// counts, 9 stats, 10 the slice, 11 pixel states, 12 keys per tile row, 13 the tiles of each
// slice, 14 the tiles to walk again, 15 each tile's state slot, 16 the keys' far depths by
// chunks, 17 each tile's first key in a walk again, 18 the uniforms again as a storage buffer
// (shaders/tiles.glsl, tiles_composite.glsl); 19 and 20 (arrays) the primitives' units and
// words past one storage buffer, pages 1 on (shaders/tiles_pages.glsl).
constexpr uint32_t kTileBindings = 19;
// Pages of units (points; vertices, two each) and of words (segment words; indices), the first
// at bindings 1 and 2: 8 and 4 keep the set's storage buffers within Mesa gallium's 32 a stage
// (shaders/pages.glsl), and on NVIDIA (pages of 2 GiB) hold 2^30 points, more than a segment word
// addresses (2^30 - 1), and 2^31 words.
constexpr uint32_t kUnitPages = 8, kWordPages = 4;
// Keys per chunk of chunk_far: a batch of the composite (kBatch in shaders/tiles_composite.comp
// and tiles_composite_triangles.comp).
constexpr uint32_t kChunkKeys = 256;
// walk_again of a tile none of whose pixels left hits for another walk.
constexpr uint32_t kNoWalkAgain = 0xFFFFFFFFu;
// A tile with more than this many times the mean keys of a walk's tiles is crowded: the
// composite dispatches it first (TileOptions::most_keys_first), in strips with
// TileStrips::crowded.
constexpr uint64_t kCrowded = 8;
// Workgroups a tile in strips (kStrips in shaders/tiles_composite.glsl; TileOptions::strips).
constexpr uint32_t kStrips = 4;
// Device memory per (tile, segment) key: key and value words with an eighth more room, and the
// radix sort's scratch (8 bytes a key, and its digit counts: a quarter byte a key with blocks of
// 4,096), rounded up.
constexpr uint64_t kKeyBytes = 18;
// The keys and values: the key sort copies its result back into them after an odd number of
// passes (radix_sort.hpp).
constexpr VkBufferUsageFlags kSortedUsage =
    VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
// The hits a pixel's state keeps pending between slices and walks (kStateWindow in
// tiles_composite.glsl): 16 in the composite whose window loops exit, 8 in the one of fixed trips.
constexpr uint32_t state_window_of(bool window_exits) {
  return window_exits ? 16 : 8;
}
// A pixel's state between slices (tiles_composite.glsl PixelState, std430: 20 words, then t,
// primitive and, unless the build shades late, an rgba colour per pending hit). The renderer
// checks each composite's own layout against it when it is made.
constexpr uint64_t pixel_state_bytes_of(uint32_t state_window, bool late_shading) {
  return 20 * 4 + state_window * (4 + 4 + (late_shading ? 0 : 16));
}
constexpr uint64_t tile_state_bytes_of(uint32_t state_window, bool late_shading) {
  return uint64_t(kTile) * kTile * pixel_state_bytes_of(state_window, late_shading);
}
// The composite's pixel state as its SPIR-V lays it out (the stride of binding 11's array)
// against the bytes the host sizes the states with.
void check_state_layout(const std::string& shader, uint32_t state_window, bool late_shading) {
  const uint64_t expected = pixel_state_bytes_of(state_window, late_shading);
  for (const SpirvBinding& b : reflect_layout(shader_spirv(shader), shader).bindings)
    if (b.set == 0 && b.binding == 11) {
      if (b.array_stride == expected) return;
      throw Error("tiles: shader " + shader + " lays out a pixel's state in " +
                  std::to_string(b.array_stride) + " bytes, the renderer sizes it as " +
                  std::to_string(expected) + " (a build of shaders and code that disagree)");
    }
  throw Error("tiles: shader " + shader + " has no pixel states at binding 11");
}
// Keys per tile per dispatch to start with where the driver caps an invocation's loop iterations
// (lavapipe's gallivm: 65535 in all): 8 trips a key, which holds in practice, not in the worst
// case (a key's entry, pair and hit take a few trips each where the key is near the pixel, the
// window's loops one per hit composited). A dispatch that runs out costs its group composited
// again in slices a quarter the size, which the renderer then keeps. Each slice reloads and stores
// its pixels' states, and the later slices of a frame dispatch only its crowded tiles, leaving
// lavapipe's threads idle: paper-small's four sets (tiles of up to 27,857 keys) ran out at none of
// 2,048 to 32,768 keys, and 8,192 took convection's composite 13 to 16 % less time than 2,048
// (docs/tiles.md).
constexpr uint32_t kCappedSliceKeys = 8192;

struct TileUniforms {
  float eye[4], forward[4], right[4], up[4];
  float shading[4], background[4], ranges[4];
  uint32_t size[4], tf_counts[4];
  float params[4];
  uint32_t tiles[4];
  uint32_t band[4];     // first tile row, one past the last
  uint32_t binning[4];  // pixels a primitive's bounds hold at most to be tested
  float colours[kMaxTfPoints][4];
  float opacities[kMaxTfPoints][4];
};

struct Counters {
  uint32_t key_count, binned;
};
struct CompositeStats {
  uint32_t window_overflows, cut_short, late_misses;
};
// Slice `slice` composites keys [slice * slice_keys, (slice + 1) * slice_keys) of the tiles
// slice_tiles[tile_offset, tile_offset + tile_count): those that have keys there (slice 0: all).
// `sentinel`: the trips of the loop that tells an invocation cut short (tiles_composite.glsl);
// `walk` > 0: a walk again over tiles whose pixels left hits for it; the first `strip_tiles` of
// the tiles go to the composite of strips (TileOptions::strips), the rest to the other.
struct SliceInfo {
  uint32_t slice, slice_keys, tile_offset, tile_count, sentinel, walk, strip_tiles;
};

}  // namespace

struct TileRenderer::State {
  Context& ctx;
  RadixSorter sorter;
  uint64_t primitive_count = 0;  // capsule segments or triangles
  uint64_t max_buffer = 0;
  std::array<float, 2> attribute_range{};
  glm::dvec3 centre{};
  double extent = 0;  // radius of the bounding sphere, capsules included
  float radius = 0;   // capsules; 0 for triangles
  Buffer uniforms, points, segments, keys, values, counters, ranges, stats, slice, states, rows,
      slice_tiles, walk_again, tile_slots, chunk_far, walk_first;
  // The units' and words' pages past the first (primitives that pass one storage buffer; `points`
  // and `segments` hold the vertices and indices in triangle mode), and the shaders'
  // specialisation: paged or not, and 2^shift units and words a page.
  std::vector<Buffer> point_pages, segment_pages;
  struct Paging {
    VkBool32 paged = VK_FALSE;
    uint32_t unit_shift = 31, word_shift = 31;
  } paging;
  std::array<VkSpecializationMapEntry, 3> paging_entries{
      {{0, offsetof(Paging, paged), sizeof(VkBool32)},
       {1, offsetof(Paging, unit_shift), sizeof(uint32_t)},
       {2, offsetof(Paging, word_shift), sizeof(uint32_t)}}};
  VkSpecializationInfo paging_info{3, paging_entries.data(), sizeof(Paging), &paging};
  uint32_t slice_keys = 0;    // 0: a tile's keys in one dispatch
  uint32_t state_window = 0;  // the composite's (above)
  PixelTargets targets;
  BufferSet set;
  // bin, ranges, composite; and where the window loops exit, the composite with the deeper
  // window for walks again over tiles of one slice (shaders/tiles_composite.glsl); then the two
  // composites again over strips of tiles (TileOptions::strips), the two with each pixel's own
  // hits (TileOptions::pixel_hits), the two that shade late (TileOptions::late_shading) and the
  // two with both, made when first used.
  static constexpr size_t kMadeAtInit = 4;   // the rest: when first used
  static constexpr size_t kLateShaders = 8;  // shaders 8 to 11 shade late
  std::array<std::string, 12> shaders;
  std::array<VkPipeline, 12> pipelines{};
  VkQueryPool queries = VK_NULL_HANDLE;

  State(Context& c, bool sort_subgroups) : ctx(c), sorter(c, sort_subgroups) {}
  // Uploads the primitives (vertex_stride floats per vertex, x y z first) and makes the passes.
  void init(const std::vector<float>& vertex_words, const std::vector<uint32_t>& primitive_words,
            uint64_t primitives, uint32_t vertex_stride, uint64_t max_buffer_bytes,
            uint32_t slice_keys_wanted, bool triangles, WindowLoops window_loops);

  // The composite of whole tiles for these options: the rounds 2, each pixel's own hits 6, late
  // shading 8, both 10 (`shaders`); the next one is its walks again with the deeper window.
  static size_t whole_composite(const TileOptions& o) {
    return o.late_shading ? (o.pixel_hits ? 10 : 8) : (o.pixel_hits ? 6 : 2);
  }
  // Pipeline i, made now if it was left for its first use ("": none).
  VkPipeline pipeline(size_t i) {
    if (!pipelines.at(i) && !shaders.at(i).empty())
      pipelines[i] =
          create_compute_pipeline(ctx.device(), set.layout, shaders[i].c_str(), &paging_info);
    return pipelines[i];
  }

  void bind() {
    write_buffer_set(ctx.device(), set.set,
                     {&uniforms, &points, &segments, &keys, &values, &counters, &ranges,
                      &targets.rgba.gpu, &targets.counts.gpu, &stats, &slice, &states, &rows,
                      &slice_tiles, &walk_again, &tile_slots, &chunk_far, &walk_first, &uniforms});
    // Pages not there are bound to the first, which the shaders then never read through them.
    for (const auto& [binding, first, pages, count] :
         {std::tuple{kTileBindings, &points, &point_pages, kUnitPages},
          std::tuple{kTileBindings + 1, &segments, &segment_pages, kWordPages}}) {
      std::vector<const Buffer*> bound;
      for (size_t i = 0; i + 1 < count; ++i)
        bound.push_back(i < pages->size() ? &(*pages)[i] : first);
      write_buffer_array(ctx.device(), set.set, binding, bound);
    }
  }

  // `words` in a first buffer and pages of 2^shift units of `unit` words after it, `shift` the
  // largest that one storage buffer holds when they do not fit one; refused past `most` pages.
  void upload_paged(const void* data, uint64_t units, uint64_t unit_bytes, uint32_t most,
                    const std::string& name, Buffer& first, std::vector<Buffer>& pages,
                    uint32_t& shift);

  ~State() {
    VkDevice d = ctx.device();
    vkDeviceWaitIdle(d);
    for (Buffer* b :
         {&uniforms, &points, &segments, &keys, &values, &counters, &ranges, &stats, &slice,
          &states, &rows, &slice_tiles, &walk_again, &tile_slots, &chunk_far, &walk_first})
      ctx.destroy(*b);
    for (std::vector<Buffer>* pages : {&point_pages, &segment_pages})
      for (Buffer& b : *pages) ctx.destroy(b);
    targets.release(ctx);
    for (VkPipeline p : pipelines)
      if (p) vkDestroyPipeline(d, p, nullptr);
    if (queries) vkDestroyQueryPool(d, queries, nullptr);
    if (set.pool) vkDestroyDescriptorPool(d, set.pool, nullptr);
    if (set.layout) vkDestroyPipelineLayout(d, set.layout, nullptr);
    if (set.set_layout) vkDestroyDescriptorSetLayout(d, set.set_layout, nullptr);
  }
};

void TileRenderer::State::init(const std::vector<float>& vertex_words,
                               const std::vector<uint32_t>& primitive_words, uint64_t primitives,
                               uint32_t vertex_stride, uint64_t max_buffer_bytes,
                               uint32_t slice_keys_wanted, bool triangles,
                               WindowLoops window_loops) {
  primitive_count = primitives;
  glm::dvec3 lo(1e300), hi(-1e300);
  for (size_t i = 0; i + 3 <= vertex_words.size(); i += vertex_stride)
    for (int k = 0; k < 3; ++k)
      lo[k] = std::min(lo[k], double(vertex_words[i + size_t(k)])),
      hi[k] = std::max(hi[k], double(vertex_words[i + size_t(k)]));
  if (vertex_words.empty()) lo = hi = glm::dvec3(0);
  centre = 0.5 * (lo + hi);
  extent = 0.5 * glm::length(hi - lo) + radius;
  VkPhysicalDeviceProperties props;
  vkGetPhysicalDeviceProperties(ctx.physical_device(), &props);
  max_buffer = props.limits.maxStorageBufferRange;
  if (max_buffer_bytes > 0) max_buffer = std::min(max_buffer, max_buffer_bytes);
  const VkBufferUsageFlags storage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
  // Past one storage buffer, in pages (shaders/tiles_pages.glsl).
  upload_paged(vertex_words.data(), vertex_words.size() / 4, 16, kUnitPages,
               triangles ? "vertices" : "points", points, point_pages, paging.unit_shift);
  upload_paged(primitive_words.data(), primitive_words.size(), 4, kWordPages,
               triangles ? "indices" : "segment words", segments, segment_pages, paging.word_shift);
  paging.paged = point_pages.empty() && segment_pages.empty() ? VK_FALSE : VK_TRUE;
  uniforms =
      ctx.create_buffer(sizeof(TileUniforms), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT | storage, true);
  counters = ctx.create_buffer(sizeof(Counters), storage, true);
  stats = ctx.create_buffer(sizeof(CompositeStats), storage, true);
  keys = ctx.create_buffer(4, kSortedUsage, false);
  values = ctx.create_buffer(4, kSortedUsage, false);
  ranges = ctx.create_buffer(8, storage, true);
  rows = ctx.create_buffer(4, storage, true);
  slice = ctx.create_buffer(sizeof(SliceInfo), storage | VK_BUFFER_USAGE_TRANSFER_DST_BIT, false);
  states = ctx.create_buffer(4, storage, false);
  slice_tiles = ctx.create_buffer(4, storage, true);
  walk_again = ctx.create_buffer(4, storage, true);
  tile_slots = ctx.create_buffer(4, storage, true);
  chunk_far = ctx.create_buffer(4, storage, true);
  walk_first = ctx.create_buffer(4, storage, true);
  const bool lavapipe = ctx.info().lavapipe;
  slice_keys = slice_keys_wanted > 0 ? slice_keys_wanted : lavapipe ? kCappedSliceKeys : 0;
  VkDevice d = ctx.device();
  set = create_buffer_set(d, kTileBindings, VK_SHADER_STAGE_COMPUTE_BIT,
                          {kUnitPages - 1, kWordPages - 1});
  // The composite whose window loops leave past the pending hits, except on lavapipe, where
  // they run slower than loops of fixed trips (shaders/tiles_composite.glsl).
  const bool exits =
      window_loops == WindowLoops::by_device ? !lavapipe : window_loops == WindowLoops::exits;
  state_window = state_window_of(exits);
  const std::string composite =
      triangles ? "tiles_composite_triangles.comp" : "tiles_composite.comp";
  // With loops of fixed trips, the capsules' ends in 64-bit words where the device has them
  // (lavapipe: one shared load instead of two, tiles_composite.comp).
  const bool wide = !exits && !triangles && ctx.info().shader_int64;
  const std::string variant = exits ? ":exits" : wide ? ":wide" : "";
  shaders = {triangles ? "tiles_bin_triangles.comp" : "tiles_bin.comp",
             "tiles_ranges.comp",
             composite + variant,
             exits ? composite + ":deep" : "",
             composite + (variant.empty() ? ":strips" : variant + "-strips"),
             exits ? composite + ":deep-strips" : "",
             composite + (exits ? ":exits-pixels" : ":pixels"),
             exits ? composite + ":deep-pixels" : "",
             composite + (exits ? ":exits-late" : ":late"),
             exits ? composite + ":deep-late" : "",
             composite + (exits ? ":exits-pixels-late" : ":pixels-late"),
             exits ? composite + ":deep-pixels-late" : ""};
  // A composite that lays out a pixel's state otherwise than the host sizes it reads and writes
  // past the states it was given (one such build hung a walk again): refused here instead.
  for (size_t i = 2; i < shaders.size(); ++i)
    if (!shaders[i].empty()) check_state_layout(shaders[i], state_window, i >= kLateShaders);
  // The other composites (strips, the pixels' own hits, late shading) are made when a frame
  // first asks for them.
  for (size_t i = 0; i < kMadeAtInit; ++i)
    if (!shaders[i].empty())
      pipelines[i] = create_compute_pipeline(d, set.layout, shaders[i].c_str(), &paging_info);
  queries = ctx.create_timestamp_pair();
}

void TileRenderer::State::upload_paged(const void* data, uint64_t units, uint64_t unit_bytes,
                                       uint32_t most, const std::string& name, Buffer& first,
                                       std::vector<Buffer>& pages, uint32_t& shift) {
  const VkBufferUsageFlags storage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
  const auto* bytes = static_cast<const uint8_t*>(data);
  if (units * unit_bytes <= max_buffer) {
    first = ctx.upload(data, units * unit_bytes, storage);
    return;
  }
  if (max_buffer < unit_bytes)
    throw Error("tiles: a storage buffer of " + std::to_string(max_buffer) +
                " bytes holds none of the " + name);
  shift = uint32_t(std::bit_width(max_buffer / unit_bytes) - 1);
  const uint64_t per_page = uint64_t{1} << shift;
  const uint64_t count = (units + per_page - 1) / per_page;
  if (count > most)
    throw BudgetExceeded(
        "tiles: the " + name + " take " + std::to_string((units * unit_bytes) >> 20) +
        " MiB, more than " + std::to_string(most) + " storage buffers of " +
        std::to_string((per_page * unit_bytes) >> 20) + " MiB hold on " + ctx.info().name);
  first = ctx.upload(bytes, per_page * unit_bytes, storage);
  for (uint64_t p = 1; p < count; ++p)
    pages.push_back(ctx.upload(bytes + p * per_page * unit_bytes,
                               std::min(per_page, units - p * per_page) * unit_bytes, storage));
}

TileRenderer::TileRenderer(Context& context, const CapsuleSegments& capsules,
                           uint64_t max_buffer_bytes, uint32_t slice_keys, bool sort_subgroups,
                           WindowLoops window_loops)
    : state_(std::make_unique<State>(context, sort_subgroups)) {
  State& s = *state_;
  s.radius = capsules.radius;
  s.attribute_range = capsules.attribute_range;
  // One array of points and one of segment words over all chunks (words re-based).
  std::vector<float> points;
  std::vector<uint32_t> words;
  uint64_t point_values = 0;
  for (const CapsuleChunk& chunk : capsules.chunks) point_values += chunk.points.size();
  points.reserve(point_values);  // exactly: capsule_upload_bytes
  words.reserve(capsules.segment_count());
  for (const CapsuleChunk& chunk : capsules.chunks) {
    const uint64_t base = points.size() / 4;
    if (base + chunk.points.size() / 4 >= (uint64_t{1} << 30))
      throw Error("tiles: 2^30 points or more; not supported yet");
    points.insert(points.end(), chunk.points.begin(), chunk.points.end());
    for (uint32_t w : chunk.segments)
      words.push_back((((w >> 2) + uint32_t(base)) << 2) | (w & 3u));
  }
  // The composite marks dropped hits in a primitive number's top bit.
  if (words.size() >= (uint64_t{1} << 31))
    throw Error("tiles: more than 2^31 - 1 segments; not supported yet");
  s.init(points, words, words.size(), 4, max_buffer_bytes, slice_keys, false, window_loops);
}

namespace {

// Appends a tube chunk's vertices (x, y, z, attribute value, then the normal) and its indices,
// re-based past the vertices before it.
void append_tube_chunk(const TubeChunk& chunk, const std::array<float, 2>& attribute_range,
                       std::vector<float>& vertices, std::vector<uint32_t>& indices) {
  const uint64_t base = vertices.size() / 8;
  if (base + chunk.vertex_count() > UINT32_MAX)
    throw Error("tiles: more than 2^32 tube vertices; not supported yet");
  for (uint64_t v = 0; v < chunk.vertex_count(); ++v) {
    const float value =
        chunk.attribute.empty() ? 0.0f : decode_unorm16(chunk.attribute[v], attribute_range);
    std::array<float, 3> n{0, 0, 1};
    if (!chunk.normals.empty())
      n = {chunk.normals[3 * v], chunk.normals[3 * v + 1], chunk.normals[3 * v + 2]};
    else if (!chunk.normals_oct.empty())
      n = decode_octahedral(chunk.normals_oct[2 * v], chunk.normals_oct[2 * v + 1]);
    vertices.insert(vertices.end(), {chunk.positions[3 * v], chunk.positions[3 * v + 1],
                                     chunk.positions[3 * v + 2], value, n[0], n[1], n[2], 0.0f});
  }
  for (uint32_t i : std::span(chunk.indices.data(), chunk.indices.size()))
    indices.push_back(i + uint32_t(base));
}

}  // namespace

// The chunks' arrays are shared, not copied (Array's copies are views of one owner).
TileRenderer::TileRenderer(Context& context, const TubeMesh& mesh, uint64_t max_buffer_bytes,
                           uint32_t slice_keys, bool sort_subgroups, WindowLoops window_loops)
    : TileRenderer(
          context, mesh, TubeCounts{mesh.vertex_count(), mesh.triangle_count()},
          [&mesh](size_t c) { return mesh.chunks[c]; }, max_buffer_bytes, slice_keys,
          sort_subgroups, window_loops) {}

TileRenderer::TileRenderer(Context& context, const TubeMesh& description, const TubeCounts& counts,
                           const std::function<TubeChunk(size_t)>& chunk, uint64_t max_buffer_bytes,
                           uint32_t slice_keys, bool sort_subgroups, WindowLoops window_loops)
    : state_(std::make_unique<State>(context, sort_subgroups)) {
  State& s = *state_;
  s.attribute_range = description.attribute_range;
  std::vector<float> vertices;
  std::vector<uint32_t> indices;
  vertices.reserve(counts.vertices * 8);
  indices.reserve(counts.triangles * 3);
  for (size_t c = 0; c < description.chunks.size(); ++c)
    append_tube_chunk(chunk(c), description.attribute_range, vertices, indices);
  s.init(vertices, indices, indices.size() / 3, 8, max_buffer_bytes, slice_keys, true,
         window_loops);
}

TileRenderer::~TileRenderer() = default;

namespace {

// The tile rows of each band: consecutive rows whose keys fit `limit` together. A row over the
// limit on its own is refused (one tile row is the smallest band).
std::vector<std::pair<uint32_t, uint32_t>> plan_bands(const uint32_t* row_keys, uint32_t rows,
                                                      uint64_t limit) {
  std::vector<std::pair<uint32_t, uint32_t>> bands;
  uint32_t first = 0;
  uint64_t keys = 0;
  for (uint32_t row = 0; row < rows; ++row) {
    if (row_keys[row] > limit) return {};
    if (keys + row_keys[row] > limit) {
      bands.emplace_back(first, row);
      first = row, keys = 0;
    }
    keys += row_keys[row];
  }
  bands.emplace_back(first, rows);
  return bands;
}

void memory_barrier(VkCommandBuffer cmd, VkAccessFlags dst, VkPipelineStageFlags stage) {
  VkMemoryBarrier b{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  b.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT;
  b.dstAccessMask = dst;
  vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                       stage, 0, 1, &b, 0, nullptr, 0, nullptr);
}

// Each tile's keys in its band's sorted keys, as the ranges pass and the composite left them in
// host-visible buffers: `ranges` (per tile its first key and one past its last), `walk_first`
// (where a tile's walk again starts) and `chunk_far` (the farthest depth of each chunk of
// kChunkKeys of a tile's keys). Read where the buffers are mapped at the time of the call.
struct TileKeys {
  const Buffer& ranges;
  const Buffer& walk_first;
  const Buffer& chunk_far;

  uint32_t first(uint32_t t) const { return static_cast<const uint32_t*>(ranges.mapped)[2 * t]; }
  uint32_t end(uint32_t t) const { return static_cast<const uint32_t*>(ranges.mapped)[2 * t + 1]; }
  // A tile's keys from where walk `walk` starts (walk 0: the first; later: walk_first).
  uint32_t walked(uint32_t t, uint32_t walk) const {
    return end(t) - (walk > 0 ? static_cast<const uint32_t*>(walk_first.mapped)[t] : first(t));
  }
  // Tile t's chunks in chunk_far (its first, and how many), as the composite indexes them.
  uint32_t first_chunk(uint32_t t) const { return first(t) / kChunkKeys + t; }
  uint32_t chunks(uint32_t t) const { return (end(t) - first(t) + kChunkKeys - 1) / kChunkKeys; }
  // Where tile t's next walk starts: its first chunk that reaches least_z, the least view depth
  // its pixels' hits may lie at (0: any); the keys before it are done with.
  uint32_t walk_again_from(uint32_t t, float least_z) const {
    const auto* far = static_cast<const float*>(chunk_far.mapped) + first_chunk(t);
    uint32_t chunk = 0;
    if (least_z > 0)
      while (chunk < chunks(t) && far[chunk] < least_z) ++chunk;
    return std::min(first(t) + chunk * kChunkKeys, end(t));
  }
  // The keys past which a tile of `list` is crowded in walk `walk` (kCrowded times the mean).
  uint64_t crowded(const std::vector<uint32_t>& list, uint32_t walk) const {
    uint64_t total = 0;
    for (uint32_t t : list) total += walked(t, walk);
    return list.empty() ? uint64_t{0} : kCrowded * total / list.size();
  }
  // The most keys a tile of `list` walks in walk `walk`, at least 1.
  uint32_t longest(const std::vector<uint32_t>& list, uint32_t walk) const {
    uint32_t most = 1;
    for (uint32_t t : list) most = std::max(most, walked(t, walk));
    return most;
  }
};

// The order a walk dispatches its tiles in, the first `strip_tiles` of them to the composite of
// strips (TileOptions::strips).
struct WalkOrder {
  std::vector<uint32_t> tiles;
  size_t strip_tiles = 0;
};

// Workgroups start roughly in the order of their IDs: the crowded tiles (more than kCrowded
// times the mean keys to walk) go first, the most keys first, and the rest follow in raster
// order, in which neighbouring tiles, which share primitives, run together.
WalkOrder order_walk(const std::vector<uint32_t>& walk_tiles, uint32_t walk,
                     const TileKeys& tile_keys, const TileOptions& o) {
  WalkOrder order{walk_tiles, 0};
  size_t crowded_count = 0;
  if (o.most_keys_first || o.strips == TileStrips::crowded) {
    const uint64_t crowded = tile_keys.crowded(walk_tiles, walk);
    const auto first =
        std::stable_partition(order.tiles.begin(), order.tiles.end(),
                              [&](uint32_t t) { return tile_keys.walked(t, walk) > crowded; });
    crowded_count = size_t(first - order.tiles.begin());
    if (o.most_keys_first)
      std::stable_sort(order.tiles.begin(), first, [&](uint32_t a, uint32_t b) {
        return tile_keys.walked(a, walk) > tile_keys.walked(b, walk);
      });
  }
  const size_t all = order.tiles.size();
  order.strip_tiles = o.strips == TileStrips::all       ? all
                      : o.strips != TileStrips::crowded ? 0
                      : all < o.few_tiles               ? all
                                                        : crowded_count;
  return order;
}

// The tiles each slice of a walk dispatches: slice k takes tiles[lists[k].offset, + count), the
// first strip_tiles of them in strips.
struct SlicePlan {
  struct List {
    uint32_t offset, count, strip_tiles;
  };
  std::vector<uint32_t> tiles;
  std::vector<List> lists;
};

// Each slice dispatches only the tiles with keys in it (the first: every tile, which starts its
// pixels), so one crowded tile does not cost a dispatch of the whole band per slice.
SlicePlan plan_slices(const WalkOrder& order, uint32_t walk, uint32_t slices, uint32_t slice_keys,
                      const TileKeys& tile_keys) {
  SlicePlan plan;
  for (uint32_t k = 0; k < slices; ++k) {
    SlicePlan::List list{uint32_t(plan.tiles.size()), 0, 0};
    for (size_t i = 0; i < order.tiles.size(); ++i) {
      const uint32_t t = order.tiles[i];
      if (k > 0 && tile_keys.walked(t, walk) <= uint64_t(k) * slice_keys) continue;
      plan.tiles.push_back(t);
      ++list.count;
      list.strip_tiles += i < order.strip_tiles;
    }
    plan.lists.push_back(list);
  }
  return plan;
}

}  // namespace

// One frame: binning of the whole image to count its keys, then per band of tile rows binning
// again where needed, the key sort and the tiles' ranges, and the composite over groups of
// tiles, each in walks (again where a full window left hits) and slices (where the device caps
// an invocation's loops).
struct TileRenderer::Frame {
  State& s;
  Context& ctx;
  const TileOptions& o;
  const std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
  uint32_t tiles_x = 0, tiles_y = 0, tiles = 0;
  uint32_t key_bits = 0;
  TileUniforms u{};
  uint64_t key_limit = 0;         // keys one band may hold
  uint64_t buffer_key_limit = 0;  // of those, what one storage buffer allows
  uint32_t group_tiles = 0;       // tiles whose pixels' states one group holds
  uint64_t state_bytes = 0;       // those states
  TileKeys tile_keys;
  TileFrame frame;
  TileStats& st = frame.stats;

  Frame(State& state, const Camera& camera, const TransferFunction& tf, const TileOptions& options);
  Frame(const Frame&) = delete;  // `st` refers to this frame's own stats
  Frame& operator=(const Frame&) = delete;
  TileFrame render();

  // Records one pass between timestamps and waits for it; its GPU milliseconds.
  double pass(const std::function<void(VkCommandBuffer)>& record);
  // Binning of the tile rows [first, last): the keys it emitted (it wrote them if they fit).
  Counters bin(uint32_t first, uint32_t last);
  void grow_keys(uint64_t keys);
  // The band's `keys` keys sorted, and each tile's range of them.
  void sort(uint32_t first, uint32_t last, uint64_t keys);
  // The composite over the band's tiles in groups whose states fit: the most slices.
  uint32_t composite_band(uint32_t first, uint32_t last);
  uint32_t composite_group(const std::vector<uint32_t>& group);
  // One walk over `walk_tiles` in `slices` slices of `slice_keys` keys per tile (walk 0: the
  // band's every tile, starting its pixels); its GPU milliseconds (composite_group tallies
  // them).
  double composite_walk(const std::vector<uint32_t>& walk_tiles, uint32_t walk, uint32_t slice_keys,
                        uint32_t slices, bool keep_states);
};

TileRenderer::Frame::Frame(State& state, const Camera& camera, const TransferFunction& tf_in,
                           const TileOptions& options)
    : s(state),
      ctx(state.ctx),
      o(options),
      tile_keys{state.ranges, state.walk_first, state.chunk_far} {
  if (o.width < 1 || o.height < 1) throw Error("tiles: empty image size");
  if (o.pixel_hits && o.strips != TileStrips::none)
    throw UsageError("tiles: each pixel's own hits (pixel_hits) are not built for strips");
  if (o.late_shading && o.strips != TileStrips::none)
    throw UsageError("tiles: late shading (late_shading) is not built for strips");
  const bool resized = s.targets.resize(ctx, o.width, o.height);
  tiles_x = (uint32_t(o.width) + kTile - 1) / kTile;
  tiles_y = (uint32_t(o.height) + kTile - 1) / kTile;
  tiles = tiles_x * tiles_y;
  // At least one tile bit: shifts by 32 are undefined in SPIR-V.
  const uint32_t tile_bits = std::max(1u, uint32_t(std::bit_width(tiles - 1)));
  // Keys of 24 bits sort in three radix passes instead of four. The depth then has 10 bits or
  // more (1,024 steps over the frame's depth range; 1920x1080 has 8,160 tiles, 13 bits): a
  // coarser depth bound only keeps hits pending a little longer.
  key_bits = o.key_bits > 0 ? o.key_bits : tile_bits <= 14 ? 24 : 32;
  if (key_bits > 32 || key_bits < tile_bits + 1)
    throw UsageError("tiles: keys of " + std::to_string(key_bits) + " bits cannot hold " +
                     std::to_string(tiles) + " tiles and a depth");
  const uint32_t depth_bits = key_bits - tile_bits;
  if (resized || s.ranges.size < uint64_t(tiles) * 8) {
    ctx.destroy(s.ranges);
    ctx.destroy(s.rows);
    ctx.destroy(s.walk_again);
    ctx.destroy(s.tile_slots);
    ctx.destroy(s.walk_first);
    s.ranges = ctx.create_buffer(uint64_t(tiles) * 8, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
    s.rows = ctx.create_buffer(uint64_t(tiles_y) * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
    s.walk_again = ctx.create_buffer(uint64_t(tiles) * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
    s.tile_slots = ctx.create_buffer(uint64_t(tiles) * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
    s.walk_first = ctx.create_buffer(uint64_t(tiles) * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
  }
  s.bind();
  TransferFunction tf = tf_in;
  if (tf.range[0] == 0 && tf.range[1] == 0)
    tf.range = {double(s.attribute_range[0]), double(s.attribute_range[1])};
  write_view(u, camera, o.width, o.height, o.shading);
  const glm::dvec3 forward = camera.image_plane(o.width, o.height).forward;
  u.ranges[2] = float(tf.range[0]), u.ranges[3] = float(tf.range[1]);
  u.size[0] = uint32_t(o.width), u.size[1] = uint32_t(o.height);
  u.size[2] = o.early_termination ? 1u : 0u, u.size[3] = uint32_t(s.primitive_count);
  // The keys' depth span: the data's bounding sphere along the view.
  const double middle = glm::dot(s.centre - camera.eye, forward);
  const double near = std::max(0.0, middle - s.extent), far = middle + s.extent;
  u.params[0] = float(o.termination_alpha), u.params[1] = s.radius;
  u.params[2] = float(near), u.params[3] = float(std::max(far, near + 1e-6));
  u.tiles[0] = tiles_x, u.tiles[1] = tiles_y, u.tiles[2] = depth_bits;
  u.binning[0] = o.tested_pixels;
  write_transfer_table(tf, u.colours, u.opacities, u.tf_counts);
  st.primitives = s.primitive_count;
  st.tiles = tiles;
  // Keys one band may hold: within one storage buffer each for keys and values (with an eighth
  // more for the next frame), and within the frame's key budget where one is set.
  buffer_key_limit = std::min<uint64_t>(s.max_buffer / 4 / 9 * 8, UINT32_MAX - 1);
  key_limit = buffer_key_limit;
  if (o.max_key_bytes > 0) key_limit = std::min(key_limit, o.max_key_bytes / kKeyBytes);
  // The pixels' states of as many tiles as one storage buffer (or the state budget) holds: the
  // tiles are composited in groups of that many (a tile's state takes 116 KiB with the window
  // loops that exit, 68 KiB with those of fixed trips: lavapipe's 128 MiB hold 1,927 tiles,
  // 1080p has 8,160; 52 and 36 KiB where the composite shades late).
  const uint64_t state_limit =
      o.max_state_bytes > 0 ? std::min(s.max_buffer, o.max_state_bytes) : s.max_buffer;
  const uint64_t tile_state = tile_state_bytes_of(s.state_window, o.late_shading);
  group_tiles = uint32_t(std::clamp<uint64_t>(state_limit / tile_state, 1, tiles));
  state_bytes = uint64_t(group_tiles) * tile_state;
}

double TileRenderer::Frame::pass(const std::function<void(VkCommandBuffer)>& record) {
  return ctx.timed_submit(s.queries, [&](VkCommandBuffer cmd) {
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, s.set.layout, 0, 1, &s.set.set, 0,
                            nullptr);
    record(cmd);
    memory_barrier(cmd, VK_ACCESS_HOST_READ_BIT, VK_PIPELINE_STAGE_HOST_BIT);
  });
}

Counters TileRenderer::Frame::bin(uint32_t first, uint32_t last) {
  u.band[0] = first, u.band[1] = last;
  u.tiles[3] = uint32_t(std::min<uint64_t>(s.keys.size / 4, UINT32_MAX));
  std::memcpy(s.uniforms.mapped, &u, sizeof u);
  std::memset(s.counters.mapped, 0, sizeof(Counters));
  std::memset(s.rows.mapped, 0, s.rows.size);
  st.bin_ms += pass([&](VkCommandBuffer cmd) {
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, s.pipelines[0]);
    dispatch_workgroups(cmd, (uint64_t(s.primitive_count) + 255) / 256, o.dispatch_row);
  });
  Counters c;
  std::memcpy(&c, s.counters.mapped, sizeof c);
  return c;
}

void TileRenderer::Frame::grow_keys(uint64_t keys) {
  const uint64_t room = std::min(key_limit, keys + keys / 8);
  ctx.destroy(s.keys);
  ctx.destroy(s.values);
  s.keys = ctx.create_buffer(room * 4, kSortedUsage, false);
  s.values = ctx.create_buffer(room * 4, kSortedUsage, false);
  s.bind();
  ++st.rebins;
}

void TileRenderer::Frame::sort(uint32_t first, uint32_t last, uint64_t keys) {
  u.band[0] = first, u.band[1] = last;
  std::memcpy(s.uniforms.mapped, &u, sizeof u);
  std::memset(s.ranges.mapped, 0, s.ranges.size);
  // A chunk of each tile's keys (chunk_far) at ranges.x / kChunkKeys + tile on: a tile of n
  // keys takes n / kChunkKeys + 1 places at most.
  if (const uint64_t chunks = keys / kChunkKeys + tiles + 1; s.chunk_far.size < chunks * 4) {
    ctx.destroy(s.chunk_far);
    s.chunk_far = ctx.create_buffer(chunks * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
    s.bind();
  }
  st.sort_ms += pass([&](VkCommandBuffer cmd) {
    s.sorter.record(cmd, s.keys, s.values, uint32_t(keys), key_bits, o.dispatch_row);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, s.set.layout, 0, 1, &s.set.set, 0,
                            nullptr);
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, s.pipelines[1]);
    dispatch_workgroups(cmd, (keys + 255) / 256 + 1, o.dispatch_row);
  });
}

double TileRenderer::Frame::composite_walk(const std::vector<uint32_t>& walk_tiles, uint32_t walk,
                                           uint32_t slice_keys, uint32_t slices, bool keep_states) {
  if ((slices > 1 || keep_states) && s.states.size < state_bytes) {
    ctx.destroy(s.states);
    s.states = ctx.create_buffer(state_bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);
    s.bind();
  }
  const WalkOrder order = order_walk(walk_tiles, walk, tile_keys, o);
  const SlicePlan plan = plan_slices(order, walk, slices, slice_keys, tile_keys);
  if (s.slice_tiles.size < plan.tiles.size() * 4) {
    ctx.destroy(s.slice_tiles);
    s.slice_tiles =
        ctx.create_buffer(plan.tiles.size() * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
    s.bind();
  }
  std::copy(plan.tiles.begin(), plan.tiles.end(), static_cast<uint32_t*>(s.slice_tiles.mapped));
  // Walks again over tiles of one slice take the deeper window where there is one.
  const bool deep = walk > 0 && slices == 1 && s.pipelines[3];
  const VkPipeline tiles_whole = s.pipeline(State::whole_composite(o) + (deep ? 1 : 0));
  const VkPipeline tiles_strips = order.strip_tiles > 0 ? s.pipeline(deep ? 5 : 4) : VK_NULL_HANDLE;
  const double ms = pass([&](VkCommandBuffer cmd) {
    const auto dispatch = [&](VkPipeline pipeline, uint32_t groups) {
      if (groups == 0) return;
      vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline);
      dispatch_workgroups(cmd, groups, o.dispatch_row);
      st.composite_workgroups += groups;
    };
    for (uint32_t k = 0; k < slices; ++k) {
      const SlicePlan::List& list = plan.lists[k];
      const SliceInfo info{k, slice_keys, list.offset, list.count, 2, walk, list.strip_tiles};
      vkCmdUpdateBuffer(cmd, s.slice.buffer, 0, sizeof info, &info);
      memory_barrier(cmd, VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT,
                     VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT);
      // The strips' tiles and the others', disjoint: the two dispatches may overlap.
      dispatch(tiles_strips, list.strip_tiles * kStrips);
      dispatch(tiles_whole, list.count - list.strip_tiles);
      memory_barrier(
          cmd,
          VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT,
          VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT);
    }
  });
  st.composite_ms += ms;
  return ms;
}

namespace {

// Composite GPU ms and tiles walked, per walk (as TileStats::walk_ms and walk_tiles).
struct WalkTally {
  std::vector<double> ms;
  std::vector<uint64_t> tiles;
  void add(uint32_t walk, double walk_ms, uint64_t walk_tiles) {
    add_to(ms, tiles, walk, walk_ms, walk_tiles);
  }
  void add(const WalkTally& other) { other.add_into(ms, tiles); }
  void add_into(std::vector<double>& ms_out, std::vector<uint64_t>& tiles_out) const {
    for (size_t w = 0; w < ms.size(); ++w) add_to(ms_out, tiles_out, uint32_t(w), ms[w], tiles[w]);
  }
  static void add_to(std::vector<double>& ms_out, std::vector<uint64_t>& tiles_out, uint32_t walk,
                     double walk_ms, uint64_t walk_tiles) {
    if (ms_out.size() <= walk) ms_out.resize(walk + 1), tiles_out.resize(walk + 1);
    ms_out[walk] += walk_ms;
    tiles_out[walk] += walk_tiles;
  }
  double total_ms() const { return std::accumulate(ms.begin(), ms.end(), 0.0); }
  uint64_t total_tiles() const { return std::accumulate(tiles.begin(), tiles.end(), uint64_t{0}); }
};

}  // namespace

// The composite pass over a group of tiles, in slices of each tile's keys where the device needs
// them, and walked again where pixels left hits for another walk (a full window): the number of
// slices. Where an invocation was cut short (lavapipe's loop limit) the group is composited
// again in slices a quarter the size; where a pixel had no room to keep its state for another
// walk, the tiles with such pixels are composited again with room (the others are written out
// already, and a tile's first walk starts its pixels afresh).
uint32_t TileRenderer::Frame::composite_group(const std::vector<uint32_t>& group) {
  auto* slots = static_cast<uint32_t*>(s.tile_slots.mapped);
  for (size_t k = 0; k < group.size(); ++k) slots[group[k]] = uint32_t(k);
  const uint32_t group_longest = tile_keys.longest(group, 0);
  for (uint32_t t : group)
    st.max_tile_keys = std::max<uint64_t>(st.max_tile_keys, tile_keys.walked(t, 0));
  if (o.most_keys_first) {
    const uint64_t crowded = tile_keys.crowded(group, 0);
    for (uint32_t t : group) st.crowded_tiles += tile_keys.walked(t, 0) > crowded;
  }
  uint32_t slice_keys = s.slice_keys > 0 ? s.slice_keys : group_longest;
  bool keep_states = false;
  CompositeStats before;
  std::memcpy(&before, s.stats.mapped, sizeof before);
  auto* again = static_cast<uint32_t*>(s.walk_again.mapped);
  auto* walk_first = static_cast<uint32_t*>(s.walk_first.mapped);
  std::vector<uint32_t> first_walk = group;
  // The walks' figures stand once the group is done: those of attempts a cut-short dispatch
  // threw away, and the first walks redone for tiles whose states had no room to stay, are
  // `redone_*`, so that walk_tiles never counts a tile twice.
  WalkTally kept, redone;
  bool redoing_first_walk = false;
  for (;;) {
    WalkTally attempt;
    std::fill_n(again, tiles, kNoWalkAgain);
    // Every chunk unknown until a walk passes it (again after a cut-short dispatch, whose
    // batches may have stopped part way).
    for (uint32_t t : group)
      std::fill_n(static_cast<float*>(s.chunk_far.mapped) + tile_keys.first_chunk(t),
                  tile_keys.chunks(t), std::numeric_limits<float>::infinity());
    uint32_t most_slices = 0, walks = 0;
    bool cut_short = false, no_room = false;
    uint64_t skipped = 0;  // keys the walks again started past
    for (std::vector<uint32_t> walk_tiles = first_walk; !walk_tiles.empty(); ++walks) {
      const uint32_t longest = tile_keys.longest(walk_tiles, walks);
      // Each walk again passes a full window (8 or 16 hits, at most one a key) of each pixel it
      // is for, so a tile takes at most keys / window + 1 walks; more means no progress (a pixel
      // state the shader and this file disagree on hung a build once), not more work.
      if (walks > group_longest / s.state_window + 1)
        throw Error("tiles: internal error: walks again over " + std::to_string(walk_tiles.size()) +
                    " tiles made no progress");
      const uint32_t slices = (longest + slice_keys - 1) / slice_keys;
      most_slices = std::max(most_slices, slices);
      const double ms = composite_walk(walk_tiles, walks, slice_keys, slices, keep_states);
      if (walks == 0 && redoing_first_walk)
        redone.add(0, ms, walk_tiles.size());
      else
        attempt.add(walks, ms, walk_tiles.size());
      const bool had_room = s.states.size >= state_bytes;
      CompositeStats after;
      std::memcpy(&after, s.stats.mapped, sizeof after);
      if ((cut_short = after.cut_short != 0)) break;
      walk_tiles.clear();
      for (uint32_t t : group) {
        if (again[t] == kNoWalkAgain) continue;
        walk_tiles.push_back(t);
        walk_first[t] = tile_keys.walk_again_from(t, std::bit_cast<float>(again[t]));
        skipped += walk_first[t] - tile_keys.first(t);
        again[t] = kNoWalkAgain;
      }
      if ((no_room = !walk_tiles.empty() && !had_room)) {
        first_walk = walk_tiles;
        break;
      }
    }
    if (!cut_short && !no_room) {
      kept.add(attempt);
      st.walks = std::max(st.walks, walks);
      st.walk_skipped_keys += skipped;
      kept.add_into(st.walk_ms, st.walk_tiles);
      st.redone_ms += redone.total_ms();
      st.redone_tiles += redone.total_tiles();
      return most_slices;
    }
    if (no_room) {
      // The first walk stands for the tiles done in it; the others walk it again, keeping their
      // states this time.
      kept.add(attempt);
      redoing_first_walk = true;
    } else {
      // Cut short: every walk of the group so far is redone in smaller slices.
      redone.add(kept);
      redone.add(attempt);
      kept = {};
      redoing_first_walk = false;
    }
    if (cut_short) {
      if (slice_keys == 1)
        throw BudgetExceeded("tiles: " + ctx.info().name + " cut a composite invocation short " +
                             "even at one key per slice (its loop iteration limit)");
      slice_keys = std::max<uint32_t>(1, slice_keys / 4);
      if (s.slice_keys > 0) s.slice_keys = slice_keys;  // for the later groups and frames
      ++st.resliced;
      first_walk = group;
    }
    keep_states = keep_states || no_room;
    std::memcpy(s.stats.mapped, &before, sizeof before);  // every overflow was a redone tile's
  }
}

uint32_t TileRenderer::Frame::composite_band(uint32_t first, uint32_t last) {
  uint32_t slices = 0, groups = 0;
  for (uint32_t t = first * tiles_x; t < last * tiles_x; t += group_tiles, ++groups) {
    std::vector<uint32_t> group;
    for (uint32_t k = t; k < std::min(t + group_tiles, last * tiles_x); ++k) group.push_back(k);
    slices = std::max(slices, composite_group(group));
  }
  st.groups = std::max(st.groups, groups);
  return slices;
}

TileFrame TileRenderer::Frame::render() {
  // The whole frame first: every key counted, per tile row.
  const Counters whole = bin(0, tiles_y);
  st.keys = whole.key_count;
  st.binned_primitives = whole.binned;
  std::vector<uint32_t> row_keys(tiles_y);
  std::memcpy(row_keys.data(), s.rows.mapped, uint64_t(tiles_y) * 4);
  st.max_row_keys = *std::max_element(row_keys.begin(), row_keys.end());
  const std::vector<std::pair<uint32_t, uint32_t>> bands =
      plan_bands(row_keys.data(), tiles_y, key_limit);
  if (bands.empty()) {
    // Which bound a band met: the keys of one storage buffer, or what the budget left them.
    const bool budget = o.max_key_bytes > 0 && o.max_key_bytes / kKeyBytes < buffer_key_limit;
    throw BudgetExceeded(
        "tiles: one row of tiles holds " + std::to_string(st.max_row_keys) + " (tile, " +
        (s.radius > 0 ? "segment" : "triangle") +
        ") keys, more than a band may: " + std::to_string(key_limit) +
        (budget ? ", what the memory budget leaves the keys (" + std::to_string(kKeyBytes) +
                      " bytes each); raise --memory-budget or render a smaller image"
                : ", what one storage buffer holds on " + ctx.info().name +
                      "; render a smaller image"));
  }
  st.bands = uint32_t(bands.size());
  uint64_t longest_band = 0;
  std::memset(s.stats.mapped, 0, sizeof(CompositeStats));
  for (const auto& [first, last] : bands) {
    uint64_t keys = 0;
    for (uint32_t row = first; row < last; ++row) keys += row_keys[row];
    longest_band = std::max(longest_band, keys);
    // The whole frame's keys are in place already when it is one band that fitted.
    if (bands.size() > 1 || whole.key_count > s.keys.size / 4) {
      if (keys > s.keys.size / 4) grow_keys(keys);
      // The rows' counts and the band's binning agree unless a count wrapped: never sort less.
      const uint32_t binned = bin(first, last).key_count;
      if (binned != keys)
        throw BudgetExceeded("tiles: tile rows " + std::to_string(first) + ".." +
                             std::to_string(last - 1) + " binned " + std::to_string(binned) +
                             " keys where their rows counted " + std::to_string(keys) +
                             " (past 2^32 keys); a smaller image renders");
    }
    sort(first, last, keys);
    st.slices = std::max(st.slices, composite_band(first, last));
  }
  CompositeStats cs;
  std::memcpy(&cs, s.stats.mapped, sizeof cs);
  st.window_overflows = cs.window_overflows;
  st.late_misses = cs.late_misses;
  PixelReadback read = s.targets.read(ctx);
  frame.image = std::move(read.image);
  frame.depth_complexity = std::move(read.counts);
  st.hits = read.total;
  st.max_depth_complexity = read.maximum;
  st.frame_bytes = s.keys.size + s.values.size + RadixSorter::scratch_bytes(longest_band) +
                   s.ranges.size + s.rows.size + s.targets.rgba.gpu.size +
                   s.targets.counts.gpu.size + s.slice_tiles.size + s.walk_again.size +
                   s.tile_slots.size + s.chunk_far.size + s.walk_first.size +
                   (st.slices > 1 || st.walks > 1 ? s.states.size : 0);
  st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return std::move(frame);
}

uint32_t TileRenderer::sort_subgroup_size() const {
  return state_->sorter.subgroup_size();
}

void TileRenderer::make_pipelines(const TileOptions& options) {
  State& s = *state_;
  const size_t whole = State::whole_composite(options);
  for (size_t i : {whole, whole + 1}) s.pipeline(i);
  if (options.strips != TileStrips::none) s.pipeline(4), s.pipeline(5);
}

uint64_t TileRenderer::tile_state_bytes(bool late_shading) const {
  return tile_state_bytes_of(state_->state_window, late_shading);
}

size_t TileRenderer::primitive_buffers() const {
  return 2 + state_->point_pages.size() + state_->segment_pages.size();
}

TileFrame TileRenderer::render(const Camera& camera, const TransferFunction& tf,
                               const TileOptions& options) {
  return Frame(*state_, camera, tf, options).render();
}

}  // namespace linebake::vk
