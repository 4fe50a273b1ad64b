// The technique registry (lib/techniques): what it lists, what each technique needs, why one
// cannot run here; and the device-local uploads the Vulkan techniques read their meshes from.

#include <gtest/gtest.h>
#include <sys/mman.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <iostream>

#include "cache/line_store.hpp"
#include "cache/tube_store.hpp"
#include "core/error.hpp"
#include "core/measure.hpp"
#include "core/memory_budget.hpp"
#include "flight_plan.hpp"
#include "pipeline/bake.hpp"
#include "render/vulkan/context.hpp"
#include "render/vulkan/raster_renderer.hpp"
#include "render/vulkan/tile_renderer.hpp"
#include "render/vulkan/voxel_caster.hpp"
#include "synth/synth.hpp"
#include "techniques/families.hpp"
#include "techniques/framing.hpp"
#include "techniques/technique.hpp"
#include "test_util.hpp"
#include "tubes/tube_builder.hpp"
#include "voxels/occupancy.hpp"
#include "voxels/voxelizer.hpp"

namespace linebake {
namespace {

using test::quiet_bake;
using test::TempDir;

TEST(Techniques, TheRegistryListsEveryTechniqueWithItsAssets) {
  const std::vector<std::string> expected{"reference", "embree", "opaque", "dp",  "ll",  "mlab",
                                          "mlabdb",    "mboit",  "wboit",  "vrc", "rtx", "tiles"};
  EXPECT_EQ(technique_names(), expected);
  for (const Technique& t : techniques()) {
    const std::string asset = t.info.name == "embree" || t.info.name == "tiles" ? "lines"
                              : t.info.name == "vrc"                            ? "voxels"
                                                                                : "tubes";
    EXPECT_EQ(t.info.assets, std::vector<std::string>{asset}) << t.info.name;
    const bool cpu = t.info.name == "reference" || t.info.name == "embree" || t.info.name == "vrc";
    EXPECT_EQ(t.info.vulkan, !cpu) << t.info.name;
    EXPECT_EQ(t.info.ray_tracing, t.info.name == "rtx") << t.info.name;
    EXPECT_NE(t.prepare, nullptr) << t.info.name;
    EXPECT_FALSE(t.info.summary.empty()) << t.info.name;
  }
  // The exact ones composite every hit in order.
  for (const char* exact : {"reference", "embree", "dp", "ll", "rtx", "tiles"})
    EXPECT_TRUE(find_technique(exact).info.exact) << exact;
  for (const char* approximate : {"opaque", "mlab", "mlabdb", "mboit", "wboit", "vrc"})
    EXPECT_FALSE(find_technique(approximate).info.exact) << approximate;
  // Frame memory before any work: 36 B/pixel for the image and counts, plus the technique's
  // own (ll: 20 nodes per pixel to start, 24 or 12 bytes each).
  TechniqueOptions o;
  o.width = 100, o.height = 50;
  EXPECT_EQ(estimate_frame_bytes(find_technique("ll"), o), 5000u * (36 + 20 * 24 + 4));
  o.node_bytes = 12;
  EXPECT_EQ(estimate_frame_bytes(find_technique("ll"), o), 5000u * (36 + 20 * 12 + 4));
  o.capacity = 1000;
  EXPECT_EQ(estimate_frame_bytes(find_technique("ll"), o), 5000u * (36 + 4) + 1000u * 12);
  EXPECT_EQ(estimate_frame_bytes(find_technique("mlab"), o), 5000u * (36 + 8 * 20 + 12));
  EXPECT_EQ(estimate_frame_bytes(find_technique("reference"), o), 5000u * (36 + 16));
  try {
    find_technique("embre");
    ADD_FAILURE() << "an unknown name was found";
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("'embre'"), std::string::npos) << message;
    EXPECT_NE(message.find("embree"), std::string::npos) << message;
  }
}

TEST(Techniques, SayWhyTheyCannotRunHere) {
  TempDir dir;
  BakeOptions o;
  o.input = "synth:aneurysm?scale=0.002";
  o.cache = dir.file("tubes-only.lbc.h5");
  o.assets = {"tubes"};
  o.progress = false;
  bake(o);
  const CacheReader cache(o.cache);
  TechniqueOptions options;
  EXPECT_EQ(technique_unavailable(find_technique("ll"), options, &cache), std::nullopt);
  EXPECT_EQ(technique_unavailable(find_technique("embree"), options, &cache), std::nullopt);
  const auto vrc = technique_unavailable(find_technique("vrc"), options, &cache);
  ASSERT_TRUE(vrc.has_value());
  EXPECT_EQ(*vrc, "the cache has no voxels (linebake bake CACHE --assets voxels)");
  options.device = "no such device";
  const auto ll = technique_unavailable(find_technique("ll"), options, nullptr);
  ASSERT_TRUE(ll.has_value());
  EXPECT_EQ(*ll, "no Vulkan device named 'no such device'");
  // CPU techniques need no device at all.
  EXPECT_EQ(technique_unavailable(find_technique("reference"), options, nullptr), std::nullopt);
  options.device.clear();
  bool ray_tracing = false;
  for (const vk::DeviceInfo& d : vk::list_devices()) ray_tracing |= d.ray_tracing;
  const auto rtx = technique_unavailable(find_technique("rtx"), options, &cache);
  if (ray_tracing)
    EXPECT_EQ(rtx, std::nullopt);
  else
    EXPECT_NE(rtx.value_or("").find("ray tracing is not supported on this device"),
              std::string::npos)
        << rtx.value_or("");
  // A prepared technique renders what the command line renders: a frame of the asked size.
  const Technique& ll_technique = find_technique("ll");
  auto prepared = ll_technique.prepare(ll_technique.info, cache, o.cache, options);
  const Camera camera = frame_bounds(flight_bounds(cache), 40.0 / 30.0, 30, 20);
  const TechniqueFrame frame = prepared->render(camera, transfer_function_preset("semi"), 40, 30);
  EXPECT_EQ(frame.image.width, 40);
  EXPECT_EQ(frame.image.height, 30);
  EXPECT_TRUE(frame.gpu_ms.count("gather")) << frame.stats.dump();
  EXPECT_GT(frame.total_gpu_ms(), 0);
}

// Device-local buffers filled through a staging buffer in small pieces (as on a discrete GPU)
// give the same images as lavapipe's in-place writes; so do the voxel grid's arrays split across
// storage buffers. With staging forced the results (images, per-pixel counts, ll's node counter)
// are device-local too and reach the host through Context::read_back's copy.
TEST(Techniques, StagingInPiecesGivesIdenticalImages) {
  const LineSet lines = synth::generate(synth::parse_synth_source("synth:aneurysm?scale=0.002"));
  TubeOptions to;
  to.normals = NormalEncoding::Oct16;  // the decoding path of the upload, piece by piece
  const TubeMesh mesh = build_tubes(lines, to);
  VoxelOptions vo;
  vo.grid = 32;
  const VoxelGrid grid = voxelize(lines, vo);
  const OccupancyPyramid occupancy = build_occupancy(grid);
  const TransferFunction tf = transfer_function_preset("semi");
  const Camera camera = frame_bounds(compute_bounds(mesh), 64.0 / 48.0, 30, 20);
  vk::ContextOptions staged_options;
  staged_options.force_staging = true;
  staged_options.staging_piece_bytes = 1000;  // many pieces, none a multiple of a vertex
  vk::Context in_place, staged(staged_options);
  EXPECT_FALSE(staged.uploads_in_place());
  std::cout << "lavapipe uploads in place: " << in_place.uploads_in_place() << "\n";
  vk::RasterOptions ro;
  ro.width = 64, ro.height = 48;
  ro.capacity = 8;  // ll grows its node pool: the counter is read back mid-frame
  for (auto technique : {vk::RasterTechnique::LinkedLists, vk::RasterTechnique::Opaque,
                         vk::RasterTechnique::DepthPeeling}) {
    ro.technique = technique;
    vk::RasterRenderer a(in_place, mesh), b(staged, mesh);
    const vk::RasterFrame fa = a.render(camera, tf, ro), fb = b.render(camera, tf, ro);
    EXPECT_EQ(fa.image.pixels, fb.image.pixels) << vk::to_string(technique);
    EXPECT_EQ(fa.alpha, fb.alpha) << vk::to_string(technique);
    EXPECT_EQ(fa.depth_complexity, fb.depth_complexity) << vk::to_string(technique);
    EXPECT_EQ(fa.stats.fragments, fb.stats.fragments) << vk::to_string(technique);
    EXPECT_EQ(fa.stats.regrows, fb.stats.regrows) << vk::to_string(technique);
    const auto [lo, hi] = std::minmax_element(fa.image.pixels.begin(), fa.image.pixels.end());
    EXPECT_GT(*hi - *lo, 0.1f) << "the tubes are in the picture";
    if (technique == vk::RasterTechnique::LinkedLists) {
      EXPECT_GT(fb.stats.regrows, 0) << "the pool grew from the counter read back";
      EXPECT_GT(fb.stats.fragments, ro.capacity);
    }
    const vk::RasterFrame ca = a.count_fragments(camera, tf, 64, 48),
                          cb = b.count_fragments(camera, tf, 64, 48);
    EXPECT_EQ(ca.depth_complexity, cb.depth_complexity);
    EXPECT_GT(cb.stats.max_depth_complexity, 1u);
  }
  VrcOptions vrc;
  vrc.width = 64, vrc.height = 48;
  vk::VoxelCaster a(in_place, grid, occupancy), b(staged, grid, occupancy);
  const VrcFrame whole = a.render(camera, tf, vrc);
  EXPECT_EQ(whole.image.pixels, b.render(camera, tf, vrc).image.pixels);
  EXPECT_EQ(a.grid_buffers(), 2u);
  // The grid's offsets and chords split across storage buffers of a quarter of the chords: the
  // same image.
  const uint64_t quarter = grid.chords.bytes() / 4;
  vk::VoxelCaster split(in_place, grid, occupancy, quarter);
  EXPECT_GE(split.grid_buffers(), 4u + 1u);
  EXPECT_EQ(split.render(camera, tf, vrc).image.pixels, whole.image.pixels);
  // A page refused by the memory budget: the pages uploaded before it are freed with it.
  if (in_place.memory_is_host()) {
    const uint64_t held = in_place.host_bytes();
    in_place.set_host_budget(trimmed_rss_bytes() + grid.offsets.bytes() + quarter * 2);
    EXPECT_THROW(vk::VoxelCaster(in_place, grid, occupancy, quarter), vk::HostBudgetExceeded);
    EXPECT_EQ(in_place.host_bytes(), held);
    in_place.set_host_budget(0);
  }
  EXPECT_GT(whole.stats.hits, 100u);
  EXPECT_EQ(in_place.validation_errors() + staged.validation_errors(), 0u);
}

// embree and reference build their scene within what --memory-budget leaves once their data is
// loaded: a budget that holds the tube mesh, the frame and 12 MiB more (some of it taken by the
// load itself), but not the BVH (a peak of about 35 MiB here), is refused by Embree's memory
// monitor with the technique's name and the budget's figures; 256 MiB more builds it.
TEST(Techniques, EmbreeScenesAreBuiltWithinTheMemoryBudget) {
  TempDir dir;
  const BakeOptions o = quiet_bake(dir, "synth:aneurysm?scale=0.02", "aneurysm.lbc.h5");
  bake(o);
  const CacheReader cache(o.cache);
  const uint64_t tubes = cache.provenance("/assets/tubes")->memory_bytes;
  const Technique& reference = find_technique("reference");
  TechniqueOptions options;
  options.width = 32, options.height = 24;
  const uint64_t frame = estimate_frame_bytes(reference, options);
  options.memory_budget = trimmed_rss_bytes() + tubes + frame + (12u << 20);
  try {
    reference.prepare(reference.info, cache, o.cache, options);
    ADD_FAILURE() << "a BVH past the budget was built";
  } catch (const BudgetExceeded& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind("reference: Embree's BVH over ", 0), 0u) << what;
    EXPECT_NE(what.find("triangles needs more than the "), std::string::npos) << what;
    EXPECT_NE(what.find("); raise --memory-budget (" + format_bytes(options.memory_budget) +
                        "; the process held "),
              std::string::npos)
        << what;
  }
  options.memory_budget += 256u << 20;
  const auto prepared = reference.prepare(reference.info, cache, o.cache, options);
  EXPECT_GT(prepared->stats()["bvh"]["bvh_peak_bytes"].get<uint64_t>(), 12u << 20);
  // Unlimited: no figure checked at all, whatever the budget's number says.
  options.memory_budget = 1;
  options.memory_unlimited = true;
  EXPECT_NO_THROW(reference.prepare(reference.info, cache, o.cache, options));
}

