// tiles (lib/render/vulkan/tile_renderer.hpp): the compute-only renderer against Embree's
// capsules on the CPU (the same surface), and its slices against one pass.

#include <gtest/gtest.h>

#include <array>
#include <bit>
#include <cmath>
#include <cstdio>
#include <functional>
#include <glm/glm.hpp>
#include <memory>
#include <optional>

#include "accel/capsule_segments.hpp"
#include "accel/embree_scene.hpp"
#include "cache/cache.hpp"
#include "cache/line_store.hpp"
#include "cache/tube_store.hpp"
#include "core/error.hpp"
#include "metrics/image_metrics.hpp"
#include "pipeline/bake.hpp"
#include "render/ray_tracer.hpp"
#include "render/vulkan/radix_sort.hpp"
#include "render/vulkan/tile_renderer.hpp"
#include "synth/synth.hpp"
#include "techniques/framing.hpp"
#include "techniques/technique.hpp"
#include "test_util.hpp"
#include "tubes/tube_builder.hpp"

namespace linebake {
namespace {

using test::TempDir;

// `source` baked into a cache in a temporary directory, with `tiles` (over `geometry`) and the
// technique `against` prepared on it for 160x120 frames.
struct PreparedPair {
  TempDir dir;
  std::optional<CacheReader> cache;
  std::unique_ptr<PreparedTechnique> ours, theirs;
};

std::unique_ptr<PreparedPair> prepare_pair(const std::string& source, const char* geometry,
                                           const char* against) {
  auto pair = std::make_unique<PreparedPair>();
  BakeOptions bake_options;
  bake_options.input = source;
  bake_options.cache = pair->dir.file("a.lbc.h5");
  bake_options.progress = false;
  bake(bake_options);
  pair->cache.emplace(bake_options.cache);
  TechniqueOptions o;
  o.width = 160, o.height = 120;
  o.geometry = "capsules";
  o.tiles_geometry = geometry;
  const Technique& theirs = find_technique(against);
  const Technique& tiles = find_technique("tiles");
  pair->theirs = theirs.prepare(theirs.info, *pair->cache, bake_options.cache, o);
  pair->ours = tiles.prepare(tiles.info, *pair->cache, bake_options.cache, o);
  return pair;
}

// The test scenes' box: the one a flight frames (the lines grown by the tubes' radius), and for
// triangles the tube mesh's own box, as when the targets were set. (At the flight's cameras
// one triangle pixel in the frame can flip at a silhouette, where float32 cannot decide:
// TrianglesDifferFromTheReferenceOnlyWhereFloatsCannotDecide, below.)
Bounds scene_bounds(const CacheReader& cache, const char* geometry) {
  return std::string(geometry) == "triangles" ? compute_bounds(load_tubes(cache))
                                              : flight_bounds(cache);
}

// Capsules against Embree's capsules and triangles against `reference` (Embree over the tube
// mesh), on two of the test scenes, for every preset.
void expect_matches(const std::string& source, const char* geometry, const char* against,
                    const std::vector<double>& zooms) {
  const auto pair = prepare_pair(source, geometry, against);
  PreparedTechnique& ours = *pair->ours;
  PreparedTechnique& theirs = *pair->theirs;
  for (const double zoom : zooms) {
    const Camera camera =
        frame_bounds(scene_bounds(*pair->cache, geometry), 160.0 / 120.0, 30, 20, zoom);
    for (const char* preset : {"opaque", "semi", "transparent"}) {
      const TransferFunction tf = transfer_function_preset(preset);
      const TechniqueFrame a = ours.render(camera, tf, 160, 120);
      const TechniqueFrame b = theirs.render(camera, tf, 160, 120);
      EXPECT_GE(psnr(display_encoded(a.image), display_encoded(b.image)), 50.0)
          << source << " " << geometry << " " << preset << " zoom " << zoom;
      EXPECT_GT(a.stats["hits"].get<uint64_t>(), 1000u) << preset;
      for (const char* field : {"keys", "tiles", "bands", "frame_bytes", "gpu_ms",
                                "depth_complexity", "walk_ms", "walk_tiles", "max_tile_keys"})
        EXPECT_TRUE(a.stats.contains(field)) << field;
    }
  }
  // Which path the key sort took (radix_sort.hpp): a subgroup size, or 0.
  EXPECT_TRUE(ours.stats().contains("sort_subgroup_size"));
}

// How near the ray from `eye` along `d` passes to the surface of a capsule of `lines` (radius
// `radius`), in double: the least |distance to a segment - radius| over the segments. The
// distance from a point moving along a segment to a ray is convex in the segment's parameter,
// so a ternary search finds its minimum.
double grazing_distance(const LineSet& lines, float radius, const glm::dvec3& eye,
                        const glm::dvec3& d) {
  const auto distance_to_ray = [&](const glm::dvec3& p) {
    const double t = std::max(0.0, glm::dot(p - eye, d));
    return glm::length(p - (eye + t * d));
  };
  const auto point = [&](uint64_t i) {
    return glm::dvec3(lines.positions[3 * i], lines.positions[3 * i + 1],
                      lines.positions[3 * i + 2]);
  };
  double grazing = INFINITY;
  for (size_t line = 0; line < lines.line_count(); ++line)
    for (uint64_t i = lines.line_offsets[line]; i + 1 < lines.line_offsets[line + 1]; ++i) {
      const glm::dvec3 a = point(i), b = point(i + 1);
      double lo = 0, hi = 1;
      for (int k = 0; k < 80; ++k) {
        const double m1 = lo + (hi - lo) / 3, m2 = hi - (hi - lo) / 3;
        if (distance_to_ray(a + m1 * (b - a)) < distance_to_ray(a + m2 * (b - a)))
          hi = m2;
        else
          lo = m1;
      }
      grazing =
          std::min(grazing, std::fabs(distance_to_ray(a + 0.5 * (lo + hi) * (b - a)) - radius));
    }
  return grazing;
}

// Per pixel, the front hits tiles counts are Embree's, except where a ray grazes a capsule so
// nearly that float32 cannot say whether it hits: both test in float32, with other formulas and,
// on a GPU, another compiler's rounding (NVIDIA's H200, 2026-11-30: at one pixel of
// ACapsuleEnteredAtItsRimIsCompositedOnce's frame, which lavapipe matches, tiles missed a capsule
// Embree hit, the ray 2.4e-5 from its surface in double, 0.22 % of the radius). Such a pixel
// differs by one hit and its ray passes within float32's reach of a capsule's surface, taken as
// 16 units in the last place of the eye's and the points' largest coordinates (3.4e-5 here); a
// binning bound too tight (hits dropped) or a crossing composited twice leaves a pixel whose ray
// is far from every surface, or one that differs by more. Returns the hits Embree counts.
uint64_t expect_front_hits_as_embree(PreparedPair& pair, const Camera& camera,
                                     const std::string& what) {
  const TransferFunction tf = transfer_function_preset("semi");
  const TechniqueFrame a = pair.ours->render(camera, tf, 160, 120);
  const TechniqueFrame b = pair.theirs->render(camera, tf, 160, 120);
  EXPECT_EQ(a.depth_complexity.size(), b.depth_complexity.size()) << what;
  if (a.depth_complexity.size() != b.depth_complexity.size()) return 0;
  std::optional<LineSet> lines;
  float radius = 0;  // the cached tubes', which the capsules take
  double reach = 0;
  uint64_t hits = 0, differing = 0;
  for (size_t i = 0; i < a.depth_complexity.size(); ++i) {
    hits += b.depth_complexity[i];
    const uint32_t ours = a.depth_complexity[i], theirs = b.depth_complexity[i];
    if (ours == theirs) continue;
    ++differing;
    if (!lines) {
      lines = load_lines(*pair.cache), radius = load_tubes(*pair.cache).radius;
      float largest = 0;
      for (const float c : lines->positions) largest = std::max(largest, std::fabs(c));
      const glm::dvec3 eye = glm::abs(camera.eye);
      reach = 16 * 0x1p-23 * (std::max({eye.x, eye.y, eye.z}) + largest);
    }
    const double x = double(i % 160), y = double(i / 160);
    const double grazing =
        grazing_distance(*lines, radius, camera.eye, camera.ray_direction(x, y, 160, 120));
    const std::string pixel =
        what + ": pixel " + std::to_string(i % 160) + ", " + std::to_string(i / 160) + " takes " +
        std::to_string(ours) + " front hits, Embree " + std::to_string(theirs) + ", its ray " +
        std::to_string(grazing) + " from a capsule's surface (radius " + std::to_string(radius) +
        ", float32's reach " + std::to_string(reach) + ")";
    std::printf("%s\n", pixel.c_str());
    EXPECT_LE(std::max(ours, theirs) - std::min(ours, theirs), 1u) << pixel;
    EXPECT_LE(grazing, reach) << pixel;
  }
  EXPECT_LE(differing, 2u) << what;
  return hits;
}

// Close up (zoom 0.25) capsules span many blocks and tiles; far away (zoom 1), several share a
// block.
TEST(Tiles, CapsulesHitThePixelsEmbreeHits) {
  const auto pair = prepare_pair("synth:aneurysm?scale=0.01", "capsules", "embree");
  for (const double zoom : {1.0, 0.25}) {
    const Camera camera = frame_bounds(flight_bounds(*pair->cache), 160.0 / 120.0, 30, 20, zoom);
    EXPECT_GT(expect_front_hits_as_embree(*pair, camera, "zoom " + std::to_string(zoom)), 1000u);
  }
}

// A capsule is convex, so a ray enters it once; where it enters at the rim between the cylinder
// and an end sphere, the float32 capsule test can report both, the same point twice. Frame 12
// of a 32-frame orbit-zoom flight over turbulence at scale 0.01 has one such pixel at 160x120
// (found by comparing 192 small frames with Embree's counts): composited twice, it took one hit
// more than Embree's, a ray far from grazing; the composite takes a primitive's nearest front
// crossing only.
TEST(Tiles, ACapsuleEnteredAtItsRimIsCompositedOnce) {
  const auto pair = prepare_pair("synth:turbulence?scale=0.01", "capsules", "embree");
  FlightOptions flight;
  flight.frames = 32;
  const Camera camera = make_flight(flight_bounds(*pair->cache), 160.0 / 120.0, flight).at(12);
  EXPECT_GT(expect_front_hits_as_embree(*pair, camera, "frame 12"), 1000u);
}

TEST(Tiles, CapsulesMatchEmbreeCapsulesForEveryPreset) {
  expect_matches("synth:aneurysm?scale=0.01", "capsules", "embree", {1.0, 0.5});
  expect_matches("synth:convection?scale=0.01", "capsules", "embree", {1.0});
}

TEST(Tiles, TrianglesMatchTheReferenceForEveryPreset) {
  expect_matches("synth:aneurysm?scale=0.01", "triangles", "reference", {1.0, 0.5});
  expect_matches("synth:convection?scale=0.01", "triangles", "reference", {1.0});
}

// Where the triangle mode and the reference (Embree over the same float32 triangles) differ at
// the flight's cameras by more than shading's float error, the pixel's ray passes so near a
// triangle's edge that float32 cannot say whether it hits: the ray in double meets a
// front-facing triangle whose barycentric coordinates lie within kNoise of its boundary (in front
// of the nearest hit or at it where only that one shows, opaque). Both compute the test from
// vertices relative to the eye in float32: with coordinates up to 16 and triangles 0.02 across,
// that is about 3e-5 of a triangle; the largest margin found was 9.8e-5. A binning or composite
// error would leave a pixel whose ray is far from every edge.
TEST(Tiles, TrianglesDifferFromTheReferenceOnlyWhereFloatsCannotDecide) {
  constexpr double kNoise = 3e-4;
  constexpr float kShading = 0.02f;  // interpolated normals and attributes: 7e-3 at most seen
  for (const auto& [source, zoom] : {std::pair{"synth:aneurysm?scale=0.01", 0.5},
                                     std::pair{"synth:convection?scale=0.01", 1.0}}) {
    const auto pair = prepare_pair(source, "triangles", "reference");
    const TubeMesh mesh = load_tubes(*pair->cache);
    const Camera camera = frame_bounds(flight_bounds(*pair->cache), 160.0 / 120.0, 30, 20, zoom);
    size_t differing = 0;
    for (const char* preset : {"opaque", "semi", "transparent"}) {
      const TransferFunction tf = transfer_function_preset(preset);
      const Image a = pair->ours->render(camera, tf, 160, 120).image;
      const Image b = pair->theirs->render(camera, tf, 160, 120).image;
      for (size_t pixel = 0; pixel < size_t(160 * 120); ++pixel) {
        float most = 0;
        for (size_t k = 0; k < 3; ++k)
          most = std::max(most, std::fabs(a.pixels[3 * pixel + k] - b.pixels[3 * pixel + k]));
        if (most <= kShading) continue;
        ++differing;
        const glm::dvec3 eye = camera.eye;
        const glm::dvec3 d =
            camera.ray_direction(double(pixel % 160), double(pixel / 160), 160, 120);
        double front = INFINITY, undecided = INFINITY;  // nearest hit, nearest edge-grazing one
        for (const TubeChunk& chunk : mesh.chunks)
          for (size_t t = 0; t < chunk.triangle_count(); ++t) {
            glm::dvec3 v[3];
            for (size_t k = 0; k < 3; ++k) {
              const uint32_t i = chunk.indices[3 * t + k];
              v[k] = {chunk.positions[3 * i], chunk.positions[3 * i + 1],
                      chunk.positions[3 * i + 2]};
            }
            const glm::dvec3 e1 = v[1] - v[0], e2 = v[2] - v[0], p = glm::cross(d, e2);
            const double det = glm::dot(e1, p);
            if (det <= 0) continue;  // the back faces neither draws
            const glm::dvec3 s0 = eye - v[0], q = glm::cross(s0, e1);
            const double u = glm::dot(s0, p) / det, w = glm::dot(d, q) / det,
                         along = glm::dot(e2, q) / det;
            const double margin = std::min({u, w, 1 - u - w});
            if (along <= 0 || margin < -kNoise) continue;
            if (margin >= 0) front = std::min(front, along);
            if (std::fabs(margin) < kNoise) undecided = std::min(undecided, along);
          }
        // Opaque, only the front hit shows; with transparency every hit does.
        const bool every_hit_shows = std::string(preset) != "opaque";
        EXPECT_LE(undecided, every_hit_shows ? double(INFINITY) / 2 : front * (1 + 1e-6))
            << source << " " << preset << ": pixel " << pixel % 160 << ", " << pixel / 160
            << " differs by " << most << " with no edge within float error of its ray";
      }
    }
    EXPECT_LE(differing, 12u) << source;  // a few silhouette pixels, in three presets
  }
}

// TechniqueOptions::tiles_sort (render --tiles-sort): `shared` keeps the key sort on shared
// memory, `subgroups` takes the subgroup path where the device has it and is refused where it
// does not, anything else is a usage error; both paths give the same image, to the bit.
TEST(Tiles, TheSortPathIsTheCallersToChoose) {
  const auto pair = prepare_pair("synth:aneurysm?scale=0.01", "capsules", "embree");
  const Technique& tiles = find_technique("tiles");
  const std::string cache_name = pair->dir.file("a.lbc.h5");
  TechniqueOptions o;
  o.width = 160, o.height = 120;
  o.tiles_sort = "shared";
  const auto shared = tiles.prepare(tiles.info, *pair->cache, cache_name, o);
  EXPECT_EQ(shared->stats()["sort_subgroup_size"], 0u);
  o.tiles_sort = "warp";
  EXPECT_THROW(tiles.prepare(tiles.info, *pair->cache, cache_name, o), UsageError);
  o.tiles_sort = "subgroups";
  vk::Context ctx;  // the device the technique picks: a discrete GPU, else any
  if (!vk::RadixSorter::subgroups_supported(ctx.info())) {
    EXPECT_THROW(tiles.prepare(tiles.info, *pair->cache, cache_name, o), Error);
    GTEST_SKIP() << ctx.info().name << " has no subgroup path to compare";
  }
  const auto subgroups = tiles.prepare(tiles.info, *pair->cache, cache_name, o);
  EXPECT_EQ(subgroups->stats()["sort_subgroup_size"], ctx.info().subgroup_size);
  const Camera camera = frame_bounds(flight_bounds(*pair->cache), 160.0 / 120.0, 30, 20, 0.5);
  const TransferFunction tf = transfer_function_preset("semi");
  const TechniqueFrame a = shared->render(camera, tf, 160, 120);
  const TechniqueFrame b = subgroups->render(camera, tf, 160, 120);
  EXPECT_GT(a.stats["keys"].get<uint64_t>(), 2 * 4096u);  // three of the sort's blocks of 4,096
  EXPECT_EQ(a.stats["keys"], b.stats["keys"]);
  EXPECT_EQ(a.image.pixels, b.image.pixels);
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
  // this set can pass; the default there is 8,192 keys a slice.)
  vk::TileRenderer coarse(ctx, capsules, 0, 700), fine(ctx, capsules, 0, 32);
  const vk::TileFrame a = coarse.render(camera, tf, o), b = fine.render(camera, tf, o);
  EXPECT_LT(a.stats.slices, b.stats.slices);
  EXPECT_GT(b.stats.slices, 3u);
  EXPECT_EQ(a.image.pixels, b.image.pixels);
  EXPECT_EQ(a.depth_complexity, b.depth_complexity);
  EXPECT_GT(a.stats.hits, 100u);
  // Storage buffers that hold the pixels' states of 4 tiles (16 x 16 pixels of 272 bytes on
  // lavapipe, 464 where the window loops exit): the 12 tiles are composited in 3 groups, one
  // after the other, with the same bytes. (At 1080p lavapipe's 128 MiB hold 1,927 of its 8,160
  // tiles.)
  const uint64_t tile_state = fine.tile_state_bytes();
  EXPECT_EQ(tile_state, 16u * 16u * (ctx.info().lavapipe ? 272u : 464u));
  vk::TileRenderer grouped(ctx, capsules, 4 * tile_state, 32);
  const vk::TileFrame c = grouped.render(camera, tf, o);
  EXPECT_EQ(c.stats.groups, 3u);
  EXPECT_EQ(b.stats.groups, 1u);
  EXPECT_EQ(c.image.pixels, b.image.pixels);
  EXPECT_EQ(c.depth_complexity, b.depth_complexity);
  // The same from a memory budget for the states (--memory-budget gives them a quarter of what
  // the image leaves): 6 tiles' states, 2 groups.
  o.max_state_bytes = 6 * tile_state;
  const vk::TileFrame d = fine.render(camera, tf, o);
  EXPECT_EQ(d.stats.groups, 2u);
  EXPECT_EQ(d.image.pixels, b.image.pixels);
  // The builds that shade late keep t and the primitive of a pending hit, no colour: 144 and 208
  // bytes a pixel (20 words, then 8 bytes a hit, where the others keep 24). A budget of 3 tiles'
  // states with colours holds 5 of theirs on lavapipe (3 x 272 / 144 = 5.7: the 12 tiles in 3
  // groups) and 6 where the window loops exit (3 x 464 / 208 = 6.7: 2 groups); one of 3 of
  // theirs, 4 groups. (The renderer checked each composite's own layout of the state against
  // these sizes when it was made.)
  const uint64_t late_state = fine.tile_state_bytes(true);
  EXPECT_EQ(late_state, 16u * 16u * (ctx.info().lavapipe ? 144u : 208u));
  o.late_shading = true;
  o.max_state_bytes = 3 * tile_state;
  const vk::TileFrame e = fine.render(camera, tf, o);
  EXPECT_EQ(e.stats.groups, ctx.info().lavapipe ? 3u : 2u);
  EXPECT_EQ(e.image.pixels, b.image.pixels);
  EXPECT_EQ(e.stats.late_misses, 0u);
  o.max_state_bytes = 3 * late_state;
  const vk::TileFrame f = fine.render(camera, tf, o);
  EXPECT_EQ(f.stats.groups, 4u);
  EXPECT_EQ(f.image.pixels, b.image.pixels);
}

// Binning counts each tile row's keys per workgroup in shared memory for images of up to 1,024
// tile rows (shaders/tiles_keys.glsl) and per primitive in global memory above that. An image
// of 1,027 tile rows takes the second way: its rows' counts must plan the same bands (the host
// refuses counts that disagree with the keys binned), with the same bytes as one band.
TEST(Tiles, ImagesOfMoreTileRowsThanSharedMemoryCountsBinTheSame) {
  const LineSet lines = synth::generate(synth::parse_synth_source("synth:aneurysm?scale=0.005"));
  const Bounds bounds = compute_bounds(lines);
  const CapsuleSegments capsules =
      build_capsule_segments(lines, 0.002f * bounds.diagonal(), lines.attributes[0].name);
  vk::TileOptions o;
  o.width = 32, o.height = 1027 * 16;
  const Camera camera = frame_bounds(bounds, double(o.width) / o.height, 30, 20, 0.05);
  const TransferFunction tf = transfer_function_preset("semi");
  vk::Context ctx;
  vk::TileRenderer renderer(ctx, capsules);
  const vk::TileFrame whole = renderer.render(camera, tf, o);
  ASSERT_EQ(whole.stats.bands, 1u);
  EXPECT_GT(whole.stats.hits, 1000u);
  o.max_key_bytes = std::max(whole.stats.max_row_keys, whole.stats.keys / 3) * 18;
  const vk::TileFrame banded = renderer.render(camera, tf, o);
  EXPECT_GE(banded.stats.bands, 3u);
  EXPECT_EQ(banded.stats.keys, whole.stats.keys);
  EXPECT_EQ(banded.image.pixels, whole.image.pixels);
}

// Bands of tile rows (a frame whose keys exceed the key budget) give the bytes of one band.
TEST(Tiles, BandsGiveTheSameBytes) {
  const LineSet lines = synth::generate(synth::parse_synth_source("synth:aneurysm?scale=0.005"));
  const Bounds bounds = compute_bounds(lines);
  const CapsuleSegments capsules =
      build_capsule_segments(lines, 0.002f * bounds.diagonal(), lines.attributes[0].name);
  const Camera camera = frame_bounds(bounds, 1.0, 30, 20, 0.5);  // zoomed in: rows alike
  const TransferFunction tf = transfer_function_preset("semi");
  vk::Context ctx;
  vk::TileRenderer renderer(ctx, capsules);
  vk::TileOptions o;
  o.width = 128, o.height = 128;
  const vk::TileFrame whole = renderer.render(camera, tf, o);
  ASSERT_EQ(whole.stats.bands, 1u);
  // A budget of the fullest row's keys (or a third of all): several bands.
  ASSERT_LT(whole.stats.max_row_keys * 2, whole.stats.keys);
  o.max_key_bytes = std::max(whole.stats.max_row_keys, whole.stats.keys / 3) * 18;
  const vk::TileFrame banded = renderer.render(camera, tf, o);
  EXPECT_GE(banded.stats.bands, 3u);
  EXPECT_EQ(banded.stats.keys, whole.stats.keys);
  EXPECT_EQ(banded.image.pixels, whole.image.pixels);
  EXPECT_EQ(banded.depth_complexity, whole.depth_complexity);
  EXPECT_GT(whole.stats.hits, 100u);
  // Fewer keys than one row of tiles holds: refused, naming the budget and the primitives.
  o.max_key_bytes = 18;
  try {
    renderer.render(camera, tf, o);
    ADD_FAILURE() << "a row of tiles past the key budget rendered";
  } catch (const BudgetExceeded& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("(tile, segment) keys, more than a band may: 1, what the memory budget "
                        "leaves the keys (18 bytes each); raise --memory-budget"),
              std::string::npos)
        << what;
  }
}

// Primitives whose arrays pass one storage buffer go in pages (lavapipe's 128 MiB held 610 MiB
// of clouds' points at scale 1.0 in 5): with a buffer of 2^k bytes at least twice the point
// count, the points take up to 8 pages and the segment words 2 or more, with the same bytes as in
// one buffer each; past 8 pages they are refused, naming the device. The same for the triangles'
// vertices and indices.
TEST(Tiles, PrimitivesPastOneStorageBufferGoInPagesWithTheSameBytes) {
  const LineSet lines = synth::generate(synth::parse_synth_source("synth:aneurysm?scale=0.005"));
  const Bounds bounds = compute_bounds(lines);
  const CapsuleSegments capsules =
      build_capsule_segments(lines, 0.002f * bounds.diagonal(), lines.attributes[0].name);
  uint64_t points = 0, words = 0;
  for (const CapsuleChunk& chunk : capsules.chunks)
    points += chunk.points.size() / 4, words += chunk.segments.size();
  const uint64_t buffer = std::bit_ceil(2 * points);
  ASSERT_LT(buffer, 4 * words) << "no buffer size pages both here";
  const Camera camera = frame_bounds(bounds, 0.5, 30, 20);
  const TransferFunction tf = transfer_function_preset("semi");
  vk::Context ctx;
  vk::TileOptions o;
  o.width = 64, o.height = 128;  // eight tile rows: a row's keys within the small buffer's
  vk::TileRenderer whole(ctx, capsules), paged(ctx, capsules, buffer);
  EXPECT_EQ(whole.primitive_buffers(), 2u);
  const size_t point_pages = (16 * points + buffer - 1) / buffer,
               word_pages = (4 * words + buffer - 1) / buffer;
  EXPECT_GE(point_pages, 5u);
  EXPECT_GE(word_pages, 2u);
  EXPECT_EQ(paged.primitive_buffers(), point_pages + word_pages);
  const vk::TileFrame a = whole.render(camera, tf, o), b = paged.render(camera, tf, o);
  EXPECT_GT(a.stats.hits, 300u);
  EXPECT_EQ(b.stats.keys, a.stats.keys);
  EXPECT_EQ(b.image.pixels, a.image.pixels);
  EXPECT_EQ(b.depth_complexity, a.depth_complexity);
  try {
    vk::TileRenderer(ctx, capsules, buffer / 2);
    ADD_FAILURE() << "points in more than 8 pages";
  } catch (const BudgetExceeded& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind("tiles: the points take ", 0), 0u) << what;
    EXPECT_NE(what.find(" MiB, more than 8 storage buffers of "), std::string::npos) << what;
    EXPECT_NE(what.find(ctx.info().name), std::string::npos) << what;
  }

