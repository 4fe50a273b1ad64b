// Vulkan ray tracing (technique `rtx`) without ray tracing hardware: the capsule segments the
// AABB BLAS are built from, the capsule intersection shader's math (capsule.glsl, run as a
// compute shader on lavapipe) against the CPU capsule chain, the serialised-BLAS header checks,
// the cache's BLAS store, and the clean refusal on a device without ray tracing. On a device
// with ray tracing the last test renders and compares with the CPU reference.

#include <gtest/gtest.h>

// Vulkan structs are initialised as {sType}, the rest zero: the idiom, not a mistake.
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"

#include <cmath>
#include <cstring>
#include <iostream>
#include <random>

#include "accel/capsule_chain.hpp"
#include "accel/capsule_segments.hpp"
#include "accel/embree_scene.hpp"
#include "cache/rtx_store.hpp"
#include "metrics/image_metrics.hpp"
#include "render/ray_tracer.hpp"
#include "render/vulkan/buffer_set.hpp"
#include "render/vulkan/context.hpp"
#include "render/vulkan/rt_renderer.hpp"
#include "render/vulkan/rt_scene.hpp"
#include "render/vulkan/serialized_as.hpp"
#include "render/vulkan/shaders.hpp"
#include "synth/synth.hpp"
#include "test_util.hpp"
#include "tubes/tube_builder.hpp"