// bench render keeps each row's frame 0 until the reference renders: those bytes count with a
// later row's estimate, and the refusal names both figures.
TEST(Techniques, FramesKeptForQualityCountAgainstTheBudget) {
  constexpr uint64_t MiB = 1 << 20;
  EXPECT_NO_THROW(cli::check_frame_memory("ll", "64x64", 60 * MiB, "100M", 40 * MiB));
  try {
    cli::check_frame_memory("ll", "64x64", 60 * MiB, "100M", 41 * MiB);
    ADD_FAILURE() << "101 MiB within 100";
  } catch (const BudgetExceeded& e) {
    EXPECT_EQ(std::string(e.what()),
              "a 64x64 ll frame needs about 60.00 MiB, and the earlier rows' frames 0, kept for "
              "the quality figures, hold 41.00 MiB: more than the memory budget of 100.00 MiB; "
              "lower --size or --capacity, or raise --memory-budget");
  }
  EXPECT_NO_THROW(cli::check_frame_memory("ll", "64x64", 60 * MiB, "unlimited", 100 * MiB));
}

// Memory freed into the middle of the C library's heap stays resident (below a live block, the
// heap cannot shrink), as lavapipe's freed device memory can. The budget's resident counts give
// it back first (trimmed_rss_bytes): a Vulkan allocation and a cache's data then fit where the
// resident count alone refused them.
TEST(Techniques, FreedHeapMemoryIsNotCountedAsHeld) {
  constexpr uint64_t MiB = 1 << 20;
  vk::Context ctx(vk::ContextOptions{});
  TechniqueOptions o;
  const uint64_t base = trimmed_rss_bytes();
  o.memory_budget = base + 40 * MiB;
  ctx.set_host_budget(o.memory_budget);
  // A hole of 64 MiB in the heap: blocks, a block above them, the blocks freed.
  std::vector<void*> blocks(1024);
  for (void*& b : blocks) std::memset(b = std::malloc(64 << 10), 1, 64 << 10);
  void* fence = std::malloc(96 << 10);  // carved from the top of the heap, above them
  ASSERT_NE(fence, nullptr);
  std::memset(fence, 1, 96 << 10);
  for (void* b : blocks) std::free(b);
  const auto above = [&] {
    for (void* b : blocks)
      if (reinterpret_cast<uintptr_t>(b) > reinterpret_cast<uintptr_t>(fence)) return true;
    return false;
  };
  if (above() || current_rss_bytes() < base + 48 * MiB) {
    std::free(fence);
    GTEST_SKIP() << "this C library's heap gave the blocks back on free or placed them above";
  }
  // 16 MiB fit the budget only once the hole is given back.
  vk::Buffer fits = ctx.create_buffer(16 * MiB, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);
  ctx.destroy(fits);
  for (void*& b : blocks) std::memset(b = std::malloc(64 << 10), 1, 64 << 10);
  for (void* b : blocks) std::free(b);
  ASSERT_GE(current_rss_bytes(), base + 48 * MiB);
  EXPECT_FALSE(data_does_not_fit(o, 16 * MiB, "lines"));
  EXPECT_LE(current_rss_bytes(), base + 24 * MiB) << "given back";
  std::free(fence);
}