  const TubeMesh mesh = build_tubes(lines, TubeOptions{});
  const uint64_t vertices = mesh.vertex_count(), indices = 3 * mesh.triangle_count();
  // At most 8 pages of vertices (32 bytes each) and 4 of indices, at least 2 of each.
  const uint64_t mesh_buffer = std::bit_ceil(std::max(4 * vertices, indices));
  const uint64_t vertex_pages = (32 * vertices + mesh_buffer - 1) / mesh_buffer,
                 index_pages = (4 * indices + mesh_buffer - 1) / mesh_buffer;
  ASSERT_GE(vertex_pages, 2u);
  ASSERT_GE(index_pages, 2u);
  vk::TileRenderer triangles(ctx, mesh), paged_triangles(ctx, mesh, mesh_buffer);
  EXPECT_EQ(triangles.primitive_buffers(), 2u);
  EXPECT_EQ(paged_triangles.primitive_buffers(), vertex_pages + index_pages);
  const vk::TileFrame c = triangles.render(camera, tf, o),
                      d = paged_triangles.render(camera, tf, o);
  EXPECT_GT(c.stats.hits, 100u);
  EXPECT_EQ(d.image.pixels, c.image.pixels);
  EXPECT_EQ(d.depth_complexity, c.depth_complexity);
  EXPECT_THROW(vk::TileRenderer(ctx, mesh, mesh_buffer / 2), BudgetExceeded);
}

