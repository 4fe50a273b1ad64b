#include "render/vulkan/rt_scene.hpp"

#include <algorithm>
#include <chrono>
#include <cstring>

#include "core/error.hpp"
#include "core/measure.hpp"
#include "core/memory_budget.hpp"
#include "render/vulkan/rt_functions.hpp"
#include "render/vulkan/serialized_as.hpp"

namespace linebake::vk {
namespace {

// std430 mirror of Chunk in shaders/rtx_common.glsl.
struct ChunkEntry {
  uint64_t positions = 0, normals = 0, normals_oct = 0, attributes = 0, indices = 0;
  uint32_t normal_encoding = 0, has_attribute = 0;
};
static_assert(sizeof(ChunkEntry) == 48);

constexpr VkBufferUsageFlags kInputUsage =
    VK_BUFFER_USAGE_ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_BIT_KHR |
    VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT | VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
constexpr VkBufferUsageFlags kAsUsage = VK_BUFFER_USAGE_ACCELERATION_STRUCTURE_STORAGE_BIT_KHR |
                                        VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT;

// An acceleration structure and the buffer it lives in.
struct As {
  VkAccelerationStructureKHR handle = VK_NULL_HANDLE;
  Buffer buffer;
};

// What one BLAS is built from.
struct ChunkInput {
  uint64_t primitives = 0;
  VkAccelerationStructureGeometryKHR geometry{
      VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_KHR};
};

void barrier(VkCommandBuffer cmd, VkAccessFlags src, VkAccessFlags dst) {
  VkMemoryBarrier b{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  b.srcAccessMask = src;
  b.dstAccessMask = dst;
  vkCmdPipelineBarrier(
      cmd, VK_PIPELINE_STAGE_ACCELERATION_STRUCTURE_BUILD_BIT_KHR | VK_PIPELINE_STAGE_TRANSFER_BIT,
      VK_PIPELINE_STAGE_ACCELERATION_STRUCTURE_BUILD_BIT_KHR |
          VK_PIPELINE_STAGE_RAY_TRACING_SHADER_BIT_KHR | VK_PIPELINE_STAGE_TRANSFER_BIT |
          VK_PIPELINE_STAGE_HOST_BIT,
      0, 1, &b, 0, nullptr, 0, nullptr);
}

constexpr VkAccessFlags kAsWrite = VK_ACCESS_ACCELERATION_STRUCTURE_WRITE_BIT_KHR;
constexpr VkAccessFlags kAsRead = VK_ACCESS_ACCELERATION_STRUCTURE_READ_BIT_KHR;

}  // namespace

RtGeometry parse_rt_geometry(const std::string& name) {
  if (name == "triangles") return RtGeometry::Triangles;
  if (name == "capsules") return RtGeometry::Capsules;
  throw Error("unknown ray tracing geometry '" + name + "' (triangles, capsules)");
}

const char* to_string(RtGeometry geometry) {
  return geometry == RtGeometry::Triangles ? "triangles" : "capsules";
}

nlohmann::json to_json(const RtBuildFigures& f) {
  nlohmann::json blas = nlohmann::json::array();
  for (const BlasFigures& b : f.blas)
    blas.push_back({{"primitives", b.primitives},
                    {"build_bytes", b.build_bytes},
                    {"scratch_bytes", b.scratch_bytes},
                    {"compacted_bytes", b.compacted_bytes},
                    {"serialized_bytes", b.serialized_bytes}});
  return {{"geometry", to_string(f.geometry)},
          {"compaction", f.compaction},
          {"loaded", f.loaded},
          {"seconds", f.seconds},
          {"upload_s", f.upload_s},
          {"gpu_blas_ms", f.gpu_blas_ms},
          {"gpu_compact_ms", f.gpu_compact_ms},
          {"gpu_tlas_ms", f.gpu_tlas_ms},
          {"geometry_bytes", f.geometry_bytes},
          {"blas_bytes", f.blas_bytes},
          {"scratch_bytes", f.scratch_bytes},
          {"tlas_bytes", f.tlas_bytes},
          {"tlas_scratch_bytes", f.tlas_scratch_bytes},
          {"instance_bytes", f.instance_bytes},
          {"peak_bytes", f.peak_bytes},
          {"resident_bytes", f.resident_bytes()},
          {"blas", blas}};
}

struct RtScene::State {
  Context& ctx;
  RtFunctions fn;
  RtGeometry geometry;
  std::array<float, 2> attribute_range{};
  float radius = 0;
  bool has_attribute = false;
  std::vector<Buffer> geometry_buffers;
  std::vector<ChunkInput> inputs;
  Buffer chunk_table;
  std::vector<As> blas;
  As tlas;
  Buffer instances;
  RtBuildFigures figures;
  VkQueryPool timestamps = VK_NULL_HANDLE;
  uint64_t scratch_alignment = 256;