// What rtx checks its cached BLAS with before reading them (and check_data_fits a cache's
// arrays): the bytes against what the budget leaves the process now.
TEST(Techniques, DataIsCheckedAgainstWhatTheBudgetLeaves) {
  constexpr uint64_t MiB = 1 << 20;
  TechniqueOptions o;
  o.memory_budget = trimmed_rss_bytes() + 64 * MiB;
  EXPECT_FALSE(data_does_not_fit(o, 16 * MiB, "cached BLAS"));
  const auto why = data_does_not_fit(o, 128 * MiB, "cached BLAS");
  ASSERT_TRUE(why);
  EXPECT_EQ(why->rfind("the cached BLAS take 128.00 MiB in memory, more than the memory budget "
                       "leaves (",
                       0),
            0u)
      << *why;
  EXPECT_NE(
      why->find(" of " + format_bytes(o.memory_budget) + ", less what the process holds already)"),
      std::string::npos)
      << *why;
  o.memory_unlimited = true;
  EXPECT_FALSE(data_does_not_fit(o, uint64_t(1) << 50, "cached BLAS"));
}

// Where the device's memory is the machine's (lavapipe here), the Context's allocations are held
// within the budget two ways: by its own count against what the budget left when it was set
// (memory allocated is resident only once written), and by the process's resident memory.
TEST(Techniques, VulkanAllocationsOfHostMemoryAreHeldWithinTheBudget) {
  vk::Context ctx;
  if (!ctx.memory_is_host()) GTEST_SKIP() << ctx.info().name << " has memory of its own";
  constexpr uint64_t MiB = uint64_t{1} << 20;
  const uint64_t before = ctx.host_bytes();
  vk::Buffer one = ctx.create_buffer(MiB, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);
  EXPECT_GE(one.host_bytes, MiB);
  EXPECT_EQ(ctx.host_bytes(), before + one.host_bytes);
  ctx.destroy(one);
  EXPECT_EQ(ctx.host_bytes(), before);
  EXPECT_EQ(ctx.host_bytes_left(), vk::Context::kNoHostLimit);

  // 8 MiB left: 6 MiB, never written, is taken; 6 MiB more passes the count though not the
  // resident memory, and is refused with the figures.
  const uint64_t total = trimmed_rss_bytes() + 8 * MiB;
  ctx.set_host_budget(total);
  EXPECT_LE(ctx.host_bytes_left(), 8 * MiB);
  EXPECT_GT(ctx.host_bytes_left(), 7 * MiB);
  vk::Buffer six = ctx.create_buffer(6 * MiB, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);
  try {
    ctx.create_buffer(6 * MiB, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);
    ADD_FAILURE() << "12 MiB were allocated within 8";
  } catch (const BudgetExceeded& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind("Vulkan: allocating 6.00 MiB on " + ctx.info().name +
                             ", whose memory is this machine's, would pass the memory budget of " +
                             format_bytes(total) + " (the device's allocations hold ",
                         0),
              0u)
        << what;
  }
  EXPECT_EQ(ctx.host_bytes(), before + six.host_bytes);
  ctx.destroy(six);

  // With 4 MiB of the 8 kept for the frame's outputs, 6 MiB is refused, and the figures say
  // where the rest went (they had named only the allocations and the resident memory).
  ctx.set_host_budget(trimmed_rss_bytes() + 8 * MiB, 4 * MiB);
  try {
    ctx.create_buffer(6 * MiB, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);
    ADD_FAILURE() << "6 MiB were allocated within 8 less 4 kept";
  } catch (const BudgetExceeded& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(", and 4.00 MiB is kept for the frame's outputs)"), std::string::npos)
        << what;
  }

  // The host's own memory counts too: 6 MiB written by the host leave about 2 MiB, so 4 MiB more
  // is refused though the count alone would allow it.
  // (Pages of their own: malloc may hand back pages that are resident already.)
  ctx.set_host_budget(trimmed_rss_bytes() + 8 * MiB);
  void* host = mmap(nullptr, 6 * MiB, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  ASSERT_NE(host, MAP_FAILED);
  std::memset(host, 1, 6 * MiB);
  EXPECT_THROW(ctx.create_buffer(4 * MiB, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false),
               BudgetExceeded);
  vk::Buffer small = ctx.create_buffer(MiB / 2, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);
  ctx.destroy(small);
  munmap(host, 6 * MiB);
  // A reserve grown by 6 MiB (the viewer's window grown) takes 6 MiB from what allocations may
  // hold, by the count's limit as well as by the resident memory; grown past all the room, the
  // limit is what they hold; shrunk back, it is what it was. The budget's number stays.
  const uint64_t serial = ctx.set_host_budget(trimmed_rss_bytes() + 16 * MiB, MiB);
  const vk::Context::HostBudget set = ctx.host_budget_state();
  ASSERT_GT(set.limit, ctx.host_bytes() + 12 * MiB);
  ctx.set_host_reserve(7 * MiB);
  EXPECT_EQ(ctx.host_budget_state().limit, set.limit - 6 * MiB);
  const uint64_t left = ctx.host_bytes_left();
  EXPECT_LE(left, set.limit - 6 * MiB - ctx.host_bytes());
  EXPECT_THROW(ctx.create_buffer(left + MiB, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false),
               BudgetExceeded);
  ctx.set_host_reserve(64 * MiB);
  EXPECT_EQ(ctx.host_budget_state().limit, ctx.host_bytes());
  ctx.set_host_reserve(MiB);
  EXPECT_EQ(ctx.host_budget_state().limit, set.limit);
  EXPECT_EQ(ctx.host_budget_state().serial, serial);
  EXPECT_EQ(ctx.host_budget_state().reserved, MiB);
  vk::Buffer back = ctx.create_buffer(left + MiB, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);
  ctx.destroy(back);
  // What the reserve holds already (the viewer's copy of a frame for its window) is counted but
  // not refused, and taken from the reserve: 4 MiB of the 8 reserved leave other allocations
  // what they had (unwritten, they are not resident: only the count moves), and 12 MiB take 4
  // MiB past the reserve from them. Freed, the reserve is whole again; past the scope, refusals
  // again.
  ctx.set_host_budget(trimmed_rss_bytes() + 40 * MiB, 8 * MiB);
  const uint64_t room = ctx.host_bytes_left();
  ASSERT_GT(room, 24 * MiB);
  {
    const vk::Context::ReservedAllocations reserved(ctx);
    vk::Buffer within = ctx.create_buffer(4 * MiB, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);
    EXPECT_EQ(ctx.host_bytes(), before + within.host_bytes);
    EXPECT_NEAR(double(ctx.host_bytes_left()), double(room), double(MiB / 2));
    ctx.destroy(within);
    vk::Buffer past = ctx.create_buffer(12 * MiB, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);
    EXPECT_NEAR(double(ctx.host_bytes_left()), double(room - 4 * MiB), double(MiB / 2));
    ctx.destroy(past);
    vk::Buffer over = ctx.create_buffer(64 * MiB, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);
    EXPECT_EQ(ctx.host_bytes(), before + over.host_bytes);
    ctx.destroy(over);
  }
  EXPECT_NEAR(double(ctx.host_bytes_left()), double(room), double(MiB / 2));
  vk::Buffer outside = ctx.create_buffer(4 * MiB, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);
  EXPECT_NEAR(double(ctx.host_bytes_left()), double(room - 4 * MiB), double(MiB / 2));
  ctx.destroy(outside);
  EXPECT_THROW(ctx.create_buffer(64 * MiB, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false),
               BudgetExceeded);
  // No budget: nothing refused.
  ctx.set_host_budget(0);
  vk::Buffer big = ctx.create_buffer(64 * MiB, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);
  ctx.destroy(big);
  EXPECT_EQ(ctx.host_bytes(), before);
}

