// Voxel ray casting (VRC) on the CPU and with Vulkan compute (lavapipe): a hand-built grid with
// one line through known voxels against the analytic ray-line distance, GPU against CPU, and
// quality against the tube-mesh reference as the grid and its quantisation grow.

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <iostream>
#include <optional>

#include "accel/embree_scene.hpp"
#include "core/measure.hpp"
#include "metrics/image_metrics.hpp"
#include "render/ray_tracer.hpp"
#include "render/voxel_ray_caster.hpp"
#include "render/vulkan/voxel_caster.hpp"
#include "synth/synth.hpp"
#include "test_util.hpp"
#include "tubes/tube_builder.hpp"
#include "voxels/voxelizer.hpp"

namespace linebake {
namespace {

using test::validated;

// Voxels of size 1 at the origin, Q = 16, each holding the one chord `chord_of` gives it (none
// where it gives nullopt).
using ChordOf = std::function<std::optional<std::array<uint32_t, 2>>(uint32_t, uint32_t, uint32_t)>;
VoxelGrid grid_of(const std::array<uint32_t, 3>& resolution, const ChordOf& chord_of) {
  VoxelGrid g;
  g.resolution = resolution;
  g.origin = {0, 0, 0};
  g.voxel_size = 1;
  g.quantization = 16;
  g.attribute_range = {0, 1};
  g.offsets = Array<uint32_t>(g.voxel_count() + 1);
  std::vector<uint32_t> words;
  for (uint32_t z = 0; z < resolution[2]; ++z)
    for (uint32_t y = 0; y < resolution[1]; ++y)
      for (uint32_t x = 0; x < resolution[0]; ++x) {
        g.offsets[g.index(x, y, z)] = uint32_t(words.size() / 2);
        if (const auto w = chord_of(x, y, z)) words.insert(words.end(), w->begin(), w->end());
      }
  g.offsets[g.voxel_count()] = uint32_t(words.size() / 2);
  g.chords = Array<uint32_t>(words.size());
  for (size_t i = 0; i < words.size(); ++i) g.chords[i] = words[i];
  return g;
}

// 12 x 3 x 3 voxels; voxels 4..7 of the middle row (y = z = 1) hold one chord each, from the
// x-low face to the x-high face at the face cell (8, 8) of Q = 16: the line y = z = 1 + 8.5 / 16
// from x = 4 to x = 8. Voxels x <= 2 and x >= 9 are empty space.
VoxelGrid one_line_grid() {
  return grid_of({12, 3, 3}, [](uint32_t x, uint32_t y, uint32_t z) {
    return y == 1 && z == 1 && x >= 4 && x <= 7
               ? std::optional(pack_chord({0, 8, 8, 0}, {1, 8, 8, 0}, 7, 128, 128, 16))
               : std::nullopt;
  });
}

// Distance from the ray to the infinite line y = z = c, and the x where they are closest.
std::pair<double, double> ray_line_distance(const glm::dvec3& o, const glm::dvec3& d, double c) {
  // Line: p = (s, c, c). Closest points of two lines with directions d and e = (1, 0, 0).
  const glm::dvec3 e(1, 0, 0), w = o - glm::dvec3(0, c, c);
  const double a = glm::dot(d, d), b = glm::dot(d, e), cc = glm::dot(e, e);
  const double dd = glm::dot(d, w), ee = glm::dot(e, w);
  const double den = a * cc - b * b;
  const double t = (b * ee - cc * dd) / den, s = (a * ee - b * dd) / den;
  return {glm::length((o + t * d) - glm::dvec3(s, c, c)), s};
}

TEST(Vrc, OneLineThroughKnownVoxelsHitsTheExpectedPixels) {
  const VoxelGrid grid = one_line_grid();
  const OccupancyPyramid occupancy = build_occupancy(grid);
  Camera camera;
  camera.eye = {6, 2.5, 8};  // above the line, looking down -z, a little off its axis
  camera.target = {6, 1.5, 1.5};
  camera.near = 0.1, camera.far = 100;
  VrcOptions o;
  o.width = 96, o.height = 64;
  o.radius = 0.3;
  TransferFunction tf = transfer_function_preset("transparent");  // opacity 0.1 everywhere
  const double c = 1 + 8.5 / 16;
  for (const bool skip : {true, false}) {
    o.skip_empty_space = skip;
    const VrcFrame f = cast_voxel_frame(grid, occupancy, camera, tf, o);
    size_t expected_hits = 0, agree = 0, compared = 0;
    for (int y = 0; y < o.height; ++y)
      for (int x = 0; x < o.width; ++x) {
        const glm::dvec3 d = camera.ray_direction(x, y, o.width, o.height);
        const auto [distance, along] = ray_line_distance(camera.eye, d, c);
        // Away from the silhouette and from the line's rounded ends.
        if (std::abs(distance - o.radius) < 0.02 || std::abs(along - 4) < 0.35 ||
            std::abs(along - 8) < 0.35)
          continue;
        const bool expected = distance < o.radius && along > 4 && along < 8;
        const float alpha = f.alpha[size_t(y) * size_t(o.width) + size_t(x)];
        ++compared;
        expected_hits += expected;
        // One hit, never two where the capsules of neighbouring chords overlap.
        agree += expected ? std::abs(alpha - 0.1f) < 1e-5f : alpha == 0.0f;
      }
    EXPECT_EQ(agree, compared) << "skip " << skip;
    EXPECT_GT(expected_hits, 300u);
    EXPECT_GT(compared, size_t(o.width * o.height) * 3 / 4);
    std::cout << "skip " << skip << ": " << expected_hits << " pixels on the line, " << compared
              << " compared\n";
    for (float a : f.alpha) EXPECT_LE(a, 0.1f + 1e-5f);
    if (skip)
      EXPECT_GT(f.stats.cells_skipped, 0u);
    else
      EXPECT_EQ(f.stats.cells_skipped, 0u);
  }
}

struct SynthScene {
  LineSet lines;
  TubeMesh mesh;
  Camera camera;
};

SynthScene aneurysm_scene() {
  SynthScene s;
  synth::SynthParams params;
  params.name = "aneurysm";
  params.scale = 0.2;
  s.lines = synth::generate(params);
  TubeOptions t;
  t.sides = 8;
  t.radius = 0.002f;
  t.attribute = synth::find_data_set("aneurysm").attribute;
  s.mesh = build_tubes(s.lines, t);
  s.camera = frame_bounds(compute_bounds(s.mesh), 1.0, 30, 20);
  return s;
}

VoxelGrid grid_for(const SynthScene& s, uint32_t resolution, uint32_t quantization) {
  VoxelOptions v;
  v.grid = resolution;
  v.quantization = quantization;
  v.attribute = synth::find_data_set("aneurysm").attribute;
  return voxelize(s.lines, v);
}

TEST(Vrc, QualityGrowsWithTheGridAndItsQuantisation) {
  const SynthScene s = aneurysm_scene();
  const TransferFunction tf = transfer_function_preset("semi");
  TraceOptions trace;
  trace.width = trace.height = 128;
  const Image reference =
      display_encoded(trace_frame(EmbreeScene::from_tubes(s.mesh, {}), s.camera, tf, trace).image);
  double quality[2][2] = {};
  int i = 0;
  for (const auto& [resolution, quantization] : {std::pair{48u, 16u}, std::pair{192u, 64u}}) {
    const VoxelGrid grid = grid_for(s, resolution, quantization);
    VrcOptions o;
    o.width = o.height = 128;
    o.radius = s.mesh.radius;
    o.early_termination = false;
    const VrcFrame f = cast_voxel_frame(grid, build_occupancy(grid), s.camera, tf, o);
    EXPECT_FALSE(f.stats.radius_clamped);
    const Image image = display_encoded(f.image);
    quality[i][0] = ssim(image, reference);
    quality[i][1] = psnr(image, reference);
    std::cout << "vrc grid " << resolution << ", Q " << quantization << ": SSIM " << quality[i][0]
              << ", PSNR " << quality[i][1] << " dB\n";
    ++i;
  }
  EXPECT_GT(quality[1][0], quality[0][0]);
  EXPECT_GT(quality[1][1], quality[0][1]);
}

TEST(Vrc, GpuAndCpuAgree) {
  const SynthScene s = aneurysm_scene();
  const VoxelGrid grid = grid_for(s, 96, 32);
  const OccupancyPyramid occupancy = build_occupancy(grid);
  vk::Context ctx(validated());
  vk::VoxelCaster caster(ctx, grid, occupancy);
  for (const std::string preset : {"semi", "transparent"}) {
    const TransferFunction tf = transfer_function_preset(preset);
    VrcOptions o;
    o.width = 128, o.height = 96;
    o.radius = s.mesh.radius;
    const VrcFrame cpu = cast_voxel_frame(grid, occupancy, s.camera, tf, o);
    const VrcFrame gpu = caster.render(s.camera, tf, o);
    const double db = psnr(display_encoded(gpu.image), display_encoded(cpu.image));
    std::cout << "vrc " << preset << ": GPU vs CPU PSNR " << db << " dB, hits " << gpu.stats.hits
              << " vs " << cpu.stats.hits << "\n";
    EXPECT_GE(db, 45.0) << preset;
    EXPECT_GT(cpu.stats.hits, 1000u);
  }
  EXPECT_EQ(ctx.validation_errors(), 0u) << ctx.last_validation_error();
}

// The same scene at a millionth of its size, ten thousand times it, and moved 1e5 away: the GPU
// tests capsules in grid units about each voxel (from the eye's place in the grid, found in
// double), so it keeps the CPU's image (in world units float32 had squared a voxel of 1e-6 to
// nothing: 19.5 dB; far from the origin the ray's start was lost: 21.8 dB).
TEST(Vrc, GpuAgreesWithTheCpuAtAnyScaleAndDistanceFromTheOrigin) {
  const SynthScene s = aneurysm_scene();
  const VoxelGrid base = grid_for(s, 96, 32);
  vk::Context ctx;
  const TransferFunction tf = transfer_function_preset("semi");
  for (const auto& [scale, offset] :
       std::vector<std::pair<double, double>>{{1e-6, 0.0}, {1e4, 0.0}, {1.0, 1e5}, {1e-3, 1e3}}) {
    VoxelGrid grid = base;  // the chords are voxel-local: the grid moves with origin and size
    for (size_t k = 0; k < 3; ++k) grid.origin[k] = float(double(base.origin[k]) * scale + offset);
    grid.voxel_size = float(double(base.voxel_size) * scale);
    const OccupancyPyramid occupancy = build_occupancy(grid);
    Camera camera = s.camera;
    camera.eye = camera.eye * scale + glm::dvec3(offset);
    camera.target = camera.target * scale + glm::dvec3(offset);
    camera.near *= scale, camera.far *= scale;
    VrcOptions o;
    o.width = 96, o.height = 72;
    o.radius = s.mesh.radius * scale;
    vk::VoxelCaster caster(ctx, grid, occupancy);
    const VrcFrame cpu = cast_voxel_frame(grid, occupancy, camera, tf, o);
    const VrcFrame gpu = caster.render(camera, tf, o);
    const double db = psnr(display_encoded(gpu.image), display_encoded(cpu.image));
    EXPECT_GE(db, 45.0) << "scale " << scale << ", offset " << offset;
    EXPECT_GT(cpu.stats.hits, 1000u) << "scale " << scale << ", offset " << offset;
  }
}

// A walk in slices of any length, the pixels' state kept between dispatches, gives the bytes of
// one walk; skipping empty space changes nothing either (on the GPU it had ended rays that left
// a cell where they entered it, grazing its face in float32).
TEST(Vrc, GpuSlicesAndSkippingGiveTheSameBytes) {
  const SynthScene s = aneurysm_scene();
  const VoxelGrid grid = grid_for(s, 96, 32);
  const OccupancyPyramid occupancy = build_occupancy(grid);
  vk::Context ctx(validated());
  const TransferFunction tf = transfer_function_preset("semi");
  VrcOptions o;
  o.width = 80, o.height = 60;
  o.radius = s.mesh.radius;
  o.early_termination = false;
  vk::VoxelCaster caster(ctx, grid, occupancy);
  const VrcFrame whole = caster.render(s.camera, tf, o);
  EXPECT_EQ(whole.stats.gpu_slice_steps, 0u);
  for (const uint32_t steps : {1u, 3u, 7u, 64u}) {
    caster.set_slice_steps(steps, 7);  // bands of 7 rows
    for (const bool skip : {true, false}) {
      o.skip_empty_space = skip;
      const VrcFrame sliced = caster.render(s.camera, tf, o);
      EXPECT_EQ(sliced.image.pixels, whole.image.pixels) << steps << " steps, skip " << skip;
      EXPECT_EQ(sliced.depth_complexity, whole.depth_complexity) << steps;
      EXPECT_EQ(sliced.stats.gpu_slice_steps, steps);
      EXPECT_GT(sliced.stats.gpu_slices, 60u / 7u) << steps;  // bands of 7 rows, 2 slices each
    }
  }
  EXPECT_EQ(ctx.validation_errors(), 0u) << ctx.last_validation_error();
}

// A row of 20,000 voxels walked end to end without skipping: on lavapipe more loop trips than
// its limit lets one invocation run (65535), which had dropped the line at the row's end
// silently. The caster slices the walk and draws it as the CPU does.
TEST(Vrc, AWalkPastLavapipesLoopLimitIsSlicedNotCut) {
  // In the last ten voxels, a chord across each from its y-low face to its y-high face.
  const VoxelGrid g = grid_of({20000, 1, 1}, [](uint32_t x, uint32_t, uint32_t) {
    return x >= 19990 ? std::optional(pack_chord({2, 8, 8, 0}, {3, 8, 8, 0}, 7, 128, 128, 16))
                      : std::nullopt;
  });
  const OccupancyPyramid occupancy = build_occupancy(g);
  Camera camera;
  camera.eye = {-1, 0.5, 0.5};
  camera.target = {20000, 0.5, 0.5};
  camera.fov_y_degrees = 0.001;  // every ray stays inside the row to its end
  camera.near = 0.1, camera.far = 30000;
  VrcOptions o;
  o.width = 8, o.height = 8;
  o.radius = 0.3;
  o.skip_empty_space = false;
  const TransferFunction tf = transfer_function_preset("transparent");
  vk::Context ctx;
  vk::VoxelCaster caster(ctx, g, occupancy);
  const VrcFrame cpu = cast_voxel_frame(g, occupancy, camera, tf, o);
  const VrcFrame gpu = caster.render(camera, tf, o);
  ASSERT_GT(cpu.stats.hits, 0u);
  EXPECT_EQ(gpu.stats.hits, cpu.stats.hits);
  EXPECT_GE(psnr(display_encoded(gpu.image), display_encoded(cpu.image)), 45.0);
  if (ctx.info().lavapipe) {
    EXPECT_GT(gpu.stats.gpu_slice_steps, 0u);
  }
  // Bands of 7 rows, each walk many slices long: the last workgroup row of a band's dispatch is
  // the next band's, and had walked with no state of its own, its walk never ending.
  caster.set_slice_steps(1024, 7);
  const VrcFrame banded = caster.render(camera, tf, o);
  EXPECT_EQ(banded.image.pixels, gpu.image.pixels);
  EXPECT_EQ(banded.stats.gpu_slices, 2u * (20000u / 1024u + 1u));
  std::cout << "hits " << gpu.stats.hits << ", " << gpu.stats.gpu_slices << " dispatches of "
            << gpu.stats.gpu_slice_steps << " steps\n";
}

}  // namespace
}  // namespace linebake