// Keys of fewer bits tie more of them (a coarser depth), and tied keys keep the order binning
// emitted them in, which a GPU varies from run to run; the image must not depend on it. Of a
// joint's two reports (seam twins, often with equal keys) the nearer is kept whichever comes
// first; keeping the first to come made 16-bit keys change pixels here. Too few bits for the
// tiles are refused.
TEST(Tiles, KeysOfAnyWidthGiveTheSameBytes) {
  const LineSet lines = synth::generate(synth::parse_synth_source("synth:convection?scale=0.01"));
  const Bounds bounds = compute_bounds(lines);
  const CapsuleSegments capsules =
      build_capsule_segments(lines, 0.002f * bounds.diagonal(), lines.attributes[0].name);
  const TransferFunction tf = transfer_function_preset("semi");
  vk::Context ctx;
  vk::TileRenderer renderer(ctx, capsules);
  vk::TileOptions o;
  o.width = 160, o.height = 120;  // 80 tiles: 7 bits
  for (const double zoom : {1.0, 0.3}) {
    const Camera camera = frame_bounds(bounds, 160.0 / 120.0, 30, 20, zoom);
    o.key_bits = 32;
    const vk::TileFrame wide = renderer.render(camera, tf, o);
    EXPECT_GT(wide.stats.hits, 1000u);
    for (const uint32_t bits : {24u, 16u, 12u}) {
      o.key_bits = bits;
      const vk::TileFrame narrow = renderer.render(camera, tf, o);
      EXPECT_EQ(narrow.stats.keys, wide.stats.keys) << bits;
      EXPECT_EQ(narrow.image.pixels, wide.image.pixels) << bits << " bits, zoom " << zoom;
      EXPECT_EQ(narrow.depth_complexity, wide.depth_complexity) << bits;
    }
  }
  o.key_bits = 7;
  EXPECT_THROW(renderer.render(frame_bounds(bounds, 160.0 / 120.0, 30, 20, 1.0), tf, o),
               UsageError);
}

