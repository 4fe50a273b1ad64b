// tiles (lib/render/vulkan/tile_renderer.hpp): the compute-only renderer against Embree's
// capsules on the CPU (the same surface), and its slices against one pass.

#include <gtest/gtest.h>

#include <cmath>

#include "accel/capsule_segments.hpp"
#include "cache/cache.hpp"
#include "metrics/image_metrics.hpp"
#include "pipeline/bake.hpp"
#include "render/vulkan/tile_renderer.hpp"
#include "synth/synth.hpp"
#include "techniques/technique.hpp"
#include "test_util.hpp"

namespace linebake {
namespace {

using test::TempDir;

TEST(Tiles, MatchesEmbreeCapsulesForEveryPreset) {
  TempDir dir;
  BakeOptions bake_options;
  bake_options.input = "synth:aneurysm?scale=0.01";
  bake_options.cache = dir.file("a.lbc.h5");
  bake_options.progress = false;
  bake(bake_options);
  const CacheReader cache(bake_options.cache);
  TechniqueOptions o;
  o.width = 160, o.height = 120;
  o.geometry = "capsules";
  const Technique& embree = find_technique("embree");
  const Technique& tiles = find_technique("tiles");
  auto reference = embree.prepare(embree.info, cache, bake_options.cache, o);
  auto ours = tiles.prepare(tiles.info, cache, bake_options.cache, o);
  for (const double zoom : {1.0, 0.5}) {
    const Camera camera = frame_bounds(ours->bounds(), 160.0 / 120.0, 30, 20, zoom);
    for (const char* preset : {"opaque", "semi", "transparent"}) {
      const TransferFunction tf = transfer_function_preset(preset);
      const TechniqueFrame a = ours->render(camera, tf, o.width, o.height);
      const TechniqueFrame b = reference->render(camera, tf, o.width, o.height);
      EXPECT_GE(psnr(display_encoded(a.image), display_encoded(b.image)), 50.0)
          << preset << " zoom " << zoom;
      EXPECT_EQ(a.stats["window_overflows"], 0) << preset;
      EXPECT_GT(a.stats["hits"].get<uint64_t>(), 1000u) << preset;
      for (const char* field : {"keys", "tiles", "frame_bytes", "gpu_ms", "depth_complexity"})
        EXPECT_TRUE(a.stats.contains(field)) << field;
    }
  }
}

TEST(Tiles, SlicesGiveTheSameBytes) {
  const LineSet lines = synth::generate(synth::parse_synth_source("synth:aneurysm?scale=0.005"));
  const Bounds bounds = compute_bounds(lines);
  const float dx = bounds.max[0] - bounds.min[0], dy = bounds.max[1] - bounds.min[1],
              dz = bounds.max[2] - bounds.min[2];
  const CapsuleSegments capsules = build_capsule_segments(
      lines, 0.002f * std::sqrt(dx * dx + dy * dy + dz * dz), lines.attributes[0].name);
  const Camera camera = frame_bounds(bounds, 64.0 / 48.0, 30, 20);
  const TransferFunction tf = transfer_function_preset("semi");
  vk::Context ctx;
  vk::TileOptions o;
  o.width = 64, o.height = 48;
  // (Not one pass: lavapipe stops an invocation after 65535 loop iterations, which a tile of
  // this set can pass; the default there is 512 keys a slice.)
  vk::TileRenderer coarse(ctx, capsules, 0, 700), fine(ctx, capsules, 0, 32);
  const vk::TileFrame a = coarse.render(camera, tf, o), b = fine.render(camera, tf, o);
  EXPECT_LT(a.stats.slices, b.stats.slices);
  EXPECT_GT(b.stats.slices, 3u);
  EXPECT_EQ(a.image.pixels, b.image.pixels);
  EXPECT_EQ(a.depth_complexity, b.depth_complexity);
  EXPECT_GT(a.stats.hits, 100u);
}

}  // namespace
}  // namespace linebake