// The synthetic aneurysm at `scale`, baked with tube chunks of at most `chunk_bytes`.
BakeOptions chunked_aneurysm(const TempDir& dir, const std::string& scale, uint64_t chunk_bytes) {
  BakeOptions o = quiet_bake(dir, "synth:aneurysm?scale=" + scale, "aneurysm.lbc.h5");
  o.tubes.max_chunk_bytes = chunk_bytes;
  bake(o);
  return o;
}

// The raster techniques upload the tube mesh a chunk at a time (the host never holds all of
// it) with the same image and bounds as the whole mesh's, and on lavapipe their device copy is
// held within the budget: one budget that leaves three quarters of the mesh is refused with the
// figures, one that leaves three times it renders the same bytes.
TEST(Techniques, RasterScenesAreUploadedAChunkAtATimeWithinTheBudget) {
  TempDir dir;
  const BakeOptions o = chunked_aneurysm(dir, "0.05", 2u << 20);
  const CacheReader cache(o.cache);
  const TubeMesh whole = load_tubes(cache);
  ASSERT_GE(whole.chunks.size(), 4u);
  const Bounds bounds = compute_bounds(whole);
  const Bounds streamed = load_tube_bounds(cache);
  EXPECT_EQ(streamed.min, bounds.min);
  EXPECT_EQ(streamed.max, bounds.max);
  // Read in pieces of 1,000 vertices, the same bounds; each chunk's bytes from the shapes are
  // what reading it holds.
  const Bounds pieces = load_tube_bounds(cache, 1000);
  EXPECT_EQ(pieces.min, bounds.min);
  EXPECT_EQ(pieces.max, bounds.max);
  const TubeMesh description = load_tube_description(cache);
  for (size_t c = 0; c < whole.chunks.size(); ++c)
    EXPECT_EQ(tube_chunk_bytes(cache, description, c), whole.chunks[c].bytes()) << c;
  const uint64_t tubes = cache.provenance("/assets/tubes")->memory_bytes;
  EXPECT_EQ(tubes, whole.bytes());

  vk::Context ctx;
  const Technique& ll = find_technique("ll");
  TechniqueOptions options;
  options.context = &ctx;
  options.width = 48, options.height = 32;
  options.memory_unlimited = true;
  const TransferFunction tf = transfer_function_preset("semi");
  const Camera camera = frame_bounds(bounds, 1.5, 30, 20, 0.05);
  Image unlimited;
  {
    const auto prepared = ll.prepare(ll.info, cache, o.cache, options);
    unlimited = prepared->render(camera, tf, options.width, options.height).image;
    // The mesh uploaded whole gives the same image.
    vk::RasterRenderer renderer(ctx, whole);
    vk::RasterOptions raster;
    raster.technique = vk::RasterTechnique::LinkedLists;
    raster.width = options.width, raster.height = options.height;
    EXPECT_EQ(renderer.render(camera, tf, raster).image.pixels, unlimited.pixels);
  }
  const uint64_t idle = ctx.host_bytes();
  if (!ctx.memory_is_host()) GTEST_SKIP() << ctx.info().name << " has memory of its own";
  options.memory_unlimited = false;
  // lavapipe's first draw compiles with LLVM beside the allocations: the budget keeps room for it.
  const uint64_t compile = ctx.first_draw_compile_bytes();
  options.memory_budget = trimmed_rss_bytes() + compile + tubes * 3 / 4;
  try {
    ll.prepare(ll.info, cache, o.cache, options);
    ADD_FAILURE() << "a device copy past the budget was made";
  } catch (const BudgetExceeded& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind("ll: Vulkan: allocating ", 0), 0u) << what;
    EXPECT_NE(what.find("would pass the memory budget of " + format_bytes(options.memory_budget)),
              std::string::npos)
        << what;
    EXPECT_NE(what.find("; raise --memory-budget"), std::string::npos) << what;
  }
  // What a refusal allocated is given back, and the budget lifted with the technique.
  EXPECT_EQ(ctx.host_bytes(), idle);
  EXPECT_EQ(ctx.host_budget(), 0u);
  options.memory_budget = trimmed_rss_bytes() + compile + tubes * 3;
  auto prepared = ll.prepare(ll.info, cache, o.cache, options);
  EXPECT_GT(ctx.host_budget(), 0u);
  EXPECT_GE(ctx.host_bytes(), tubes);
  EXPECT_EQ(ctx.host_budget_state().compile, compile);
  EXPECT_EQ(prepared->render(camera, tf, options.width, options.height).image.pixels,
            unlimited.pixels);
  EXPECT_EQ(ctx.host_budget_state().compile, 0u);  // drawn once: the room for it is given back
  // The viewer prepares the next technique before the last goes. One refused puts back the
  // budget of the one kept; one prepared leaves its own in place when the last goes, and puts
  // back the one it found (the last one's, stale but harmless) when it goes itself.
  const vk::Context::HostBudget kept = ctx.host_budget_state();
  TechniqueOptions refused = options;
  refused.memory_budget = 1;
  EXPECT_THROW(ll.prepare(ll.info, cache, o.cache, refused), BudgetExceeded);
  EXPECT_EQ(ctx.host_budget_state().serial, kept.serial);
  EXPECT_EQ(ctx.host_budget_state().limit, kept.limit);
  EXPECT_EQ(ctx.host_budget(), kept.total);
  options.memory_budget = trimmed_rss_bytes() + compile + tubes * 4;
  auto next = ll.prepare(ll.info, cache, o.cache, options);
  EXPECT_EQ(ctx.host_budget(), options.memory_budget);
  prepared.reset();
  EXPECT_EQ(ctx.host_budget(), options.memory_budget);
  next.reset();
  EXPECT_EQ(ctx.host_budget_state().serial, kept.serial);
  EXPECT_EQ(ctx.host_budget(), kept.total);
}