// Vulkan promises 65,535 workgroups a dimension, which binning 10^8 segments exceeds: every pass
// dispatches rows of at most that many, the last row's spare workgroups idle. Rows of a few
// workgroups (binning, the sort, the ranges and the composite all take several rows here) give
// the same image, keys and hits as one row.
TEST(Tiles, WorkgroupsInRowsGiveTheSameBytes) {
  const LineSet lines = synth::generate(synth::parse_synth_source("synth:convection?scale=0.01"));
  const Bounds bounds = compute_bounds(lines);
  const CapsuleSegments capsules =
      build_capsule_segments(lines, 0.002f * bounds.diagonal(), lines.attributes[0].name);
  ASSERT_GT(capsules.segment_count(), 3u * 256u * 7u);  // binning: rows of 7 of 256 segments
  const TransferFunction tf = transfer_function_preset("semi");
  vk::Context ctx;
  vk::TileRenderer renderer(ctx, capsules);
  vk::TileOptions o;
  o.width = 160, o.height = 120;
  const Camera camera = frame_bounds(bounds, 160.0 / 120.0, 30, 20, 0.6);
  const vk::TileFrame one_row = renderer.render(camera, tf, o);
  ASSERT_GT(one_row.stats.keys, 3u * 4096u);  // the sort: rows of 2 of its blocks
  for (const uint32_t row : {7u, 2u}) {
    o.dispatch_row = row;
    const vk::TileFrame rows = renderer.render(camera, tf, o);
    EXPECT_EQ(rows.stats.keys, one_row.stats.keys) << row;
    EXPECT_EQ(rows.stats.hits, one_row.stats.hits) << row;
    EXPECT_EQ(rows.image.pixels, one_row.image.pixels) << row;
  }
}

// The eye at the origin looking along +z, 40 degrees high: the hand-built scenes below.
Camera looking_along_z() {
  Camera camera;
  camera.eye = {0, 0, 0}, camera.target = {0, 0, 1}, camera.up = {0, 1, 0};
  camera.fov_y_degrees = 40;
  return camera;
}

// The pixels of a size x size image of looking_along_z() at depth z: a pixel's width there, the
// image's unit right (-x here) and down, and where a pixel's centre lies (that of pixel (32, 32)
// of 64 half a pixel right of and below the image's centre).
struct PixelGrid {
  int size;
  double z, pixel;
  glm::dvec3 right, down;

  glm::dvec3 centre_of(double x, double y) const {
    const double middle = (size - 1) / 2.0;
    return glm::dvec3(0, 0, z) + (x - middle) * pixel * right + (y - middle) * pixel * down;
  }
};

PixelGrid pixel_grid(int size, double z) {
  const Camera::ImagePlane plane = looking_along_z().image_plane(size, size);
  return {size, z, 2 * plane.up.y * z / size, glm::normalize(plane.right),
          -glm::normalize(plane.up)};
}

// Red at attribute 0 and blue at 1, with those opacities.
TransferFunction red_to_blue(double red_opacity, double blue_opacity) {
  TransferFunction tf;
  tf.name = "two colours";
  tf.colours = {{0.0, {1, 0, 0}}, {1.0, {0, 0, 1}}};
  tf.opacities = {{0.0, red_opacity}, {1.0, blue_opacity}};
  return tf;
}

// A primitive crossing the plane of the eye has an unbounded projection. One far off to the side
// lies outside the view's pyramid, where no pixel's ray goes: it gets no key, where it had
// taken every tile (a fly-through of clouds at 1920x1080: 65.8 million keys, 72 s a frame on
// lavapipe). The image is the same as without it, in both geometries. A capsule that comes
// from beside the eye into the view is cut to its part near the view: every pixel's front hits
// are still Embree's.
TEST(Tiles, PrimitivesBesideTheEyeOutsideTheViewGetNoKeys) {
  LineSet seen, beside;
  for (LineSet* lines : {&seen, &beside}) {
    lines->append_point(-0.5f, 0, 3), lines->append_point(0.5f, 0.2f, 5), lines->end_line();
    lines->attributes = {{"v", {0, 1}}};
  }
  // Across the eye's plane 10 to the side, and 8 above (the view is 40 degrees high).
  for (const float side : {-10.0f, 10.0f}) {
    beside.append_point(side, 0, -1), beside.append_point(side, 0.1f, 1), beside.end_line();
  }
  beside.append_point(0, 8, -2), beside.append_point(0.1f, 8, 2), beside.end_line();
  beside.attributes[0].values.insert(beside.attributes[0].values.end(), {0, 1, 0, 1, 0, 1});
  const Camera camera = looking_along_z();
  const TransferFunction tf = red_to_blue(0.6, 0.5);
  vk::TileOptions o;
  o.width = 96, o.height = 64;
  vk::Context ctx;
  {
    vk::TileRenderer alone(ctx, build_capsule_segments(seen, 0.1f, "v")),
        crowded(ctx, build_capsule_segments(beside, 0.1f, "v"));
    const vk::TileFrame a = alone.render(camera, tf, o), b = crowded.render(camera, tf, o);
    EXPECT_GT(a.stats.hits, 50u);
    EXPECT_EQ(b.stats.keys, a.stats.keys);
    EXPECT_EQ(b.image.pixels, a.image.pixels);
  }
  {
    TubeOptions tube;
    tube.radius = 0.1f, tube.radius_absolute = true, tube.attribute = "v";
    vk::TileRenderer alone(ctx, build_tubes(seen, tube)), crowded(ctx, build_tubes(beside, tube));
    const vk::TileFrame a = alone.render(camera, tf, o), b = crowded.render(camera, tf, o);
    EXPECT_GT(a.stats.hits, 50u);
    EXPECT_EQ(b.stats.keys, a.stats.keys);
    EXPECT_EQ(b.image.pixels, a.image.pixels);
  }
  // From 6 to the left and 2 behind the eye to the middle of the view, 6 in front: cut where it
  // enters reach of the view's left plane (it had taken all 24 tiles).
  LineSet entering = beside;
  entering.append_point(-6, 0.3f, -2), entering.append_point(0.3f, -0.2f, 6), entering.end_line();
  entering.attributes[0].values.insert(entering.attributes[0].values.end(), {0, 1});
  const float radius = 0.1f;
  vk::TileRenderer renderer(ctx, build_capsule_segments(entering, radius, "v"));
  const vk::TileFrame frame = renderer.render(camera, tf, o);
  EmbreeOptions embree;
  embree.geometry = EmbreeGeometry::Capsules;
  const EmbreeScene scene = EmbreeScene::from_lines(entering, radius, "v", embree);
  size_t differing = 0, hit_pixels = 0;
  for (int y = 0; y < o.height; ++y)
    for (int x = 0; x < o.width; ++x) {
      const size_t expected =
          trace_hits(scene, camera.eye, camera.ray_direction(x, y, o.width, o.height)).size();
      hit_pixels += expected > 0;
      differing += frame.depth_complexity[size_t(y) * o.width + x] != expected;
    }
  EXPECT_GT(hit_pixels, 300u);
  EXPECT_LE(differing, 2u);  // float against Embree's double at a silhouette, at most
  EXPECT_LT(frame.stats.keys, 24u + 6u);
}