  explicit State(Context& c, RtGeometry g)
      : ctx(c), fn(RtFunctions::load(c.device())), geometry(g) {
    if (!c.ray_tracing()) throw Error("rtx: the Vulkan context was created without ray tracing");
    figures.geometry = g;
    VkPhysicalDeviceAccelerationStructurePropertiesKHR as_props{
        VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_ACCELERATION_STRUCTURE_PROPERTIES_KHR};
    VkPhysicalDeviceProperties2 props{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2, &as_props};
    vkGetPhysicalDeviceProperties2(c.physical_device(), &props);
    scratch_alignment =
        std::max<uint64_t>(as_props.minAccelerationStructureScratchOffsetAlignment, 1);
    timestamps = c.create_timestamp_pair();
  }

  ~State() {
    VkDevice d = ctx.device();
    vkDeviceWaitIdle(d);
    release_structures();
    for (Buffer& b : geometry_buffers) ctx.destroy(b);
    ctx.destroy(chunk_table);
    if (timestamps) vkDestroyQueryPool(d, timestamps, nullptr);
  }

  void destroy(As& as) {
    if (as.handle) fn.destroy_as(ctx.device(), as.handle, nullptr);
    ctx.destroy(as.buffer);
    as = As{};
  }

  void release_structures() {
    for (As& b : blas) destroy(b);
    blas.clear();
    destroy(tlas);
    ctx.destroy(instances);
  }

  VkDeviceAddress put(const void* data, uint64_t bytes, VkBufferUsageFlags usage = kInputUsage) {
    if (bytes == 0) return 0;
    geometry_buffers.push_back(ctx.upload(data, bytes, usage));
    figures.geometry_bytes += geometry_buffers.back().size;
    return ctx.address(geometry_buffers.back());
  }