namespace linebake {
namespace {

// Two lines: a bent one of four points (a right angle, then a 45-degree turn) and a straight
// one of two points, with an attribute equal to the point index.
LineSet bent_lines() {
  LineSet lines;
  lines.append_point(0, 0, 0);
  lines.append_point(2, 0, 0);
  lines.append_point(2, 2, 0);
  lines.append_point(3, 3, 0.5f);
  lines.end_line();
  lines.append_point(-1, 4, 1);
  lines.append_point(4, 4, 1);
  lines.end_line();
  lines.attributes.push_back({"index", {0, 1, 2, 3, 4, 5}});
  return lines;
}

TEST(CapsuleSegments, WordsFlagsBoxesAndChunksFollowTheLines) {
  const LineSet lines = bent_lines();
  const CapsuleSegments one = build_capsule_segments(lines, 0.25f, "index");
  ASSERT_EQ(one.chunks.size(), 1u);
  const CapsuleChunk& c = one.chunks[0];
  ASSERT_EQ(c.segment_count(), 4u);
  // Segment words: first point << 2 | previous (1) / next (2) neighbour flags.
  EXPECT_EQ(c.segments[0], (0u << 2) | kCapsuleHasNext);
  EXPECT_EQ(c.segments[1], (1u << 2) | kCapsuleHasPrevious | kCapsuleHasNext);
  EXPECT_EQ(c.segments[2], (2u << 2) | kCapsuleHasPrevious);
  EXPECT_EQ(c.segments[3], 4u << 2);
  EXPECT_EQ(c.points[4 * 3 + 3], 3.0f);  // attribute of point 3
  EXPECT_EQ(one.attribute_range[0], 0.0f);
  EXPECT_EQ(one.attribute_range[1], 5.0f);
  // Each box holds both end spheres, and not much more.
  for (uint64_t s = 0; s < c.segment_count(); ++s) {
    const uint32_t first = c.segments[s] >> 2;
    for (int k = 0; k < 3; ++k) {
      const float a = c.points[4 * first + uint32_t(k)],
                  b = c.points[4 * (first + 1) + uint32_t(k)];
      EXPECT_LE(c.aabbs[6 * s + uint64_t(k)], std::min(a, b) - 0.25f);
      EXPECT_GE(c.aabbs[6 * s + 3 + uint64_t(k)], std::max(a, b) + 0.25f);
      EXPECT_GT(c.aabbs[6 * s + uint64_t(k)], std::min(a, b) - 0.26f);
    }
  }
  // At most 3 segments per chunk: the lines split at their boundary, points renumbered.
  const CapsuleSegments split = build_capsule_segments(lines, 0.25f, "", 3);
  // What the budget is checked against before building: what the chunks hold, split or not.
  EXPECT_EQ(capsule_segments_bytes(lines), one.bytes());
  EXPECT_EQ(capsule_segments_bytes(lines), split.bytes());
  ASSERT_EQ(split.chunks.size(), 2u);
  EXPECT_EQ(split.chunks[0].line_count, 1u);
  EXPECT_EQ(split.chunks[1].first_line, 1u);
  EXPECT_EQ(split.chunks[1].segments[0], 0u);
  EXPECT_EQ(split.chunks[1].points[0], -1.0f);
  EXPECT_EQ(split.segment_count(), 4u);
  EXPECT_THROW(build_capsule_segments(lines, 0, ""), Error);
  EXPECT_THROW(build_capsule_segments(lines, 0.1f, "missing"), Error);
}

// std430 mirrors of capsule_test.comp's Case and Crossings.
struct GpuCase {
  float before[4], p0[4], p1[4], after[4], origin[4], direction[4];
};
struct GpuCrossings {
  float t[4], u[4], normal[4][4];
  uint32_t count[4];
  float front[4];  // capsule_front_crossing: t, u, found
  float front_normal[4];
};

TEST(CapsuleShader, CrossingsMatchTheCpuCapsuleChain) {
  const LineSet lines = bent_lines();
  const float radius = 0.3f;
  const CapsuleSegments capsules = build_capsule_segments(lines, radius, "");
  const CapsuleChunk& chunk = capsules.chunks[0];
  // The same chain in Embree's layout for the CPU code: x y z r per point.
  std::vector<float> vertices;
  for (size_t p = 0; p + 4 <= chunk.points.size(); p += 4)
    vertices.insert(vertices.end(),
                    {chunk.points[p], chunk.points[p + 1], chunk.points[p + 2], radius});
  vertices.insert(vertices.end(), {0, 0, 0, 0});
  std::vector<uint32_t> indices;
  std::vector<uint8_t> flags;
  for (uint32_t word : chunk.segments) {
    indices.push_back(word >> 2);
    flags.push_back(uint8_t(((word & kCapsuleHasPrevious) ? RTC_CURVE_FLAG_NEIGHBOR_LEFT : 0) |
                            ((word & kCapsuleHasNext) ? RTC_CURVE_FLAG_NEIGHBOR_RIGHT : 0)));
  }
  const CapsuleChain chain{vertices.data(), indices.data(), flags.data()};
  // Rays from random points around the lines towards random points near their segments.
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> unit(0, 1), around(-4, 8);
  std::vector<GpuCase> cases;
  std::vector<uint32_t> case_segment;
  for (int i = 0; i < 4000; ++i) {
    const uint32_t s = uint32_t(i) % uint32_t(indices.size());
    const float* a = &vertices[4 * indices[s]];
    const float* b = a + 4;
    const float h = -0.2f + 1.4f * unit(rng);
    glm::vec3 target(a[0] + h * (b[0] - a[0]), a[1] + h * (b[1] - a[1]), a[2] + h * (b[2] - a[2]));
    target += glm::vec3(unit(rng) - 0.5f, unit(rng) - 0.5f, unit(rng) - 0.5f) * 0.7f;
    const glm::vec3 origin(around(rng), around(rng), around(rng));
    const glm::vec3 direction = glm::normalize(target - origin);
    GpuCase c{};
    const uint32_t first = indices[s];
    const uint32_t before = flags[s] & RTC_CURVE_FLAG_NEIGHBOR_LEFT ? first - 1 : first;
    const uint32_t after = flags[s] & RTC_CURVE_FLAG_NEIGHBOR_RIGHT ? first + 2 : first + 1;
    for (int k = 0; k < 3; ++k) {
      c.before[k] = vertices[4 * before + uint32_t(k)];
      c.p0[k] = a[k];
      c.p1[k] = b[k];
      c.after[k] = vertices[4 * after + uint32_t(k)];
      c.origin[k] = origin[k];
      c.direction[k] = direction[k];
    }
    c.p0[3] = radius;
    c.p1[3] = float((flags[s] & RTC_CURVE_FLAG_NEIGHBOR_LEFT ? 1 : 0) |
                    (flags[s] & RTC_CURVE_FLAG_NEIGHBOR_RIGHT ? 2 : 0));
    cases.push_back(c);
    case_segment.push_back(s);
  }
  // capsule_test.comp on the Vulkan device (lavapipe in CI).
  vk::Context ctx;
  vk::Buffer params = ctx.create_buffer(16, VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, true);
  vk::Buffer input =
      ctx.create_buffer(cases.size() * sizeof(GpuCase), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
  vk::Buffer output = ctx.create_buffer(cases.size() * sizeof(GpuCrossings),
                                        VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
  const uint32_t count[4] = {uint32_t(cases.size()), 0, 0, 0};
  std::memcpy(params.mapped, count, sizeof count);
  std::memcpy(input.mapped, cases.data(), cases.size() * sizeof(GpuCase));
  const vk::BufferSet set = vk::create_buffer_set(ctx.device(), 3, VK_SHADER_STAGE_COMPUTE_BIT);
  vk::write_buffer_set(ctx.device(), set.set, {&params, &input, &output});
  const VkPipeline pipeline =
      vk::create_compute_pipeline(ctx.device(), set.layout, "capsule_test.comp");
  ctx.submit([&](VkCommandBuffer cmd) {
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, set.layout, 0, 1, &set.set, 0,
                            nullptr);
    vkCmdDispatch(cmd, uint32_t(cases.size() + 63) / 64, 1, 1);
    VkMemoryBarrier barrier{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    barrier.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
    barrier.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0,
                         1, &barrier, 0, nullptr, 0, nullptr);
  });
  std::vector<GpuCrossings> gpu(cases.size());
  std::memcpy(gpu.data(), output.mapped, gpu.size() * sizeof(GpuCrossings));
  vkDestroyPipeline(ctx.device(), pipeline, nullptr);
  vkDestroyDescriptorPool(ctx.device(), set.pool, nullptr);
  vkDestroyPipelineLayout(ctx.device(), set.layout, nullptr);
  vkDestroyDescriptorSetLayout(ctx.device(), set.set_layout, nullptr);
  for (vk::Buffer* b : {&params, &input, &output}) ctx.destroy(*b);

  // Every crossing the CPU finds, the shader finds at the same place with the same normal; and
  // the nearest front crossing ahead of the origin (what tiles composites) is the CPU's first
  // crossing with t > 0 and a normal against the ray.
  size_t equal_counts = 0, crossings = 0, fronts = 0;
  for (size_t i = 0; i < cases.size(); ++i) {
    const GpuCase& c = cases[i];
    CapsuleHit cpu[4];
    const glm::dvec3 origin(c.origin[0], c.origin[1], c.origin[2]);
    const glm::dvec3 direction(c.direction[0], c.direction[1], c.direction[2]);
    const int n = intersect_capsule(chain, case_segment[i], origin, direction, cpu);
    crossings += size_t(n);
    // A ray through the seam where one primitive's surface hands over to a neighbour's, within
    // float precision: the owner can differ (7 of 4000 cases here).
    if (int(gpu[i].count[0]) != n) continue;
    ++equal_counts;
    int front = -1;
    for (int k = 0; k < n && front < 0; ++k)
      if (cpu[k].t > 0 && glm::dot(cpu[k].normal, direction) < 0) front = k;
    EXPECT_EQ(gpu[i].front[2], front >= 0 ? 1.0f : 0.0f) << "case " << i;
    if (front >= 0 && gpu[i].front[2] == 1.0f) {
      ++fronts;
      EXPECT_NEAR(gpu[i].front[0], cpu[front].t, 2e-4 * std::max(1.0, cpu[front].t))
          << "case " << i;
      EXPECT_NEAR(gpu[i].front[1], cpu[front].u, 1e-3) << "case " << i;
      const glm::dvec3 normal(gpu[i].front_normal[0], gpu[i].front_normal[1],
                              gpu[i].front_normal[2]);
      EXPECT_GT(glm::dot(normal, cpu[front].normal), 0.999) << "case " << i;
    }
    for (int k = 0; k < n; ++k) {
      EXPECT_NEAR(gpu[i].t[k], cpu[k].t, 2e-4 * std::max(1.0, cpu[k].t)) << "case " << i;
      EXPECT_NEAR(gpu[i].u[k], cpu[k].u, 1e-3) << "case " << i;
      const glm::dvec3 normal(gpu[i].normal[k][0], gpu[i].normal[k][1], gpu[i].normal[k][2]);
      EXPECT_GT(glm::dot(normal, cpu[k].normal), 0.999) << "case " << i;
    }
  }
  EXPECT_GT(crossings, cases.size());   // the rays do hit: about half of them twice
  EXPECT_GT(fronts, cases.size() / 4);  // and many enter ahead of the origin
  EXPECT_GE(double(equal_counts), 0.995 * double(cases.size()));
}

std::vector<uint8_t> blob(const std::array<uint8_t, 16>& driver, uint64_t size, uint64_t handles) {
  std::vector<uint8_t> b(size, 0xAB);
  std::copy(driver.begin(), driver.end(), b.begin());
  const uint64_t fields[3] = {size, 4096, handles};
  for (int f = 0; f < 3; ++f)
    for (int k = 0; k < 8; ++k) b[size_t(32 + 8 * f + k)] = uint8_t(fields[f] >> (8 * k));
  return b;
}

TEST(SerializedAs, HeaderIsParsedAndForeignOrDamagedBlobsAreTurnedDown) {
  std::array<uint8_t, 16> driver{}, other{};
  for (size_t i = 0; i < 16; ++i) driver[i] = uint8_t(i + 1), other[i] = uint8_t(200 - i);
  const auto good = blob(driver, 300, 0);
  const vk::SerializedAsHeader h = vk::parse_serialized_as(good);
  EXPECT_EQ(h.driver_uuid, driver);
  EXPECT_EQ(h.serialized_size, 300u);
  EXPECT_EQ(h.deserialized_size, 4096u);
  EXPECT_EQ(h.handle_count, 0u);
  EXPECT_EQ(vk::serialized_as_problem(good, driver), std::nullopt);
  const auto foreign = vk::serialized_as_problem(good, other);
  ASSERT_TRUE(foreign.has_value());
  EXPECT_NE(foreign->find(vk::to_hex(driver)), std::string::npos) << *foreign;
  // Shorter than the header, shorter than the header says, a TLAS.
  EXPECT_TRUE(vk::serialized_as_problem(std::vector<uint8_t>(40, 0), driver).has_value());
  auto truncated = good;
  truncated.resize(200);
  const auto short_blob = vk::serialized_as_problem(truncated, driver);
  ASSERT_TRUE(short_blob.has_value());
  EXPECT_NE(short_blob->find("300"), std::string::npos) << *short_blob;
  EXPECT_TRUE(vk::serialized_as_problem(blob(driver, 300, 2), driver).has_value());
  EXPECT_THROW(vk::parse_serialized_as(blob(driver, 300, uint64_t(1) << 50)), Error);
}

TEST(RtxStore, BlobsAndDescriptionRoundTripThroughTheCache) {
  test::TempDir dir;
  const std::string path = dir.file("rtx.lbc.h5");
  StoredRtx rtx;
  rtx.geometry = "capsules";
  rtx.compaction = false;
  rtx.source = "source-key";
  rtx.device = "Some GPU";
  rtx.driver = "driver";
  rtx.driver_uuid = std::string(32, 'f');
  rtx.blobs = {std::vector<uint8_t>(1000, 7), std::vector<uint8_t>(3, 9)};
  {
    CacheWriter w(path, Compression::Lz4);
    Provenance p;
    p.step = "rtx";
    p.key = "k";
    store_rtx(w, rtx, p);
    // A cache needs its line set for CacheReader to accept it.
    Provenance lines;
    lines.step = "lines";
    w.create_group("/lines");
    w.write_provenance("/lines", lines);
    w.commit();
  }
  const CacheReader cache(path);
  const StoredRtx back = load_rtx(cache);
  EXPECT_EQ(back.geometry, rtx.geometry);
  EXPECT_EQ(back.compaction, rtx.compaction);
  EXPECT_EQ(back.source, rtx.source);
  EXPECT_EQ(back.device, rtx.device);
  EXPECT_EQ(back.driver_uuid, rtx.driver_uuid);
  EXPECT_EQ(back.blobs, rtx.blobs);
  EXPECT_EQ(cache.provenance(kRtxGroup)->step, "rtx");
  // The description alone gives the blobs' sizes (what rtx checks against the budget before it
  // reads them) and no blobs; reading them then gives the same bytes.
  StoredRtx described = load_rtx_description(cache);
  EXPECT_TRUE(described.blobs.empty());
  EXPECT_EQ(described.blas, 2u);
  EXPECT_EQ(described.blob_bytes, 1003u);
  EXPECT_EQ(described.largest_blob_bytes, 1000u);
  EXPECT_EQ(described.source, rtx.source);
  load_rtx_blobs(cache, described);
  EXPECT_EQ(described.blobs, rtx.blobs);
}

bool device_has_ray_tracing() {
  for (const vk::DeviceInfo& d : vk::list_devices())
    if (d.ray_tracing) return true;
  return false;
}

TEST(Rtx, DeviceWithoutRayTracingIsRefusedInOneLine) {
  if (device_has_ray_tracing()) GTEST_SKIP() << "this machine has a ray tracing device";
  vk::ContextOptions o;
  o.ray_tracing = true;
  try {
    vk::Context ctx(o);
    FAIL() << "a context with ray tracing on a device without it";
  } catch (const vk::RayTracingUnsupported& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("not supported on this device"), std::string::npos) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  }
  // Without the request the same device serves the other techniques.
  EXPECT_NO_THROW(vk::Context{});
}

// Only where a device can ray trace (a GPU machine): rtx against the CPU reference, triangles
// and capsules, and serialised BLAS loading back to the same image.
TEST(Rtx, MatchesTheReferenceOnARayTracingDevice) {
  if (!device_has_ray_tracing()) GTEST_SKIP() << "no Vulkan device with ray tracing here";
  const LineSet lines = synth::generate(synth::parse_synth_source("synth:aneurysm?scale=0.02"));
  TubeOptions to;
  const TubeMesh mesh = build_tubes(lines, to);
  const TransferFunction tf = transfer_function_preset("semi");
  const EmbreeScene reference_scene = EmbreeScene::from_tubes(mesh, {});
  const Camera camera = frame_bounds(compute_bounds(mesh), 160.0 / 120.0, 30, 20);
  TraceOptions trace;
  trace.width = 160, trace.height = 120;
  const Frame reference = trace_frame(reference_scene, camera, tf, trace);
  vk::ContextOptions co;
  co.ray_tracing = true;
  co.validation = true;
  vk::Context ctx(co);
  vk::RtScene scene(ctx, mesh);
  scene.build(true);
  EXPECT_LE(scene.figures().blas_bytes, scene.figures().blas[0].build_bytes);
  vk::RtRenderer renderer(ctx);
  vk::RtOptions o;
  o.width = trace.width, o.height = trace.height;
  const vk::RtFrame frame = renderer.render(scene, camera, tf, o);
  EXPECT_GE(psnr(reference.image, frame.image), 45.0);
  EXPECT_EQ(frame.stats.truncated_pixels, 0u);
  // Every front hit the reference composites, found by the any-hit windows (float against the
  // reference's double distances can move a grazing hit in or out: a few per mille).
  const double front = double(reference.stats.counters.hits);
  EXPECT_NEAR(double(frame.stats.hits), front, 0.005 * front);
  EXPECT_NEAR(double(frame.stats.max_depth_complexity),
              double(reference.stats.max_depth_complexity), 1.0);
  // Stepping from just past each hit is the older way; report what it loses beside it.
  vk::RtOptions stepping = o;
  stepping.hits = vk::RtHits::Stepping;
  const vk::RtFrame stepped = renderer.render(scene, camera, tf, stepping);
  std::cout << "rtx filter: " << psnr(reference.image, frame.image) << " dB, " << frame.stats.hits
            << " front hits, " << frame.stats.gpu_ms
            << " ms; stepping: " << psnr(reference.image, stepped.image) << " dB, "
            << stepped.stats.hits << " front hits, " << stepped.stats.gpu_ms
            << " ms; reference: " << reference.stats.counters.hits << " front hits\n";
  // Serialised and loaded back: the same image.
  const auto blobs = scene.serialize();
  vk::RtScene loaded(ctx, mesh);
  EXPECT_EQ(loaded.load(blobs), std::nullopt);
  const vk::RtFrame again = renderer.render(loaded, camera, tf, o);
  EXPECT_EQ(again.image.pixels, frame.image.pixels);
  EXPECT_EQ(ctx.validation_errors(), 0u) << ctx.last_validation_error();
}

}  // namespace
}  // namespace linebake