// Two capsules whose depth keys misorder them at one pixel: A starts nearer (its key sorts
// first) but runs away from the eye, and at the pixel through B it lies behind B. Ambient light
// only, so each hit's colour is the transfer function's: the pixel must be B over A over the
// background, composited by hand.
TEST(Tiles, CrossingCapsulesCompositeInExactOrder) {
  LineSet lines;
  lines.append_point(-3, 0, 2), lines.append_point(3, 0, 14), lines.end_line();       // A
  lines.append_point(0.5f, -1, 4), lines.append_point(0.5f, 1, 4), lines.end_line();  // B
  lines.attributes = {{"v", {0, 0, 1, 1}}};
  const CapsuleSegments capsules = build_capsule_segments(lines, 0.1f, "v");
  const Camera camera = looking_along_z();
  const TransferFunction tf = red_to_blue(0.6, 0.5);  // A red, B blue
  vk::TileOptions o;
  o.width = 64, o.height = 63;  // row 31's rays lie in the plane y = 0, through both axes
  o.shading.ambient = 1, o.shading.diffuse = 0, o.shading.specular = 0;
  o.shading.background = {0.2, 0.3, 0.4};
  // The pixel whose ray meets B's axis (x = 0.5 at depth 4).
  const Camera::ImagePlane plane = camera.image_plane(o.width, o.height);
  const int x = int(std::floor((0.125 / plane.right.x + 1) / 2 * o.width));
  const int y = 31;
  vk::Context ctx;
  vk::TileRenderer renderer(ctx, capsules);
  const vk::TileFrame frame = renderer.render(camera, tf, o);
  EXPECT_EQ(frame.stats.window_overflows, 0u);
  ASSERT_EQ(frame.depth_complexity[size_t(y) * o.width + x], 2u);
  const Rgba a = tf.at(0), b = tf.at(1);
  const std::array<double, 3> ca{a.r, a.g, a.b}, cb{b.r, b.g, b.b};
  for (int c = 0; c < 3; ++c) {
    const double expected = b.a * cb[c] + (1 - b.a) * a.a * ca[c] +
                            (1 - b.a) * (1 - a.a) * o.shading.background[size_t(c)];
    const double misordered = a.a * ca[c] + (1 - a.a) * b.a * cb[c] +
                              (1 - a.a) * (1 - b.a) * o.shading.background[size_t(c)];
    EXPECT_NEAR(frame.image.at(x, y, c), expected, 1e-5) << "channel " << c;
    if (c != 1) {
      EXPECT_GT(std::abs(expected - misordered), 0.05) << "channel " << c;
    }
  }
}

// A pixel's ray passes through its centre, so a capsule whose image lies between pixel centres
// is hit by no ray and binning emits no key for it; one around a centre gets one key and one
// hit. 64x64 pixels, the capsule a fifth of a pixel long and a tenth of a pixel in radius at
// depth 4: first around the corner shared by pixels (31, 31) to (32, 32), which is also the
// corner of four tiles (the older bounds, a pixel wider, binned it into all four), then around
// the centre of pixel (32, 32).
TEST(Tiles, ACapsuleBetweenPixelCentresHasNoKey) {
  const Camera camera = looking_along_z();
  const int size = 64;
  const PixelGrid grid = pixel_grid(size, 4);
  vk::TileOptions o;
  o.width = size, o.height = size;
  vk::Context ctx;
  for (const bool on_centre : {false, true}) {
    const double at = on_centre ? 32 : 31.5;
    const glm::dvec3 centre = grid.centre_of(at, at);
    const glm::dvec3 along = 0.1 * grid.pixel * grid.right;
    LineSet lines;
    for (const glm::dvec3 p : {centre - along, centre + along})
      lines.append_point(float(p.x), float(p.y), float(p.z));
    lines.end_line();
    lines.attributes = {{"v", {0.5f, 0.5f}}};
    vk::TileRenderer renderer(ctx, build_capsule_segments(lines, float(0.1 * grid.pixel), "v"));
    const vk::TileFrame frame = renderer.render(camera, red_to_blue(0.5, 0.5), o);
    EXPECT_EQ(frame.stats.keys, on_centre ? 1u : 0u) << "on centre " << on_centre;
    EXPECT_EQ(frame.stats.hits, on_centre ? 1u : 0u) << "on centre " << on_centre;
    if (on_centre) {
      EXPECT_EQ(frame.depth_complexity[32 * size + 32], 1u);
    }
  }
}

// One frame rendered with binning's pixel tests off (all) and on (tested, 4 pixels).
struct TestedAndAll {
  vk::TileFrame all, tested;
};
TestedAndAll render_tested_and_all(vk::TileRenderer& renderer, const Camera& camera,
                                   const TransferFunction& tf, int width, int height) {
  vk::TileOptions o;
  o.width = width, o.height = height;
  o.tested_pixels = 0;
  TestedAndAll frames{renderer.render(camera, tf, o), {}};
  o.tested_pixels = 4;
  frames.tested = renderer.render(camera, tf, o);
  return frames;
}

// The tests leave out only keys without a hit: the same hits, bytes and depth complexity.
void expect_the_same_frame(const TestedAndAll& f, const std::string& what) {
  EXPECT_EQ(f.tested.stats.hits, f.all.stats.hits) << what;
  EXPECT_EQ(f.tested.image.pixels, f.all.image.pixels) << what;
  EXPECT_EQ(f.tested.depth_complexity, f.all.depth_complexity) << what;
}

// A straight chain of 8 capsules, each an eighth of a pixel long and 0.15 pixel in radius, whose
// middle (the middle of segment 3) lies on the centre of pixel (32, 32). Every segment's bounds
// (1.25 radii and a sixteenth of a pixel wide, tiles_capsules.glsl) hold only that pixel's
// centre or none: segments 1 to 5 hold it (5 keys with no pixel tested). Its ray, nearly
// perpendicular to the chain, comes within a radius of segments 2, 3 and 4 only, and meets
// segments 2 and 4 only inside segment 3's capsule (where they enter it, 0.42 radii along the
// axis from the ray, they lie 0.09 radii inside it): with pixels tested, segment 3 alone gets a
// key. One hit either way, on segment 3, the same bytes.
TEST(Tiles, ShortCapsulesGetKeysOnlyWhereAPixelMayCrossTheirSurface) {
  const Camera camera = looking_along_z();
  const int size = 64;
  const PixelGrid grid = pixel_grid(size, 4);
  const glm::dvec3 centre = grid.centre_of(32, 32);
  const double pixel = grid.pixel;
  LineSet lines;
  for (int k = 0; k <= 8; ++k) {
    const glm::dvec3 p = centre + (k - 3.5) / 8 * pixel * grid.right;
    lines.append_point(float(p.x), float(p.y), float(p.z));
  }
  lines.end_line();
  lines.attributes = {{"v", std::vector<float>(9, 0.5f)}};
  vk::Context ctx;
  vk::TileRenderer renderer(ctx, build_capsule_segments(lines, float(0.15 * pixel), "v"));
  const TestedAndAll f = render_tested_and_all(renderer, camera, red_to_blue(0.5, 0.5), size, size);
  EXPECT_EQ(f.all.stats.keys, 5u);
  EXPECT_EQ(f.tested.stats.keys, 1u);
  EXPECT_EQ(f.all.stats.hits, 1u);
  EXPECT_EQ(f.tested.depth_complexity[32 * size + 32], 1u);
  expect_the_same_frame(f, "capsules");
}

// Two right triangles smaller than a pixel facing the eye, each with one pixel centre inside its
// bounds. In pixels from that centre (x right, y down), the first has its corners at (-0.45,
// -0.45), (0.2, -0.45) and (-0.45, 0.2): its hypotenuse, x + y = -0.25, passes 0.18 pixels short
// of the centre, more than binning's margin of a sixteenth. The second, at (-0.2, -0.2), (0.45,
// -0.2) and (-0.2, 0.45), holds its centre 0.18 pixels inside. With pixels tested only the second
// gets a key; one hit either way, on its pixel.
TEST(Tiles, SmallTrianglesGetKeysOnlyWhereTheyHoldAPixelCentre) {
  const Camera camera = looking_along_z();
  const int size = 64;
  const PixelGrid grid = pixel_grid(size, 4);
  const double pixel = grid.pixel;
  const glm::dvec3 right = grid.right, down = grid.down;
  TubeChunk chunk;
  std::vector<glm::dvec3> corners;
  const auto add_triangle = [&](glm::dvec3 centre, double leg, double tip) {
    glm::dvec3 a = centre + pixel * (leg * right + leg * down);
    glm::dvec3 b = centre + pixel * (tip * right + leg * down);
    glm::dvec3 c = centre + pixel * (leg * right + tip * down);
    // Facing the eye: counter-clockwise seen from it, the normal towards -z.
    if (glm::cross(b - a, c - a).z > 0) std::swap(b, c);
    corners.insert(corners.end(), {a, b, c});
  };
  add_triangle(grid.centre_of(32, 32), -0.45, 0.2);  // misses its centre
  add_triangle(grid.centre_of(40, 32), -0.2, 0.45);  // holds its centre
  chunk.line_count = 2;
  chunk.positions = Array<float>(corners.size() * 3);
  chunk.normals = Array<float>(corners.size() * 3);
  chunk.indices = Array<uint32_t>(corners.size());
  for (size_t v = 0; v < corners.size(); ++v) {
    for (int k = 0; k < 3; ++k) chunk.positions[3 * v + k] = float(corners[v][k]);
    chunk.normals[3 * v] = 0, chunk.normals[3 * v + 1] = 0, chunk.normals[3 * v + 2] = -1;
    chunk.indices[v] = uint32_t(v);
  }
  TubeMesh mesh;
  mesh.chunks.push_back(std::move(chunk));
  vk::Context ctx;
  vk::TileRenderer renderer(ctx, mesh);
  const TestedAndAll f = render_tested_and_all(renderer, camera, red_to_blue(0.5, 0.5), size, size);
  EXPECT_EQ(f.all.stats.keys, 2u);
  EXPECT_EQ(f.tested.stats.keys, 1u);
  EXPECT_EQ(f.all.stats.hits, 1u);
  EXPECT_EQ(f.tested.depth_complexity[32 * size + 40], 1u);
  expect_the_same_frame(f, "triangles");
}