// tiles over the tube mesh's triangles also takes the mesh a chunk at a time into its arrays,
// sized by the datasets' shapes: the same image as from the whole mesh.
TEST(Techniques, TilesTakesTheTubeMeshAChunkAtATime) {
  TempDir dir;
  const BakeOptions o = chunked_aneurysm(dir, "0.02", 1u << 20);
  const CacheReader cache(o.cache);
  const TubeMesh whole = load_tubes(cache);
  ASSERT_GE(whole.chunks.size(), 3u);
  const TubeCounts counts = load_tube_counts(cache);
  EXPECT_EQ(counts.vertices, whole.vertex_count());
  EXPECT_EQ(counts.triangles, whole.triangle_count());
  vk::Context ctx;
  const Technique& tiles = find_technique("tiles");
  TechniqueOptions options;
  options.context = &ctx;
  options.tiles_geometry = "triangles";
  options.width = 48, options.height = 32;
  const auto prepared = tiles.prepare(tiles.info, cache, o.cache, options);
  const Bounds bounds = compute_bounds(whole);
  const TransferFunction tf = transfer_function_preset("semi");
  const Camera camera = frame_bounds(bounds, 1.5, 30, 20);
  const TechniqueFrame frame = prepared->render(camera, tf, options.width, options.height);
  vk::TileRenderer renderer(ctx, whole);
  vk::TileOptions tile_options;
  tile_options.width = options.width, tile_options.height = options.height;
  const vk::TileFrame expected = renderer.render(camera, tf, tile_options);
  EXPECT_GT(expected.stats.hits, 100u);
  EXPECT_EQ(frame.image.pixels, expected.image.pixels);
}