namespace linebake {
namespace {

// The walks' state refused by the memory budget: an error, and the caster still renders the next
// frame (it had kept no buffer for its counters and wrote through a null mapping).
TEST(Vrc, ARefusedWalkStateLeavesACasterThatRendersAgain) {
  const SynthScene s = aneurysm_scene();
  const VoxelGrid grid = grid_for(s, 64, 32);
  const OccupancyPyramid occupancy = build_occupancy(grid);
  vk::Context ctx;
  if (!ctx.memory_is_host()) GTEST_SKIP() << ctx.info().name << " has memory of its own";
  vk::VoxelCaster caster(ctx, grid, occupancy);
  const TransferFunction tf = transfer_function_preset("semi");
  VrcOptions o;
  o.width = 64, o.height = 48;
  o.radius = s.mesh.radius;
  const VrcFrame first = caster.render(s.camera, tf, o);
  caster.set_slice_steps(4);
  ctx.set_host_budget(trimmed_rss_bytes() + 64);  // no room for a row of state
  EXPECT_THROW(caster.render(s.camera, tf, o), BudgetExceeded);
  ctx.set_host_budget(0);
  caster.set_slice_steps(0);
  const VrcFrame again = caster.render(s.camera, tf, o);
  EXPECT_EQ(again.image.pixels, first.image.pixels);
}

}  // namespace
}  // namespace linebake