// Two frames of one scene alike to the byte: image, depth complexity, hits, walks, overflows.
void expect_same_tile_frame(const vk::TileFrame& a, const vk::TileFrame& b,
                            const std::string& where) {
  EXPECT_EQ(a.image.pixels, b.image.pixels) << where;
  EXPECT_EQ(a.depth_complexity, b.depth_complexity) << where;
  EXPECT_EQ(a.stats.hits, b.stats.hits) << where;
  EXPECT_EQ(a.stats.walks, b.stats.walks) << where;
  EXPECT_EQ(a.stats.window_overflows, b.stats.window_overflows) << where;
}

// The composite's workgroups take the crowded tiles first; in raster order the image, hits and
// walks are the same: each workgroup writes its own tile, whatever the order they run.
// The aneurysm seen from afar, so that its few central tiles are crowded (more than 8 times the
// mean keys), in slices and with walks again, as capsules and as triangles, on any device.
TEST(Tiles, TheOrderOfTheTilesChangesNoByte) {
  vk::Context ctx;
  const TransferFunction tf = transfer_function_preset("transparent");
  const LineSet lines = synth::generate(synth::parse_synth_source("synth:aneurysm?scale=0.01"));
  const Bounds bounds = compute_bounds(lines);
  const Camera camera = frame_bounds(bounds, 160.0 / 120.0, 30, 20, 2.5);
  const auto expect_same = [&](vk::TileRenderer& renderer, const char* what) {
    vk::TileOptions o;
    o.width = 160, o.height = 120;
    const vk::TileFrame first = renderer.render(camera, tf, o);
    o.most_keys_first = false;
    const vk::TileFrame raster = renderer.render(camera, tf, o);
    EXPECT_GT(first.stats.slices, 1u) << what;
    EXPECT_GT(first.stats.crowded_tiles, 0u) << what;
    EXPECT_EQ(raster.stats.crowded_tiles, 0u) << what;
    EXPECT_GT(first.stats.walks, 1u) << what;
    expect_same_tile_frame(first, raster, what);
  };
  // Slices of 64 keys, with the 8-hit window of the loops of fixed trips (lavapipe's; a GPU's
  // 16 and 64 hold these pixels' hits in one walk).
  vk::TileRenderer capsules(
      ctx, build_capsule_segments(lines, 0.004f * bounds.diagonal(), lines.attributes[0].name), 0,
      64, true, vk::WindowLoops::fixed);
  expect_same(capsules, "capsules");
  TubeOptions tube;
  tube.radius = 0.004f;
  vk::TileRenderer triangles(ctx, build_tubes(lines, tube), 0, 64, true, vk::WindowLoops::fixed);
  expect_same(triangles, "triangles");
}

// The aneurysm framed a little closer than whole in an image whose last row and column of tiles
// are cut (150x108: the last column's strips hold 6 of their 16 columns of pixels, the last
// row's fourth strip no pixel), as capsules and as triangles, each composited with the loops of
// fixed trips in slices of 64 keys and with the loops that exit in one slice (walks again with
// the deep window): `check(renderer, camera, what)` for each of the four, each of which walks
// tiles again here (the triangles' tubes are thicker than the capsules, so that a pixel fills
// even the 16-hit window and its tile takes the deep window's walk again; with the capsules'
// radius none did).
using CompositeCheck = std::function<void(vk::TileRenderer&, const Camera&, const std::string&)>;
void for_each_composite_build(const CompositeCheck& check) {
  vk::Context ctx;
  const LineSet lines = synth::generate(synth::parse_synth_source("synth:aneurysm?scale=0.01"));
  const Bounds bounds = compute_bounds(lines);
  const Camera camera = frame_bounds(bounds, 150.0 / 108.0, 30, 20, 0.85);
  const CapsuleSegments capsules =
      build_capsule_segments(lines, 0.004f * bounds.diagonal(), lines.attributes[0].name);
  TubeOptions tube;
  tube.radius = 0.01f;
  const TubeMesh mesh = build_tubes(lines, tube);
  for (const bool exits : {false, true}) {
    const vk::WindowLoops loops = exits ? vk::WindowLoops::exits : vk::WindowLoops::fixed;
    const uint32_t slice_keys = exits ? 0 : 64;
    const std::string how = exits ? ", window loops that exit" : ", slices of 64 keys";
    vk::TileRenderer over_capsules(ctx, capsules, 0, slice_keys, true, loops);
    check(over_capsules, camera, "capsules" + how);
    vk::TileRenderer over_triangles(ctx, mesh, 0, slice_keys, true, loops);
    check(over_triangles, camera, "triangles" + how);
  }
}

// Four workgroups a tile, each over a strip of 16x4 pixels, composite the same pixels with the
// same hits in the same order as one workgroup a tile: the same bytes, hits, walks and
// overflows, for every tile in strips and for the crowded ones only (beside the others' one
// workgroup each, in the same slice), in every build of for_each_composite_build.
TEST(Tiles, StripsOfATileGiveTheSameBytes) {
  const TransferFunction tf = transfer_function_preset("transparent");
  for_each_composite_build(
      [&](vk::TileRenderer& renderer, const Camera& camera, const std::string& what) {
        vk::TileOptions o;
        o.width = 150, o.height = 108;
        // A frame first, so that both below find the pixels' states' buffer made (the first walk
        // that needs it composites its tiles again: more workgroups).
        renderer.render(camera, tf, o);
        const vk::TileFrame whole = renderer.render(camera, tf, o);
        EXPECT_GE(whole.stats.walks, 2u) << what;
        EXPECT_GT(whole.stats.hits, 5000u) << what;
        EXPECT_GT(whole.stats.crowded_tiles, 0u) << what;
        // Every tile in strips; then only the crowded (no walk counts as few), the two composites
        // dispatched together in each slice.
        o.strips = vk::TileStrips::all;
        const vk::TileFrame all = renderer.render(camera, tf, o);
        o.strips = vk::TileStrips::crowded, o.few_tiles = 0;
        const vk::TileFrame crowded = renderer.render(camera, tf, o);
        EXPECT_EQ(all.stats.composite_workgroups, 4 * whole.stats.composite_workgroups) << what;
        EXPECT_GT(crowded.stats.composite_workgroups, whole.stats.composite_workgroups) << what;
        EXPECT_LT(crowded.stats.composite_workgroups, all.stats.composite_workgroups) << what;
        expect_same_tile_frame(whole, all, what + ", strips: all");
        expect_same_tile_frame(whole, crowded, what + ", strips: crowded");
      });
}

// Each pixel computing its own hits (TileOptions::pixel_hits) takes the same hits in the same
// order as the workgroup's rounds of pairs, and shading a hit late (TileOptions::late_shading),
// when it is composited, tests its primitive again and gives the colour the rounds gave it: the
// same bytes, hits, walks and overflows for each of the four, in every build of
// for_each_composite_build. Neither is built for strips: a usage error.
TEST(Tiles, PixelHitsAndLateShadingGiveTheSameBytes) {
  const TransferFunction tf = transfer_function_preset("transparent");
  for_each_composite_build(
      [&](vk::TileRenderer& renderer, const Camera& camera, const std::string& what) {
        vk::TileOptions o;
        o.width = 150, o.height = 108;
        renderer.render(camera, tf, o);  // the pixels' states' buffer made, as in the strips test
        const vk::TileFrame pairs = renderer.render(camera, tf, o);
        EXPECT_GE(pairs.stats.walks, 2u) << what;
        EXPECT_GT(pairs.stats.hits, 5000u) << what;
        for (const bool own : {false, true})
          for (const bool late : {false, true}) {
            if (!own && !late) continue;
            o.pixel_hits = own, o.late_shading = late, o.strips = vk::TileStrips::none;
            const std::string which =
                std::string(own ? ", pixel hits" : "") + (late ? ", late shading" : "");
            const vk::TileFrame f = renderer.render(camera, tf, o);
            expect_same_tile_frame(pairs, f, what + which);
            EXPECT_EQ(f.stats.late_misses, 0u) << what + which;
            o.strips = vk::TileStrips::crowded;
            EXPECT_THROW(renderer.render(camera, tf, o), UsageError) << what + which;
          }
      });
}

// Binning's pixel tests leave out only keys without a hit: on sets of many short segments
// (clouds: most shorter than the radius; convection) seen whole and zoomed in, and on tube
// meshes, fewer keys and the same bytes, hits and depth complexity as binning by the bounds
// alone.
TEST(Tiles, TestedPixelsLeaveOutKeysWithoutChangingAByte) {
  vk::Context ctx;
  const TransferFunction tf = transfer_function_preset("semi");
  const auto expect_fewer_keys = [&](vk::TileRenderer& renderer, const Bounds& bounds,
                                     const std::string& what) {
    for (const double zoom : {1.0, 0.4}) {
      const Camera camera = frame_bounds(bounds, 160.0 / 120.0, 30, 20, zoom);
      const TestedAndAll f = render_tested_and_all(renderer, camera, tf, 160, 120);
      const std::string where = what + ", zoom " + std::to_string(zoom);
      EXPECT_GT(f.all.stats.hits, 1000u) << where;
      EXPECT_LT(f.tested.stats.keys, f.all.stats.keys) << where;
      expect_the_same_frame(f, where);
    }
  };
  for (const char* source : {"synth:clouds?scale=0.01", "synth:convection?scale=0.01"}) {
    const LineSet lines = synth::generate(synth::parse_synth_source(source));
    const Bounds bounds = compute_bounds(lines);
    vk::TileRenderer capsules(
        ctx, build_capsule_segments(lines, 0.002f * bounds.diagonal(), lines.attributes[0].name));
    expect_fewer_keys(capsules, bounds, std::string(source) + " capsules");
  }
  // The tube mesh's triangles, most smaller than a pixel here.
  for (const char* source : {"synth:aneurysm?scale=0.01", "synth:convection?scale=0.01"}) {
    const LineSet lines = synth::generate(synth::parse_synth_source(source));
    vk::TileRenderer triangles(ctx, build_tubes(lines, TubeOptions{}));
    expect_fewer_keys(triangles, compute_bounds(lines), std::string(source) + " triangles");
  }
}