// Every technique's flight frames one box over a cache: the lines' bounds (kept in their
// provenance) grown by the tubes' radius, which holds the tube mesh; without tubes, by the radius a
// bake would give them. (Each technique had framed its own geometry: embree's and tiles' cameras
// sat farther out than the reference's, and their PSNR against it counted the difference.)
TEST(Techniques, EveryFlightFramesTheLinesGrownByTheTubesRadius) {
  TempDir dir;
  BakeOptions o = quiet_bake(dir, "synth:convection?scale=0.02", "convection.lbc.h5");
  o.assets = {"voxels"};
  bake(o);
  {
    const CacheReader cache(o.cache);
    ASSERT_FALSE(cache.exists("/assets/tubes"));
    const Bounds lines = compute_bounds(load_lines(cache));
    const float radius = 0.001f * lines.diagonal();
    const Bounds framed = flight_bounds(cache);
    for (size_t k = 0; k < 3; ++k) {
      EXPECT_EQ(framed.min[k], lines.min[k] - radius) << k;
      EXPECT_EQ(framed.max[k], lines.max[k] + radius) << k;
    }
  }
  // Without tubes, Embree's curves' radius (they are built with the tubes' options).
  o.assets = {"voxels", "embree"};
  o.tubes.radius = 0.02f;
  bake(o);
  {
    const CacheReader cache(o.cache);
    const Bounds lines = compute_bounds(load_lines(cache));
    const float radius = cache.provenance("/assets/embree")->stats["radius_world"].get<float>();
    EXPECT_NEAR(radius, 0.02 * lines.diagonal(), 1e-6 * lines.diagonal());
    EXPECT_EQ(flight_bounds(cache).max[0], lines.max[0] + radius);
  }
  o.assets = {"tubes", "voxels"};
  o.tubes.radius = 0.004f;
  bake(o);
  const CacheReader cache(o.cache);
  const Bounds lines = compute_bounds(load_lines(cache));
  const Bounds mesh = compute_bounds(load_tubes(cache));
  const float radius = cache.provenance("/assets/tubes")->stats["radius_world"].get<float>();
  EXPECT_NEAR(radius, 0.004 * lines.diagonal(), 1e-6 * lines.diagonal());
  const Bounds framed = flight_bounds(cache);
  for (size_t k = 0; k < 3; ++k) {
    EXPECT_EQ(framed.min[k], lines.min[k] - radius) << k;
    EXPECT_EQ(framed.max[k], lines.max[k] + radius) << k;
    EXPECT_LE(framed.min[k], mesh.min[k]) << k;  // the rings lie within the radius
    EXPECT_GE(framed.max[k], mesh.max[k]) << k;
    EXPECT_GT(mesh.max[k] - mesh.min[k], lines.max[k] - lines.min[k]) << k;
  }
}

}  // namespace
}  // namespace linebake