  void upload_table(const std::vector<ChunkEntry>& table) {
    chunk_table = ctx.upload(table.data(), table.size() * sizeof(ChunkEntry),
                             VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    figures.geometry_bytes += chunk_table.size;
  }

  As create_as(uint64_t size, VkAccelerationStructureTypeKHR type) {
    As as;
    as.buffer = ctx.create_buffer(size, kAsUsage, false);
    VkAccelerationStructureCreateInfoKHR create{
        VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_CREATE_INFO_KHR};
    create.buffer = as.buffer.buffer;
    create.size = size;
    create.type = type;
    const VkResult r = fn.create_as(ctx.device(), &create, nullptr, &as.handle);
    if (r != VK_SUCCESS) {
      ctx.destroy(as.buffer);
      check(r, "vkCreateAccelerationStructureKHR");
    }
    return as;
  }

  VkDeviceAddress as_address(VkAccelerationStructureKHR handle) const {
    VkAccelerationStructureDeviceAddressInfoKHR info{
        VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_DEVICE_ADDRESS_INFO_KHR};
    info.accelerationStructure = handle;
    return fn.get_as_address(ctx.device(), &info);
  }

  // A scratch buffer of at least `size` bytes at the device's scratch alignment.
  std::pair<Buffer, VkDeviceAddress> scratch(uint64_t size) {
    Buffer b = ctx.create_buffer(size + scratch_alignment,
                                 kAsUsage | VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);
    return {b, align_up(ctx.address(b), scratch_alignment)};
  }

  // Submits `record` between two timestamps; returns the GPU milliseconds (0 without them).
  template <class Record>
  double timed(Record&& record) {
    return ctx.timed_submit(timestamps, record);
  }

  VkAccelerationStructureBuildGeometryInfoKHR blas_info(const ChunkInput& input,
                                                        bool compaction) const {
    VkAccelerationStructureBuildGeometryInfoKHR info{
        VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_GEOMETRY_INFO_KHR};
    info.type = VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR;
    info.flags = VK_BUILD_ACCELERATION_STRUCTURE_PREFER_FAST_TRACE_BIT_KHR;
    if (compaction) info.flags |= VK_BUILD_ACCELERATION_STRUCTURE_ALLOW_COMPACTION_BIT_KHR;
    info.mode = VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR;
    info.geometryCount = 1;
    info.pGeometries = &input.geometry;
    return info;
  }

  void build_blas(bool compaction) {
    VkDevice d = ctx.device();
    std::vector<VkAccelerationStructureBuildGeometryInfoKHR> infos;
    uint64_t scratch_size = 0, build_total = 0;
    for (const ChunkInput& input : inputs) {
      infos.push_back(blas_info(input, compaction));
      const auto count = uint32_t(input.primitives);
      VkAccelerationStructureBuildSizesInfoKHR sizes{
          VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_SIZES_INFO_KHR};
      fn.get_build_sizes(d, VK_ACCELERATION_STRUCTURE_BUILD_TYPE_DEVICE_KHR, &infos.back(), &count,
                         &sizes);
      BlasFigures f;
      f.primitives = input.primitives;
      f.build_bytes = sizes.accelerationStructureSize;
      f.scratch_bytes = sizes.buildScratchSize;
      f.compacted_bytes = f.build_bytes;
      figures.blas.push_back(f);
      scratch_size = std::max<uint64_t>(scratch_size, sizes.buildScratchSize);
      build_total += sizes.accelerationStructureSize;
      blas.push_back(create_as(sizes.accelerationStructureSize,
                               VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR));
    }
    // (Not a structured binding: clang 14, the fuzz preset's compiler, cannot capture one.)
    auto scratch_pair = scratch(scratch_size);
    Buffer& scratch_buffer = scratch_pair.first;
    const VkDeviceAddress scratch_address = scratch_pair.second;
    figures.scratch_bytes = scratch_buffer.size;
    VkQueryPool sizes_pool = VK_NULL_HANDLE;
    if (compaction) {
      VkQueryPoolCreateInfo q{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
      q.queryType = VK_QUERY_TYPE_ACCELERATION_STRUCTURE_COMPACTED_SIZE_KHR;
      q.queryCount = uint32_t(blas.size());
      check(vkCreateQueryPool(d, &q, nullptr, &sizes_pool), "query pool (compacted sizes)");
    }
    try {
      figures.gpu_blas_ms = timed([&](VkCommandBuffer cmd) {
        if (sizes_pool) vkCmdResetQueryPool(cmd, sizes_pool, 0, uint32_t(blas.size()));
        for (size_t i = 0; i < inputs.size(); ++i) {
          infos[i].pGeometries = &inputs[i].geometry;
          infos[i].dstAccelerationStructure = blas[i].handle;
          infos[i].scratchData.deviceAddress = scratch_address;
          VkAccelerationStructureBuildRangeInfoKHR range{};
          range.primitiveCount = uint32_t(inputs[i].primitives);
          const VkAccelerationStructureBuildRangeInfoKHR* ranges = &range;
          fn.cmd_build(cmd, 1, &infos[i], &ranges);
          // The scratch is reused by the next build.
          barrier(cmd, kAsWrite, kAsWrite | kAsRead);
        }
        if (sizes_pool) {
          std::vector<VkAccelerationStructureKHR> handles;
          for (const As& b : blas) handles.push_back(b.handle);
          fn.cmd_write_properties(cmd, uint32_t(handles.size()), handles.data(),
                                  VK_QUERY_TYPE_ACCELERATION_STRUCTURE_COMPACTED_SIZE_KHR,
                                  sizes_pool, 0);
        }
      });
      figures.peak_bytes = figures.geometry_bytes + build_total + scratch_buffer.size;
      ctx.destroy(scratch_buffer);
      if (compaction) compact(sizes_pool, build_total);
    } catch (...) {
      ctx.destroy(scratch_buffer);
      if (sizes_pool) vkDestroyQueryPool(d, sizes_pool, nullptr);
      throw;
    }
    if (sizes_pool) vkDestroyQueryPool(d, sizes_pool, nullptr);
    figures.blas_bytes = 0;
    for (const BlasFigures& f : figures.blas) figures.blas_bytes += f.compacted_bytes;
  }

  void compact(VkQueryPool sizes_pool, uint64_t build_total) {
    std::vector<uint64_t> compacted(blas.size());
    check(vkGetQueryPoolResults(ctx.device(), sizes_pool, 0, uint32_t(blas.size()),
                                compacted.size() * 8, compacted.data(), 8,
                                VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT),
          "vkGetQueryPoolResults (compacted sizes)");
    std::vector<As> small;
    uint64_t small_total = 0;
    try {
      for (size_t i = 0; i < blas.size(); ++i) {
        small.push_back(create_as(compacted[i], VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR));
        figures.blas[i].compacted_bytes = compacted[i];
        small_total += compacted[i];
      }
      figures.gpu_compact_ms = timed([&](VkCommandBuffer cmd) {
        for (size_t i = 0; i < blas.size(); ++i) {
          VkCopyAccelerationStructureInfoKHR copy{
              VK_STRUCTURE_TYPE_COPY_ACCELERATION_STRUCTURE_INFO_KHR};
          copy.src = blas[i].handle;
          copy.dst = small[i].handle;
          copy.mode = VK_COPY_ACCELERATION_STRUCTURE_MODE_COMPACT_KHR;
          fn.cmd_copy(cmd, &copy);
        }
        barrier(cmd, kAsWrite, kAsRead);
      });
    } catch (...) {
      for (As& s : small) destroy(s);
      throw;
    }
    figures.peak_bytes =
        std::max(figures.peak_bytes, figures.geometry_bytes + build_total + small_total);
    for (As& b : blas) destroy(b);
    blas = std::move(small);
  }

  void build_tlas() {
    VkDevice d = ctx.device();
    if (blas.size() >= (size_t(1) << 24))
      throw Error("rtx: more than 2^24 chunks; raise the chunk size");
    std::vector<VkAccelerationStructureInstanceKHR> list(blas.size());
    for (size_t i = 0; i < blas.size(); ++i) {
      VkAccelerationStructureInstanceKHR& inst = list[i];
      inst.transform.matrix[0][0] = inst.transform.matrix[1][1] = inst.transform.matrix[2][2] = 1;
      inst.instanceCustomIndex = uint32_t(i) & 0xFFFFFFu;  // the chunk table entry (24 bits)
      inst.mask = 0xFF;
      // Hit group 0 (triangles) or 1 (capsules) of the shader binding table.
      inst.instanceShaderBindingTableRecordOffset = geometry == RtGeometry::Triangles ? 0 : 1;
      inst.flags = VK_GEOMETRY_INSTANCE_TRIANGLE_FACING_CULL_DISABLE_BIT_KHR;
      inst.accelerationStructureReference = as_address(blas[i].handle);
    }
    instances = ctx.upload(list.data(), list.size() * sizeof(VkAccelerationStructureInstanceKHR),
                           kInputUsage);
    figures.instance_bytes = instances.size;
    VkAccelerationStructureGeometryKHR geom{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_KHR};
    geom.geometryType = VK_GEOMETRY_TYPE_INSTANCES_KHR;
    geom.geometry.instances = {
        VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_INSTANCES_DATA_KHR};
    geom.geometry.instances.arrayOfPointers = VK_FALSE;
    geom.geometry.instances.data.deviceAddress = ctx.address(instances);
    VkAccelerationStructureBuildGeometryInfoKHR info{
        VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_GEOMETRY_INFO_KHR};
    info.type = VK_ACCELERATION_STRUCTURE_TYPE_TOP_LEVEL_KHR;
    info.flags = VK_BUILD_ACCELERATION_STRUCTURE_PREFER_FAST_TRACE_BIT_KHR;
    info.mode = VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR;
    info.geometryCount = 1;
    info.pGeometries = &geom;
    const auto count = uint32_t(list.size());
    VkAccelerationStructureBuildSizesInfoKHR sizes{
        VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_SIZES_INFO_KHR};
    fn.get_build_sizes(d, VK_ACCELERATION_STRUCTURE_BUILD_TYPE_DEVICE_KHR, &info, &count, &sizes);
    tlas = create_as(sizes.accelerationStructureSize, VK_ACCELERATION_STRUCTURE_TYPE_TOP_LEVEL_KHR);
    figures.tlas_bytes = tlas.buffer.size;
    // (Not a structured binding: clang 14, the fuzz preset's compiler, cannot capture one.)
    auto scratch_pair = scratch(sizes.buildScratchSize);
    Buffer& scratch_buffer = scratch_pair.first;
    const VkDeviceAddress scratch_address = scratch_pair.second;
    figures.tlas_scratch_bytes = scratch_buffer.size;
    try {
      figures.gpu_tlas_ms = timed([&](VkCommandBuffer cmd) {
        info.dstAccelerationStructure = tlas.handle;
        info.scratchData.deviceAddress = scratch_address;
        VkAccelerationStructureBuildRangeInfoKHR range{};
        range.primitiveCount = count;
        const VkAccelerationStructureBuildRangeInfoKHR* ranges = &range;
        fn.cmd_build(cmd, 1, &info, &ranges);
        barrier(cmd, kAsWrite, kAsRead);
      });
    } catch (...) {
      ctx.destroy(scratch_buffer);
      throw;
    }
    ctx.destroy(scratch_buffer);
  }
};

RtScene::RtScene(Context& context, const TubeMesh& mesh)
    : state_(std::make_unique<State>(context, RtGeometry::Triangles)) {
  State& s = *state_;
  const auto start = std::chrono::steady_clock::now();
  s.attribute_range = mesh.attribute_range;
  s.has_attribute = !mesh.attribute.empty();
  std::vector<ChunkEntry> table;
  for (const TubeChunk& chunk : mesh.chunks) {
    if (chunk.triangle_count() == 0) continue;
    ChunkEntry e;
    e.positions = s.put(chunk.positions.data(), chunk.positions.bytes());
    e.normals = s.put(chunk.normals.data(), chunk.normals.bytes());
    e.normals_oct = s.put(chunk.normals_oct.data(), chunk.normals_oct.bytes());
    e.attributes = s.put(chunk.attribute.data(), chunk.attribute.bytes());
    e.indices = s.put(chunk.indices.data(), chunk.indices.bytes());
    e.normal_encoding = mesh.normals == NormalEncoding::Oct16 ? 1 : 0;
    e.has_attribute = chunk.attribute.empty() ? 0 : 1;
    table.push_back(e);
    ChunkInput input;
    input.primitives = chunk.triangle_count();
    input.geometry.geometryType = VK_GEOMETRY_TYPE_TRIANGLES_KHR;
    input.geometry.flags = VK_GEOMETRY_OPAQUE_BIT_KHR;
    auto& t = input.geometry.geometry.triangles;
    t = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_TRIANGLES_DATA_KHR};
    t.vertexFormat = VK_FORMAT_R32G32B32_SFLOAT;
    t.vertexData.deviceAddress = e.positions;
    t.vertexStride = 12;
    t.maxVertex = uint32_t(chunk.vertex_count() - 1);
    t.indexType = VK_INDEX_TYPE_UINT32;
    t.indexData.deviceAddress = e.indices;
    s.inputs.push_back(input);
  }
  if (table.empty()) throw Error("rtx: the tube mesh has no triangles");
  s.upload_table(table);
  s.figures.upload_s = seconds_since(start);
}

RtScene::RtScene(Context& context, const CapsuleSegments& capsules)
    : state_(std::make_unique<State>(context, RtGeometry::Capsules)) {
  State& s = *state_;
  const auto start = std::chrono::steady_clock::now();
  s.attribute_range = capsules.attribute_range;
  s.has_attribute = !capsules.attribute.empty();
  s.radius = capsules.radius;
  std::vector<ChunkEntry> table;
  for (const CapsuleChunk& chunk : capsules.chunks) {
    ChunkEntry e;
    e.positions = s.put(chunk.points.data(), chunk.points.size() * 4);
    e.indices = s.put(chunk.segments.data(), chunk.segments.size() * 4);
    const VkDeviceAddress aabbs = s.put(chunk.aabbs.data(), chunk.aabbs.size() * 4);
    e.has_attribute = s.has_attribute ? 1 : 0;
    table.push_back(e);
    ChunkInput input;
    input.primitives = chunk.segment_count();
    input.geometry.geometryType = VK_GEOMETRY_TYPE_AABBS_KHR;
    input.geometry.flags = VK_GEOMETRY_OPAQUE_BIT_KHR;
    auto& a = input.geometry.geometry.aabbs;
    a = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_AABBS_DATA_KHR};
    a.data.deviceAddress = aabbs;
    a.stride = sizeof(VkAabbPositionsKHR);
    s.inputs.push_back(input);
  }
  if (table.empty()) throw Error("rtx: the line set has no segments");
  s.upload_table(table);
  s.figures.upload_s = seconds_since(start);
}

RtScene::~RtScene() = default;

void RtScene::build(bool compaction) {
  State& s = *state_;
  s.release_structures();
  s.figures.blas.clear();
  s.figures.compaction = compaction;
  s.figures.loaded = false;
  const auto start = std::chrono::steady_clock::now();
  s.build_blas(compaction);
  s.build_tlas();
  s.figures.peak_bytes = std::max(s.figures.peak_bytes, s.figures.resident_bytes());
  s.figures.seconds = seconds_since(start);
}

std::optional<std::string> RtScene::load(const std::vector<std::vector<uint8_t>>& blobs) {
  State& s = *state_;
  if (blobs.size() != s.inputs.size())
    return "the cache holds " + std::to_string(blobs.size()) + " BLAS for " +
           std::to_string(s.inputs.size()) + " chunks";
  for (size_t i = 0; i < blobs.size(); ++i) {
    if (auto problem = serialized_as_problem(blobs[i], s.ctx.info().driver_uuid))
      return "BLAS " + std::to_string(i) + ": " + *problem;
    VkAccelerationStructureVersionInfoKHR version{
        VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_VERSION_INFO_KHR};
    version.pVersionData = blobs[i].data();
    VkAccelerationStructureCompatibilityKHR compatible =
        VK_ACCELERATION_STRUCTURE_COMPATIBILITY_INCOMPATIBLE_KHR;
    s.fn.get_compatibility(s.ctx.device(), &version, &compatible);
    if (compatible != VK_ACCELERATION_STRUCTURE_COMPATIBILITY_COMPATIBLE_KHR)
      return "BLAS " + std::to_string(i) + ": the device reports it incompatible";
  }
  s.release_structures();
  s.figures.blas.clear();
  s.figures.loaded = true;
  s.figures.gpu_compact_ms = 0;
  const auto start = std::chrono::steady_clock::now();
  std::vector<Buffer> staging;
  try {
    std::vector<VkDeviceAddress> sources;
    for (size_t i = 0; i < blobs.size(); ++i) {
      const SerializedAsHeader h = parse_serialized_as(blobs[i]);
      // Deserialisation reads from a 256-byte aligned device address.
      staging.push_back(s.ctx.create_buffer(
          blobs[i].size() + 256,
          VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT | VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true));
      const VkDeviceAddress base = s.ctx.address(staging.back());
      const VkDeviceAddress aligned = align_up(base, 256);
      std::memcpy(static_cast<char*>(staging.back().mapped) + (aligned - base), blobs[i].data(),
                  blobs[i].size());
      sources.push_back(aligned);
      s.blas.push_back(
          s.create_as(h.deserialized_size, VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR));
      BlasFigures f;
      f.primitives = s.inputs[i].primitives;
      f.compacted_bytes = h.deserialized_size;
      f.serialized_bytes = blobs[i].size();
      s.figures.blas.push_back(f);
    }
    s.figures.gpu_blas_ms = s.timed([&](VkCommandBuffer cmd) {
      for (size_t i = 0; i < blobs.size(); ++i) {
        VkCopyMemoryToAccelerationStructureInfoKHR copy{
            VK_STRUCTURE_TYPE_COPY_MEMORY_TO_ACCELERATION_STRUCTURE_INFO_KHR};
        copy.src.deviceAddress = sources[i];
        copy.dst = s.blas[i].handle;
        copy.mode = VK_COPY_ACCELERATION_STRUCTURE_MODE_DESERIALIZE_KHR;
        s.fn.cmd_deserialize(cmd, &copy);
      }
      barrier(cmd, kAsWrite, kAsRead);
    });
  } catch (...) {
    for (Buffer& b : staging) s.ctx.destroy(b);
    throw;
  }
  for (Buffer& b : staging) s.ctx.destroy(b);
  s.figures.blas_bytes = 0;
  for (const BlasFigures& f : s.figures.blas) s.figures.blas_bytes += f.compacted_bytes;
  s.figures.scratch_bytes = 0;
  s.build_tlas();
  s.figures.peak_bytes = s.figures.resident_bytes();
  s.figures.seconds = seconds_since(start);
  return std::nullopt;
}

std::vector<std::vector<uint8_t>> RtScene::serialize() {
  State& s = *state_;
  if (s.blas.empty()) throw Error("rtx: nothing to serialise; build the scene first");
  VkDevice d = s.ctx.device();
  VkQueryPool pool = VK_NULL_HANDLE;
  VkQueryPoolCreateInfo q{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
  q.queryType = VK_QUERY_TYPE_ACCELERATION_STRUCTURE_SERIALIZATION_SIZE_KHR;
  q.queryCount = uint32_t(s.blas.size());
  check(vkCreateQueryPool(d, &q, nullptr, &pool), "query pool (serialisation sizes)");
  std::vector<uint64_t> sizes(s.blas.size());
  std::vector<Buffer> targets;
  std::vector<std::vector<uint8_t>> blobs;
  try {
    s.ctx.submit([&](VkCommandBuffer cmd) {
      vkCmdResetQueryPool(cmd, pool, 0, q.queryCount);
      std::vector<VkAccelerationStructureKHR> handles;
      for (const As& b : s.blas) handles.push_back(b.handle);
      s.fn.cmd_write_properties(cmd, q.queryCount, handles.data(),
                                VK_QUERY_TYPE_ACCELERATION_STRUCTURE_SERIALIZATION_SIZE_KHR, pool,
                                0);
    });
    check(vkGetQueryPoolResults(d, pool, 0, q.queryCount, sizes.size() * 8, sizes.data(), 8,
                                VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT),
          "vkGetQueryPoolResults (serialisation sizes)");
    // The blobs are copied to the host: within what the Context's budget leaves, with the
    // host-visible targets they are copied from.
    uint64_t total = 0;
    for (uint64_t size : sizes) total += size;
    if (total > s.ctx.host_bytes_left() / 2)
      throw HostBudgetExceeded("serialising " + std::to_string(sizes.size()) + " BLAS takes " +
                               format_bytes(total) +
                               " of host memory twice (the buffers and the copies), more than "
                               "the memory budget of " +
                               format_bytes(s.ctx.host_budget()) + " leaves");
    std::vector<VkDeviceAddress> offsets;
    for (uint64_t size : sizes) {
      targets.push_back(s.ctx.create_buffer(
          size + 256,
          VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT | VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true));
      const VkDeviceAddress base = s.ctx.address(targets.back());
      offsets.push_back(align_up(base, 256) - base);
    }
    s.ctx.submit([&](VkCommandBuffer cmd) {
      for (size_t i = 0; i < s.blas.size(); ++i) {
        VkCopyAccelerationStructureToMemoryInfoKHR copy{
            VK_STRUCTURE_TYPE_COPY_ACCELERATION_STRUCTURE_TO_MEMORY_INFO_KHR};
        copy.src = s.blas[i].handle;
        copy.dst.deviceAddress = s.ctx.address(targets[i]) + offsets[i];
        copy.mode = VK_COPY_ACCELERATION_STRUCTURE_MODE_SERIALIZE_KHR;
        s.fn.cmd_serialize(cmd, &copy);
      }
      VkMemoryBarrier b{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
      b.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT | kAsWrite;
      b.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
      vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_ACCELERATION_STRUCTURE_BUILD_BIT_KHR,
                           VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &b, 0, nullptr, 0, nullptr);
    });
    for (size_t i = 0; i < targets.size(); ++i) {
      const auto* bytes = static_cast<const uint8_t*>(targets[i].mapped) + offsets[i];
      blobs.emplace_back(bytes, bytes + sizes[i]);
      s.figures.blas[i].serialized_bytes = sizes[i];
    }
  } catch (...) {
    for (Buffer& b : targets) s.ctx.destroy(b);
    vkDestroyQueryPool(d, pool, nullptr);
    throw;
  }
  for (Buffer& b : targets) s.ctx.destroy(b);
  vkDestroyQueryPool(d, pool, nullptr);
  return blobs;
}

bool RtScene::built() const {
  return state_->tlas.handle != VK_NULL_HANDLE;
}
const RtBuildFigures& RtScene::figures() const {
  return state_->figures;
}
RtGeometry RtScene::geometry() const {
  return state_->geometry;
}
VkAccelerationStructureKHR RtScene::tlas() const {
  return state_->tlas.handle;
}
const Buffer& RtScene::chunk_table() const {
  return state_->chunk_table;
}
std::array<float, 2> RtScene::attribute_range() const {
  return state_->attribute_range;
}
float RtScene::capsule_radius() const {
  return state_->radius;
}
bool RtScene::has_attribute() const {
  return state_->has_attribute;
}

}  // namespace linebake::vk