// Eight points of one line of synth:clouds?scale=0.1 (segments 781729 to 781735), each segment
// about 1/80 of the radius long, and the ray of pixel (280, 220) of frame 5 of an 8-frame
// flight at 640x360: in float the ray crosses four consecutive capsules within 4e-5 of each
// other at the front of the line, a chain of seam twins. Embree's capsules (double) report one
// crossing. Each crossing with a twin just before it is a seam double, whatever the order the
// keys bring them in: one hit for every key width (keeping the nearer of two twins, with the
// farther dropped from the window, kept two).
TEST(Tiles, AChainOfSeamTwinsIsCompositedOnce) {
  const float points[][3] = {
      {20.0410519f, 14.9489193f, 0.00351820444f}, {20.0403748f, 14.9491701f, 0.00353275915f},
      {20.0396957f, 14.9494228f, 0.00354741421f}, {20.039011f, 14.9496784f, 0.00356217194f},
      {20.0383224f, 14.9499359f, 0.00357703492f}, {20.0376282f, 14.9501963f, 0.00359200547f},
      {20.036932f, 14.9504595f, 0.00360708637f},  {20.0362301f, 14.9507246f, 0.00362228067f}};
  LineSet lines;
  for (const auto& p : points) lines.append_point(p[0], p[1], p[2]);
  lines.end_line();
  lines.attributes = {{"v", std::vector<float>(8, 0.5f)}};
  const float radius = 0.0558400527f;
  // The pixel's ray as the centre of a 15x15 image.
  Camera camera;
  camera.eye = {-25.8410982, 42.3840757, -38.5412282};
  camera.target = camera.eye + 60.0 * glm::dvec3(0.696592094, -0.416259954, 0.58436898);
  camera.up = {0, 1, 0};
  camera.fov_y_degrees = 1;
  const int size = 15, centre = 7 * size + 7;
  EmbreeOptions embree;
  embree.geometry = EmbreeGeometry::Capsules;
  const EmbreeScene scene = EmbreeScene::from_lines(lines, radius, "v", embree);
  const size_t expected =
      trace_hits(scene, camera.eye, camera.ray_direction(7, 7, size, size)).size();
  EXPECT_EQ(expected, 1u);
  vk::Context ctx;
  vk::TileRenderer renderer(ctx, build_capsule_segments(lines, radius, "v"));
  std::optional<Image> first;
  for (const uint32_t bits : {12u, 16u, 24u, 32u}) {
    vk::TileOptions o;
    o.width = o.height = size;
    o.key_bits = bits;
    const vk::TileFrame frame = renderer.render(camera, red_to_blue(0.5, 0.5), o);
    EXPECT_EQ(frame.depth_complexity[centre], expected) << bits << "-bit keys";
    if (!first) first = frame.image;
    EXPECT_EQ(frame.image.pixels, first->pixels) << bits << "-bit keys";
  }
}

// A stack of short lines across the view axis, each a capsule a little behind the last: the
// centre pixel's ray meets every one (one front hit each), and so the composite of its tile
// runs far past lavapipe's 65535 loop iterations an invocation when given all keys at once.
CapsuleSegments stacked_capsules(int count) {
  LineSet lines;
  for (int k = 0; k < count; ++k) {
    const float z = 2.0f + 0.01f * float(k);
    lines.append_point(-0.05f, 0, z), lines.append_point(0.05f, 0, z), lines.end_line();
  }
  lines.attributes = {{"v", std::vector<float>(size_t(2 * count), 0.5f)}};
  return build_capsule_segments(lines, 0.004f, "v");
}

// Slices given all keys of a tile at once (as on GPUs without a loop limit) give the same bytes
// as small ones, because an invocation cut short is found (a sentinel loop that runs short) and
// its band composited again in smaller slices.
TEST(Tiles, AnInvocationCutShortIsRenderedAgainInSmallerSlices) {
  const int count = 20000;
  const CapsuleSegments capsules = stacked_capsules(count);
  const Camera camera = looking_along_z();
  const TransferFunction tf = transfer_function_preset("transparent");
  vk::TileOptions o;
  o.width = 33, o.height = 33;
  vk::Context ctx;
  vk::TileRenderer whole(ctx, capsules, 0, 1u << 20), fine(ctx, capsules, 0, 64);
  const vk::TileFrame a = whole.render(camera, tf, o), b = fine.render(camera, tf, o);
  const size_t centre = size_t(16) * o.width + 16;
  EXPECT_EQ(b.depth_complexity[centre], uint32_t(count));
  EXPECT_EQ(a.depth_complexity[centre], uint32_t(count));
  EXPECT_EQ(a.image.pixels, b.image.pixels);
  EXPECT_EQ(a.depth_complexity, b.depth_complexity);
  if (ctx.info().lavapipe) {
    // All 20,000 keys of a tile in one slice pass the limit there: found, and sliced again.
    EXPECT_GT(a.stats.resliced, 0u);
    EXPECT_GT(a.stats.slices, 1u);
  }
}

// Forty long capsules that all start near the eye and cross the view axis one behind the other
// (at depths 4, 4.5, ... 23.5), those that start nearer crossing farther: every key's depth bound
// lies before the first hit, and the hits arrive far to near, so the centre pixel's window (8
// hits with the loops of fixed trips, 16 where they exit) fills before any hit may be
// composited. Compositing the window's nearest early would misorder them; instead the tile is
// walked again for the hits past the window (five walks of 8 hits with the loops of fixed
// trips), and the pixel must be the forty colours composited front to back by hand,
// whatever the slice size. (The near half is red, the far half blue: compositing the window's
// nearest early would put blue hits before red ones.)
// `clutter` short capsules (value 0.5) come first in the tile of the centre pixel: nearer than
// every long capsule's start, and off the centre pixel's ray (test below).
CapsuleSegments long_capsules_far_to_near(int count, int clutter = 0) {
  LineSet lines;
  std::vector<float> values;
  const Camera::ImagePlane plane = looking_along_z().image_plane(33, 33);
  for (int k = 0; k < clutter; ++k) {
    // Around the pixels (20..31, 20..31) of the 33x33 image, at view depths 1 to 1.4, sparse
    // enough that no pixel of theirs keeps 8 hits pending: each capsule's screen bounds reach into
    // the centre pixel's tile (pixels 16..31).
    const double z = 1.0 + 0.4 * k / clutter;
    const double px = 20 + k % 12, py = 20 + (k / 12) % 12;
    const double nx = (px + 0.5) / 33 * 2 - 1, ny = (py + 0.5) / 33 * 2 - 1;
    const glm::dvec3 p = z * (plane.forward + nx * plane.right - ny * plane.up);
    lines.append_point(float(p.x), float(p.y), float(p.z));
    lines.append_point(float(p.x) + 0.01f, float(p.y), float(p.z));
    lines.end_line();
    values.insert(values.end(), 2, 0.5f);
  }
  for (int k = 0; k < count; ++k) {
    const float angle = 2.39996f * float(k);  // golden angle: the starts spread around the axis
    const float depth = 4.0f + 0.5f * float(count - 1 - k);
    const glm::vec3 start(std::cos(angle), std::sin(angle), 1.5f + 0.01f * float(k));
    const glm::vec3 end = 2.0f * glm::vec3(0, 0, depth) - start;
    lines.append_point(start.x, start.y, start.z), lines.append_point(end.x, end.y, end.z);
    lines.end_line();
    values.insert(values.end(), 2, k < count / 2 ? 1.0f : 0.0f);  // the far half blue
  }
  lines.attributes = {{"v", values}};
  return build_capsule_segments(lines, 0.05f, "v");
}

// The centre pixel of long_capsules_far_to_near: the `count` colours composited front to back
// by hand (ambient light only), over the background.
std::array<double, 3> far_to_near_centre(const TransferFunction& tf, int count,
                                         const std::array<double, 3>& background) {
  std::array<double, 3> colour{};
  double alpha = 0;
  for (int k = count - 1; k >= 0; --k) {  // nearest first
    const Rgba c = tf.at(k < count / 2 ? 1.0 : 0.0);
    const std::array<double, 3> rgb{c.r, c.g, c.b};
    for (int i = 0; i < 3; ++i) colour[size_t(i)] += (1 - alpha) * c.a * rgb[size_t(i)];
    alpha += (1 - alpha) * c.a;
  }
  for (int i = 0; i < 3; ++i) colour[size_t(i)] += (1 - alpha) * background[size_t(i)];
  return colour;
}

// The options of the tests below: 33x33 (the centre pixel's ray is the view axis), ambient light
// only (each hit's colour is the transfer function's), a coloured background.
vk::TileOptions far_to_near_options() {
  vk::TileOptions o;
  o.width = 33, o.height = 33;
  o.shading.ambient = 1, o.shading.diffuse = 0, o.shading.specular = 0;
  o.shading.background = {0.2, 0.3, 0.4};
  return o;
}

TEST(Tiles, AFullWindowIsWalkedAgainAndStaysExact) {
  const int count = 40;
  const CapsuleSegments capsules = long_capsules_far_to_near(count);
  const Camera camera = looking_along_z();
  const TransferFunction tf = red_to_blue(0.15, 0.1);
  const vk::TileOptions o = far_to_near_options();
  vk::Context ctx;
  // Loops of fixed trips: the build whose loops exit walks again with a deeper window on GPUs
  // (two walks here; Tiles.WindowLoopsThatExitEarlyGiveTheSameBytes).
  const auto fixed = vk::WindowLoops::fixed;
  vk::TileRenderer whole(ctx, capsules, 0, 1u << 20, true, fixed);
  vk::TileRenderer fine(ctx, capsules, 0, 8, true, fixed);
  const vk::TileFrame a = whole.render(camera, tf, o), b = fine.render(camera, tf, o);
  const size_t centre = size_t(16) * o.width + 16;
  ASSERT_EQ(a.depth_complexity[centre], uint32_t(count));
  EXPECT_EQ(a.stats.window_overflows, 4u);
  EXPECT_EQ(a.stats.walks, 5u);
  // Per walk: the composite's time and the tiles walked (the first: all 9), then the centre
  // tile alone. A new renderer's states have no room to stay until a walk again needs them: the
  // centre tile's first walk is then redone, counted apart (it had made walk_tiles[0] 10 of 9
  // tiles, and the stats depend on whether a frame came before).
  ASSERT_EQ(a.stats.walk_tiles.size(), 5u);
  ASSERT_EQ(a.stats.walk_ms.size(), 5u);
  EXPECT_EQ(a.stats.walk_tiles[0], uint64_t(a.stats.tiles));
  for (size_t walk = 1; walk < 5; ++walk) EXPECT_EQ(a.stats.walk_tiles[walk], 1u) << walk;
  EXPECT_EQ(a.stats.redone_tiles, 1u);
  EXPECT_EQ(a.stats.max_tile_keys, uint64_t(count));
  double walks_ms = a.stats.redone_ms;
  for (double ms : a.stats.walk_ms) walks_ms += ms;
  EXPECT_NEAR(walks_ms, a.stats.composite_ms, 1e-9 * (1 + a.stats.composite_ms));
  const vk::TileFrame again = whole.render(camera, tf, o);  // the states have room now
  EXPECT_EQ(again.stats.walk_tiles, a.stats.walk_tiles);
  EXPECT_EQ(again.stats.redone_tiles, 0u);
  EXPECT_EQ(again.image.pixels, a.image.pixels);
  // A frame with no key: no tile holds one.
  Camera away = camera;
  away.target = {0, 0, -1};
  const vk::TileFrame empty = whole.render(away, tf, o);
  EXPECT_EQ(empty.stats.keys, 0u);
  EXPECT_EQ(empty.stats.max_tile_keys, 0u);
  const std::array<double, 3> expected = far_to_near_centre(tf, count, o.shading.background);
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(a.image.at(16, 16, i), expected[size_t(i)], 1e-5) << "channel " << i;
  EXPECT_EQ(a.image.pixels, b.image.pixels);
  EXPECT_EQ(a.depth_complexity, b.depth_complexity);
  EXPECT_EQ(b.stats.walks, 5u);
}

// The forty capsules above behind 300 short ones nearer than any of them, in the centre pixel's
// tile but off its ray: that tile's first 256 keys (a chunk) end before the hits the centre
// pixel leaves for another walk, so each walk again starts past them (1,024 keys in the four
// walks again of the 8-hit window, 256 in the one of the 64-hit window where loops exit).
// Slices of 8 keys record no chunk's far depth (a batch is a whole chunk or tells nothing), so
// their walks pass every key: the same bytes, and the centre pixel still the forty colours
// composited by hand.
TEST(Tiles, WalksAgainStartPastTheKeysTheirPixelsAreDoneWith) {
  const int count = 40, clutter = 300;
  const CapsuleSegments capsules = long_capsules_far_to_near(count, clutter);
  const TransferFunction tf = red_to_blue(0.15, 0.1);
  const vk::TileOptions o = far_to_near_options();
  vk::Context ctx;
  const auto fixed = vk::WindowLoops::fixed;
  vk::TileRenderer whole(ctx, capsules, 0, 1u << 20, true, fixed);
  vk::TileRenderer fine(ctx, capsules, 0, 8, true, fixed);
  vk::TileRenderer exits(ctx, capsules, 0, 1u << 20, true, vk::WindowLoops::exits);
  const vk::TileFrame a = whole.render(looking_along_z(), tf, o);
  const vk::TileFrame b = fine.render(looking_along_z(), tf, o);
  const vk::TileFrame c = exits.render(looking_along_z(), tf, o);
  const size_t centre = size_t(16) * o.width + 16;
  ASSERT_EQ(a.depth_complexity[centre], uint32_t(count));
  EXPECT_EQ(a.stats.max_tile_keys, uint64_t(count + clutter));
  EXPECT_EQ(a.stats.walks, 5u);
  EXPECT_EQ(a.stats.window_overflows, 4u);  // the centre pixel's alone
  EXPECT_EQ(a.stats.walk_skipped_keys, 1024u);
  EXPECT_EQ(b.stats.walks, 5u);
  EXPECT_EQ(b.stats.walk_skipped_keys, 0u);
  EXPECT_EQ(c.stats.walks, 2u);
  EXPECT_EQ(c.stats.walk_skipped_keys, 256u);
  const std::array<double, 3> expected = far_to_near_centre(tf, count, o.shading.background);
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(a.image.at(16, 16, i), expected[size_t(i)], 1e-5) << "channel " << i;
  EXPECT_GT(a.stats.hits, uint64_t(clutter));  // the clutter is on screen
  EXPECT_EQ(a.image.pixels, b.image.pixels);
  EXPECT_EQ(a.depth_complexity, b.depth_complexity);
  EXPECT_EQ(a.image.pixels, c.image.pixels);
  EXPECT_EQ(a.depth_complexity, c.depth_complexity);
}

// The composite's window loops that leave past the pending hits (the pipeline of GPUs) and
// those of fixed trips (lavapipe's): the same bytes and hits over capsules and the tube mesh,
// and with a window that overflows (the forty capsules of the test above), where the build that
// exits walks again with its 64-hit window: all 24 hits left after its first walk (of 16) in one
// walk more, where the 8-hit window of fixed trips takes four walks after its first. Where the
// device has 64-bit integers (lavapipe), the capsules' build of fixed trips also reads their ends
// as 64-bit words (tiles_composite.comp): the two layouts give the same bytes too.
TEST(Tiles, WindowLoopsThatExitEarlyGiveTheSameBytes) {
  vk::Context ctx;
  {
    const CapsuleSegments capsules = long_capsules_far_to_near(40);
    vk::TileOptions o;
    o.width = 33, o.height = 33;
    const TransferFunction tf = transfer_function_preset("semi");
    vk::TileRenderer fixed(ctx, capsules, 0, 0, true, vk::WindowLoops::fixed);
    vk::TileRenderer exits(ctx, capsules, 0, 0, true, vk::WindowLoops::exits);
    const vk::TileFrame a = fixed.render(looking_along_z(), tf, o);
    const vk::TileFrame b = exits.render(looking_along_z(), tf, o);
    EXPECT_EQ(a.stats.walks, 5u);
    EXPECT_EQ(b.stats.walks, 2u);
    EXPECT_EQ(a.stats.window_overflows, 4u);
    EXPECT_EQ(b.stats.window_overflows, 1u);
    EXPECT_EQ(a.image.pixels, b.image.pixels);
    EXPECT_EQ(a.depth_complexity, b.depth_complexity);
  }
  const LineSet lines = synth::generate(synth::parse_synth_source("synth:aneurysm?scale=0.005"));
  const Bounds bounds = compute_bounds(lines);
  const CapsuleSegments capsules =
      build_capsule_segments(lines, 0.004f * bounds.diagonal(), lines.attributes[0].name);
  TubeOptions tube;
  tube.radius = 0.004f;  // of the diagonal, as the capsules'
  const TubeMesh mesh = build_tubes(lines, tube);
  const Camera camera = frame_bounds(bounds, 1.0, 30, 20, 0.7);
  vk::TileOptions o;
  o.width = 96, o.height = 96;
  // Capsules, then the tube mesh's triangles.
  const auto expect_same = [&](const auto& primitives, const char* what) {
    for (const char* preset : {"semi", "transparent"}) {
      const TransferFunction tf = transfer_function_preset(preset);
      vk::TileRenderer fixed(ctx, primitives, 0, 0, true, vk::WindowLoops::fixed);
      vk::TileRenderer exits(ctx, primitives, 0, 0, true, vk::WindowLoops::exits);
      const vk::TileFrame a = fixed.render(camera, tf, o), b = exits.render(camera, tf, o);
      EXPECT_GT(a.stats.hits, 1000u) << what << " " << preset;
      EXPECT_EQ(a.image.pixels, b.image.pixels) << what << " " << preset;
      EXPECT_EQ(a.depth_complexity, b.depth_complexity) << what << " " << preset;
      EXPECT_EQ(a.stats.hits, b.stats.hits) << what << " " << preset;
    }
  };
  expect_same(capsules, "capsules");
  expect_same(mesh, "triangles");
}

}  // namespace
}  // namespace linebake
