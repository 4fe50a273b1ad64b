// The CPU ray tracer against hand-computed pixels, hit bookkeeping along rays, curve/triangle
// agreement, cameras and transfer functions.

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>

#include "accel/embree_scene.hpp"
#include "core/error.hpp"
#include "core/memory_budget.hpp"
#include "render/ray_tracer.hpp"
#include "test_util.hpp"
#include "tubes/tube_builder.hpp"

namespace linebake {
namespace {

// n straight lines along x, stacked along z at z = 0, -1, -2, ...; each split into two
// segments with the joint at x = 0 (where the test rays pass). Attribute of line i: values[i].
LineSet stacked_lines(int n, const std::vector<float>& values = {}) {
  LineSet lines;
  Attribute a{"value", {}};
  for (int i = 0; i < n; ++i) {
    for (const float x : {-1.0f, 0.0f, 1.0f}) {
      lines.append_point(x, 0.0f, -float(i));
      a.values.push_back(values.empty() ? 0.0f : values[size_t(i)]);
    }
    lines.end_line();
  }
  lines.attributes.push_back(a);
  return lines;
}

// Red, green, blue at attribute 0, 0.5, 1 (exact in sRGB and linear), opacity 0.5, 0.25, 0.8.
TransferFunction rgb_tf() {
  TransferFunction tf;
  tf.name = "test";
  tf.colours = {{0.0, {1, 0, 0}}, {0.5, {0, 1, 0}}, {1.0, {0, 0, 1}}};
  tf.opacities = {{0.0, 0.5}, {0.5, 0.25}, {1.0, 0.8}};
  tf.range = {0, 1};
  return tf;
}

constexpr float kRadius = 0.2f;
const glm::dvec3 kOrigin(0.3, 0.0, 10.0), kDown(0, 0, -1);

TEST(RayTracer, ThreeOverlappingTubesMatchTheHandComputedPixel) {
  const LineSet lines = stacked_lines(3, {0.0f, 0.5f, 1.0f});
  const EmbreeScene scene = EmbreeScene::from_lines(lines, kRadius, "value", {});
  TraceOptions o;
  o.shading.background = {0.25, 0.5, 0.75};
  const auto hits = trace_hits(scene, kOrigin, kDown);
  ASSERT_EQ(hits.size(), 3u);
  const auto c = composite(hits, kDown, rgb_tf(), o);
  // Each hit faces the eye head-on: lambert 1, specular 1, so shaded = 0.95 c + 0.2.
  const double k = o.shading.ambient + o.shading.diffuse, s = o.shading.specular;
  const double shaded[3][3] = {{k + s, s, s}, {s, k + s, s}, {s, s, k + s}};
  const double alpha[3] = {0.5, 0.25, 0.8};
  double expected[3] = {0, 0, 0}, transmittance = 1;
  for (int i = 0; i < 3; ++i) {
    for (int ch = 0; ch < 3; ++ch) expected[ch] += transmittance * alpha[i] * shaded[i][ch];
    transmittance *= 1 - alpha[i];
  }
  for (int ch = 0; ch < 3; ++ch) expected[ch] += transmittance * o.shading.background[size_t(ch)];
  // By hand: T = 0.5 * 0.75 * 0.2 = 0.075.
  EXPECT_NEAR(transmittance, 0.075, 1e-12);
  for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(c[size_t(ch)], expected[ch], 1e-4) << ch;
  EXPECT_NEAR(c[3], 1 - 0.075, 1e-4);

  // The same pixel through the full frame path: a 1x1 image looks along the camera axis.
  Camera cam;
  cam.eye = kOrigin;
  cam.target = kOrigin + kDown;
  cam.near = 0.01, cam.far = 100;
  o.width = o.height = 1;
  const Frame f = trace_frame(scene, cam, rgb_tf(), o);
  for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(f.image.at(0, 0, ch), expected[ch], 1e-4);
  EXPECT_EQ(f.depth_complexity[0], 3u);

  // Early termination stops after the hit that takes A past the threshold.
  o.early_termination = true;
  o.termination_alpha = 0.6;  // A = 0.5, then 0.625: two hits composited
  uint64_t used = 0;
  composite(hits, kDown, rgb_tf(), o, &used);
  EXPECT_EQ(used, 2u);
}

TEST(RayTracer, EveryHitOnceAlongARayThroughNTubesAtTheirJoints) {
  for (const auto geometry : {EmbreeGeometry::LinearCurve, EmbreeGeometry::Capsules})
    for (const int n : {1, 4, 9}) {
      const LineSet lines = stacked_lines(n);
      for (const uint64_t per_scene : {uint64_t{0xFFFFFFFF}, uint64_t{4}}) {  // 4: instanced
        SCOPED_TRACE(std::string(to_string(geometry)) + " n " + std::to_string(n) + " per scene " +
                     std::to_string(per_scene));
        EmbreeOptions options;
        options.geometry = geometry;
        options.max_primitives_per_scene = per_scene;
        const EmbreeScene scene = EmbreeScene::from_lines(lines, kRadius, "", options);
        EXPECT_EQ(scene.stats().instanced, per_scene == 4 && n > 2);
        TraceCounters counters;
        // Through the joints at x = 0: one hit per tube; the second segment's is a seam double.
        const auto hits = trace_hits(scene, {0, 0, 10}, kDown, 0, 1e30, &counters);
        ASSERT_EQ(hits.size(), size_t(n));
        for (int i = 0; i < n; ++i) EXPECT_NEAR(hits[size_t(i)].t, 10.0 + i - kRadius, 1e-4);
        EXPECT_EQ(counters.duplicates, uint64_t(n));
        // Away from the joints: one rejected back hit (the far side) per tube, no doubles.
        TraceCounters off_joint;
        EXPECT_EQ(trace_hits(scene, kOrigin, kDown, 0, 1e30, &off_joint).size(), size_t(n));
        EXPECT_EQ(off_joint.back_hits, uint64_t(n));
        EXPECT_EQ(off_joint.duplicates, 0u);
        // Stepping finds the same hits; past a hit it does not see the seam double at all.
        for (const glm::dvec3& origin : {glm::dvec3(0, 0, 10), kOrigin}) {
          TraceCounters stepped;
          const auto again =
              trace_hits(scene, origin, kDown, 0, 1e30, &stepped, HitCollection::Stepping);
          ASSERT_EQ(again.size(), size_t(n));
          for (int i = 0; i < n; ++i) EXPECT_NEAR(again[size_t(i)].t, 10.0 + i - kRadius, 1e-4);
          EXPECT_EQ(stepped.back_hits, uint64_t(n));
          EXPECT_EQ(stepped.duplicates, 0u);
        }
      }
    }
}

TEST(Capsules, ARayAlongTheChainSeesOnlyItsEndCaps) {
  // Three collinear segments along x; the ray runs down the axis. The union of the capsules is
  // one long capsule: the ray enters the first end cap and leaves the last, and the joint
  // spheres and cylinders in between lie inside the neighbours.
  LineSet lines;
  for (const float x : {-1.0f, -0.2f, 0.5f, 1.0f}) lines.append_point(x, 0, 0);
  lines.end_line();
  EmbreeOptions o;
  o.geometry = EmbreeGeometry::Capsules;
  const EmbreeScene scene = EmbreeScene::from_lines(lines, kRadius, "", o);
  TraceCounters c;
  const auto hits = trace_hits(scene, {-5, 0, 0}, {1, 0, 0}, 0, 1e30, &c);
  ASSERT_EQ(hits.size(), 1u);
  EXPECT_NEAR(hits[0].t, 4 - kRadius, 1e-5);
  EXPECT_NEAR(glm::length(hits[0].surface.normal - glm::dvec3(-1, 0, 0)), 0, 1e-5);
  EXPECT_EQ(c.back_hits, 1u);  // leaving through the far cap at t = 6 + r
  EXPECT_EQ(c.duplicates, 0u);
}

TEST(Capsules, TheJointSphereFillsTheOuterCornerOfABend) {
  // An L: (0,0,0) -> (1,0,0) -> (1,1,0). Beyond the corner, outside both cylinders, only the
  // joint sphere is there: a ray down z at (1 + r/2, -r/2) meets it at height r / sqrt(2).
  LineSet lines;
  lines.append_point(0, 0, 0);
  lines.append_point(1, 0, 0);
  lines.append_point(1, 1, 0);
  lines.end_line();
  EmbreeOptions o;
  o.geometry = EmbreeGeometry::Capsules;
  const EmbreeScene scene = EmbreeScene::from_lines(lines, kRadius, "", o);
  const double r = kRadius;
  TraceCounters c;
  const auto hits = trace_hits(scene, {1 + r / 2, -r / 2, 10}, kDown, 0, 1e30, &c);
  ASSERT_EQ(hits.size(), 1u);
  EXPECT_NEAR(hits[0].t, 10 - r / std::sqrt(2.0), 1e-5);
  EXPECT_EQ(c.back_hits, 1u);
  // Inside the bend the cylinders overlap: the first segment's wall is higher there (at
  // sqrt(r^2 - (r/4)^2)); the second's, lower, lies inside it. One way in, one way out.
  TraceCounters inner;
  const auto inside = trace_hits(scene, {1 - r / 2, r / 4, 10}, kDown, 0, 1e30, &inner);
  ASSERT_EQ(inside.size(), 1u);
  EXPECT_NEAR(inside[0].t, 10 - std::sqrt(r * r - r * r / 16), 1e-5);
  EXPECT_EQ(inner.back_hits, 1u);
  EXPECT_EQ(inner.duplicates, 0u);
}

TEST(RayTracer, TriangleTubesGiveOneFrontHitPerTube) {
  const int n = 5;
  const LineSet lines = stacked_lines(n);
  TubeOptions t;
  t.sides = 8;
  t.radius = kRadius;
  t.radius_absolute = true;
  t.attribute = "none";
  const TubeMesh mesh = build_tubes(lines, t);
  for (const uint64_t per_scene : {uint64_t{0xFFFFFFFF}, uint64_t{8}}) {
    EmbreeOptions options;
    options.max_primitives_per_scene = per_scene;
    const EmbreeScene scene = EmbreeScene::from_tubes(mesh, options);
    TraceCounters counters;
    const auto hits = trace_hits(scene, kOrigin, kDown, 0, 1e30, &counters);
    ASSERT_EQ(hits.size(), size_t(n));
    // The octagon's top is a flat face at radius * cos(pi / 8) from the axis (ring vertex 0
    // points along the frame normal; the test only needs the hit between that and the radius).
    for (int i = 0; i < n; ++i) {
      EXPECT_GE(hits[size_t(i)].t, 10.0 + i - kRadius - 1e-4);
      EXPECT_LE(hits[size_t(i)].t, 10.0 + i - kRadius * std::cos(M_PI / 8) + 1e-4);
      EXPECT_GT(glm::dot(hits[size_t(i)].surface.normal, -kDown), 0.5);
    }
    EXPECT_EQ(counters.back_hits, uint64_t(n));
    EXPECT_EQ(hits.front().t < hits.back().t, true);
  }
}

// Three triangles over the ray's point, 1e-5 apart along it (within the seam distance of 1e-5 t
// at t = 10): T1 shares a vertex with T2 and T2 with T3, but T1 none with T3. A front hit with a
// front hit of an adjacent primitive just before it is a seam double, kept or itself a double,
// so only T1 is kept; comparing with kept hits only (T3 with T1, not with the dropped T2) kept
// T3 as well.
TEST(RayTracer, ASeamDoubleOfASeamDoubleIsDropped) {
  const float z1 = 2e-5f;
  const std::vector<float> positions = {
      -1, -1, z1, 1, -1, z1, 0, 1, z1,  // T1 at z = 2e-5 (vertex 2 shared with T2)
      -1, -1, 0,  1, -1, 0,             // T2 through vertex 2: z = 1e-5 at the ray
      3,  -1, 0,  0, 2,  0};            // T3 through vertex 3 at z = 0
  const std::vector<uint32_t> indices = {0, 1, 2, 3, 4, 2, 3, 5, 6};
  TubeMesh mesh;
  TubeChunk chunk;
  chunk.line_count = 1;
  chunk.positions = Array<float>(positions.size());
  std::copy(positions.begin(), positions.end(), chunk.positions.begin());
  chunk.normals = Array<float>(positions.size());
  for (size_t v = 0; v < positions.size() / 3; ++v)
    chunk.normals[3 * v] = 0, chunk.normals[3 * v + 1] = 0, chunk.normals[3 * v + 2] = 1;
  chunk.indices = Array<uint32_t>(indices.size());
  std::copy(indices.begin(), indices.end(), chunk.indices.begin());
  mesh.chunks.push_back(std::move(chunk));
  const EmbreeScene scene = EmbreeScene::from_tubes(mesh, {});
  TraceCounters counters;
  const glm::dvec3 origin(0, 0, 10);
  const auto hits = trace_hits(scene, origin, kDown, 0, 1e30, &counters);
  ASSERT_EQ(hits.size(), 1u);
  EXPECT_EQ(hits[0].primitive, 0u);
  EXPECT_NEAR(hits[0].t, 10 - 2e-5, 1e-6);
  EXPECT_EQ(counters.back_hits, 0u);
  EXPECT_EQ(counters.duplicates, 2u);
}

TEST(RayTracer, CurvesAndTrianglesAgreeOnCoverage) {
  LineSet lines;
  for (int i = 0; i < 6; ++i) {
    for (int k = 0; k <= 8; ++k) {
      const float s = float(k) / 8;
      lines.append_point(-1 + 2 * s, 0.6f * std::sin(3 * s + float(i)), 0.3f * float(i) - 0.8f);
    }
    lines.end_line();
  }
  TubeOptions t;
  t.sides = 32;
  t.radius = 0.05f;
  t.radius_absolute = true;
  t.attribute = "none";
  const EmbreeScene curves = EmbreeScene::from_lines(lines, t.radius, "", {});
  const EmbreeScene triangles = EmbreeScene::from_tubes(build_tubes(lines, t), {});
  const Camera cam = frame_bounds(curves.bounds(), 1.0, 20, 15);
  TraceOptions o;
  o.width = o.height = 96;
  const TransferFunction tf = transfer_function_preset("opaque");
  const Frame a = trace_frame(curves, cam, tf, o), b = trace_frame(triangles, cam, tf, o);
  size_t both = 0, either = 0;
  for (size_t i = 0; i < a.depth_complexity.size(); ++i) {
    both += a.depth_complexity[i] > 0 && b.depth_complexity[i] > 0;
    either += a.depth_complexity[i] > 0 || b.depth_complexity[i] > 0;
  }
  ASSERT_GT(either, 500u);
  EXPECT_GT(double(both) / double(either), 0.95);  // 32-gons against round tubes: edge pixels

  // Capsule chains are round linear curves by another method: the same pixels, the same hits.
  EmbreeOptions capsule_options;
  capsule_options.geometry = EmbreeGeometry::Capsules;
  const EmbreeScene capsules = EmbreeScene::from_lines(lines, t.radius, "", capsule_options);
  const Frame c = trace_frame(capsules, cam, tf, o);
  size_t same = 0;
  for (size_t i = 0; i < a.depth_complexity.size(); ++i)
    same += a.depth_complexity[i] == c.depth_complexity[i];
  EXPECT_GT(double(same) / double(a.depth_complexity.size()), 0.995);
}

// Curves of short segments go to Embree in a frame of their own (SceneFrame), so their image
// does not depend on the data's units: the same lines at 1, 1e-3 and 1e-6 times their size (and
// moved away from the origin) give the same pixels, linear and Bezier. Without the frame Embree 3's
// absolute epsilons let hits through the segments' caps: at 1e-3 the linear curves' pixels drew
// many hits more (the probe's 22.5 dB against the tube mesh).
TEST(RayTracer, ShortCurvesRenderAsAtAnyScale) {
  const auto lines_at = [](double scale, double offset) {
    LineSet lines;
    for (int i = 0; i < 6; ++i) {
      for (int k = 0; k <= 200; ++k) {
        const double s = double(k) / 200;
        lines.append_point(float((-1 + 2 * s) * scale + offset),
                           float(0.6 * std::sin(3 * s + i) * scale + offset),
                           float((0.3 * i - 0.8) * scale + offset));
      }
      lines.end_line();
    }
    return lines;
  };
  const TransferFunction tf = transfer_function_preset("semi");
  TraceOptions o;
  o.width = o.height = 64;
  for (const EmbreeGeometry geometry : {EmbreeGeometry::LinearCurve, EmbreeGeometry::BezierCurve}) {
    EmbreeOptions options;
    options.geometry = geometry;
    const EmbreeScene unit = EmbreeScene::from_lines(lines_at(1, 0), 0.02f, "", options);
    EXPECT_EQ(unit.frame().scale, 1.0);  // segments of 0.01: Embree's own frame
    const Camera cam = frame_bounds(unit.bounds(), 1.0, 20, 15);
    const Frame a = trace_frame(unit, cam, tf, o);
    for (const auto& [scale, offset] :
         std::vector<std::pair<double, double>>{{1e-3, 0.0}, {1e-6, 0.0}, {1e-3, 0.5}}) {
      const EmbreeScene small =
          EmbreeScene::from_lines(lines_at(scale, offset), float(0.02 * scale), "", options);
      EXPECT_GT(small.frame().scale, 1.0 / scale);
      Camera c = cam;
      c.eye = cam.eye * scale + glm::dvec3(offset);
      c.target = cam.target * scale + glm::dvec3(offset);
      c.near *= scale, c.far *= scale;
      const Frame b = trace_frame(small, c, tf, o);
      size_t same = 0;
      for (size_t i = 0; i < a.depth_complexity.size(); ++i)
        same += a.depth_complexity[i] == b.depth_complexity[i];
      EXPECT_GT(double(same) / double(a.depth_complexity.size()), 0.99)
          << to_string(geometry) << " at " << scale << " + " << offset;
      double worst = 0;
      for (size_t i = 0; i < a.image.pixels.size(); ++i)
        worst = std::max(worst, double(std::abs(a.image.pixels[i] - b.image.pixels[i])));
      EXPECT_LT(worst, 0.05) << to_string(geometry) << " at " << scale << " + " << offset;
      // Hits given back in world units.
      const glm::dvec3 d = c.ray_direction(32, 32, 64, 64);
      const auto hits = trace_hits(small, c.eye, d);
      const auto unit_hits = trace_hits(unit, cam.eye, cam.ray_direction(32, 32, 64, 64));
      ASSERT_EQ(hits.size(), unit_hits.size());
      for (size_t i = 0; i < hits.size(); ++i)
        EXPECT_NEAR(hits[i].t / scale, unit_hits[i].t, 1e-3) << i;
    }
  }
}

TEST(RayTracer, FramesDoNotDependOnTheThreadCount) {
  const LineSet lines = stacked_lines(4, {0.0f, 0.3f, 0.6f, 1.0f});
  const EmbreeScene scene = EmbreeScene::from_lines(lines, kRadius, "value", {});
  const Camera cam = frame_bounds(scene.bounds(), 1.5, 30, 20);
  TraceOptions o;
  o.width = 60, o.height = 40;
  const Frame many = trace_frame(scene, cam, rgb_tf(), o);
  Frame one;
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    one = trace_frame(scene, cam, rgb_tf(), o);
  }
  EXPECT_EQ(many.image.pixels, one.image.pixels);
  EXPECT_EQ(many.depth_complexity, one.depth_complexity);
}

// A stack of 12 tubes seen from above whose second tube is opaque: the walk stops there. Its
// pixel equals the hand-computed value of the two tubes over nothing, and fewer hits are
// visited than the all-hits path finds.
TEST(RayTracer, AnOpaqueTubeStopsTheWalk) {
  std::vector<float> values(12, 0.0f);
  values[1] = 1.0f;  // opacity 1 at attribute 1
  const LineSet lines = stacked_lines(12, values);
  const EmbreeScene scene = EmbreeScene::from_lines(lines, kRadius, "value", {});
  TransferFunction tf = rgb_tf();
  tf.opacities = {{0.0, 0.5}, {0.5, 0.5}, {0.75, 1.0}, {1.0, 1.0}};  // opaque over [0.75, 1]
  Camera cam;
  cam.eye = kOrigin;
  cam.target = kOrigin + kDown;
  cam.near = 0.01, cam.far = 100;
  TraceOptions o;
  o.width = o.height = 1;
  o.shading.background = {0.25, 0.5, 0.75};
  const Frame all = trace_frame(scene, cam, tf, o);
  o.every_hit = false;
  const Frame walked = trace_frame(scene, cam, tf, o);
  EXPECT_EQ(all.stats.counters.hits, 12u);
  EXPECT_EQ(all.depth_complexity[0], 12u);
  EXPECT_TRUE(walked.depth_complexity.empty());
  EXPECT_FALSE(walked.stats.every_hit);
  EXPECT_EQ(walked.stats.counters.stopped, 1u);
  EXPECT_LT(walked.stats.counters.hits, all.stats.counters.hits);
  EXPECT_EQ(walked.stats.counters.composited, 2u);
  // Red at A 0.5 over blue at A 1, both head-on (lambert 1): shaded = 0.95 c + 0.2.
  const double k = o.shading.ambient + o.shading.diffuse, sp = o.shading.specular;
  const double expected[3] = {0.5 * (k + sp) + 0.5 * sp, 0.5 * sp + 0.5 * sp,
                              0.5 * sp + 0.5 * (k + sp)};
  for (int ch = 0; ch < 3; ++ch) {
    EXPECT_NEAR(walked.image.at(0, 0, ch), expected[ch], 1e-5) << ch;
    EXPECT_EQ(walked.image.at(0, 0, ch), all.image.at(0, 0, ch)) << ch;
  }
}

// The walk gives the all-hits image exactly, for the three presets on curves and on the
// triangle tube mesh, with and without early termination; the all-hits path keeps its depth
// complexity.
TEST(RayTracer, TheIntervalWalkGivesTheAllHitsImage) {
  std::vector<float> values;
  for (int i = 0; i < 16; ++i) values.push_back(float(i % 5) / 4.0f);
  LineSet lines = stacked_lines(16, values);
  // Tilted lines cross the stack: seams, joints and near misses along the rays.
  for (int i = 0; i < 16; ++i) {
    lines.append_point(-1.0f, 0.3f * float(i % 3) - 0.3f, -float(i));
    lines.append_point(1.0f, 0.1f, -float(i) - 0.5f);
    lines.attributes[0].values.insert(lines.attributes[0].values.end(), 2, values[size_t(i)]);
    lines.end_line();
  }
  TubeOptions t;
  t.radius = kRadius;
  t.radius_absolute = true;
  const TubeMesh mesh = build_tubes(lines, t);
  const EmbreeScene curves = EmbreeScene::from_lines(lines, kRadius, "value", {});
  const EmbreeScene triangles = EmbreeScene::from_tubes(mesh, {});
  for (const EmbreeScene* scene : {&curves, &triangles})
    for (const char* preset : {"opaque", "semi", "transparent"})
      for (const bool early : {false, true}) {
        const TransferFunction tf = transfer_function_preset(preset);
        Camera cam;  // from above, down the stack: up to 32 tubes along a ray
        cam.eye = {0.1, 0.05, 4}, cam.target = {0, 0, -8};
        TraceOptions o;
        o.width = 48, o.height = 32;
        o.early_termination = early;
        const Frame all = trace_frame(*scene, cam, tf, o);
        o.every_hit = false;
        const Frame walked = trace_frame(*scene, cam, tf, o);
        const std::string what = std::string(preset) + (early ? " early" : "") +
                                 (scene == &curves ? " curves" : " triangles");
        EXPECT_EQ(walked.image.pixels, all.image.pixels) << what;
        EXPECT_EQ(all.depth_complexity.size(), size_t(48 * 32)) << what;
        EXPECT_GT(all.stats.max_depth_complexity, 4u) << what;
        // Only a pixel that can become opaque stops early; transparent never does.
        if (std::string(preset) == "transparent" && !early) {
          EXPECT_EQ(walked.stats.counters.hits, all.stats.counters.hits) << what;
        }
        if (std::string(preset) == "opaque") {
          EXPECT_LT(walked.stats.counters.hits, all.stats.counters.hits / 2) << what;
        }
      }
}

TEST(RayTracer, PacketsMatchSingleRays) {
  // 61x41: tiles whose edges cut 4x2 packets, so some lanes are off the image.
  const LineSet lines = stacked_lines(4, {0.0f, 0.3f, 0.6f, 1.0f});
  for (const auto geometry : {EmbreeGeometry::LinearCurve, EmbreeGeometry::Capsules}) {
    EmbreeOptions eo;
    eo.geometry = geometry;
    const EmbreeScene scene = EmbreeScene::from_lines(lines, kRadius, "value", eo);
    const Camera cam = frame_bounds(scene.bounds(), 61.0 / 41.0, 30, 20);
    TraceOptions o;
    o.width = 61, o.height = 41;
    const Frame single = trace_frame(scene, cam, rgb_tf(), o);
    o.packets = true;
    const Frame packed = trace_frame(scene, cam, rgb_tf(), o);
    EXPECT_EQ(packed.depth_complexity, single.depth_complexity) << to_string(geometry);
    ASSERT_GT(single.stats.counters.hits, 500u);
    float worst = 0;
    for (size_t i = 0; i < single.image.pixels.size(); ++i)
      worst = std::max(worst, std::abs(single.image.pixels[i] - packed.image.pixels[i]));
    EXPECT_LT(worst, 1e-5f) << to_string(geometry);
  }
}

TEST(EmbreeScene, BezierCurvesThroughStraightPointsHitLikeLinearOnes) {
  const LineSet lines = stacked_lines(3);
  EmbreeOptions o;
  o.geometry = EmbreeGeometry::BezierCurve;
  const EmbreeScene scene = EmbreeScene::from_lines(lines, kRadius, "", o);
  EXPECT_EQ(scene.stats().primitives, 6u);
  const auto hits = trace_hits(scene, kOrigin, kDown);  // away from the joints
  ASSERT_EQ(hits.size(), 3u);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(hits[size_t(i)].t, 10.0 + i - kRadius, 1e-3);
}

TEST(EmbreeScene, PreparedBuffersRebuildTheSameScene) {
  // Lines without segments in between and at the end, and parts split at 3 segments: the
  // prepared buffers of one build make a scene that hits exactly like it.
  LineSet lines = stacked_lines(5, {0.0f, 0.25f, 0.5f, 0.75f, 1.0f});
  lines.append_point(0, 0, 5);
  lines.attributes[0].values.push_back(0);
  lines.end_line();
  for (const auto geometry :
       {EmbreeGeometry::LinearCurve, EmbreeGeometry::BezierCurve, EmbreeGeometry::Capsules}) {
    SCOPED_TRACE(to_string(geometry));
    EmbreeOptions o;
    o.geometry = geometry;
    o.max_primitives_per_scene = 3;
    const EmbreeScene built = EmbreeScene::from_lines(lines, kRadius, "value", o);
    const EmbreeScene again =
        EmbreeScene::from_prepared(lines, built.prepared_curves(), "value", o);
    EXPECT_EQ(again.stats().primitives, built.stats().primitives);
    EXPECT_EQ(again.stats().parts, built.stats().parts);
    for (const glm::dvec3& origin : {glm::dvec3(0, 0, 10), kOrigin, glm::dvec3(-0.7, 0.1, 10)}) {
      const auto a = trace_hits(built, origin, kDown), b = trace_hits(again, origin, kDown);
      ASSERT_EQ(a.size(), b.size());
      for (size_t i = 0; i < a.size(); ++i) {
        EXPECT_EQ(a[i].t, b[i].t);
        EXPECT_EQ(a[i].surface.attribute, b[i].surface.attribute);
      }
    }
    // Buffers of other lines are refused.
    EXPECT_THROW(EmbreeScene::from_prepared(stacked_lines(4), built.prepared_curves(), "", o),
                 Error);
  }
}

TEST(EmbreeScene, ReportsBuildFiguresAndRejectsBadInput) {
  const LineSet lines = stacked_lines(2);
  const EmbreeScene scene = EmbreeScene::from_lines(lines, kRadius, "value", {});
  EXPECT_EQ(scene.stats().primitives, 4u);
  EXPECT_GT(scene.stats().bvh_bytes, 0u);
  EXPECT_GE(scene.stats().bvh_peak_bytes, scene.stats().bvh_bytes);
  // Linear curves: one FLOAT4 per point plus a padding vertex, an index and a flag per segment.
  EXPECT_EQ(scene.stats().buffer_bytes, (6 + 1) * 16u + 4 * 4u + 4u);
  EXPECT_THROW(EmbreeScene::from_lines(lines, 0.0f, "", {}), Error);
  EXPECT_THROW(EmbreeScene::from_lines(lines, kRadius, "nope", {}), Error);
}

TEST(EmbreeScene, ABvhPastItsMemoryLimitIsRefusedWithTheFigures) {
  // Enough lines for a BVH of some megabytes, as curves and as the tube mesh (the reference's).
  const LineSet lines = stacked_lines(20000);
  TubeOptions t;
  t.radius = kRadius;
  const TubeMesh mesh = build_tubes(lines, t);
  // Curves in one scene and in instanced sub-scenes of 5,000 segments, and triangles.
  for (const int kind : {0, 1, 2}) {
    const bool triangles = kind == 2;
    SCOPED_TRACE(kind == 0 ? "curves" : kind == 1 ? "curves in sub-scenes" : "triangles");
    const auto build = [&](uint64_t limit) {
      EmbreeOptions o;
      o.max_memory_bytes = limit;
      if (kind == 1) o.max_primitives_per_scene = 5000;
      return triangles ? EmbreeScene::from_tubes(mesh, o)
                       : EmbreeScene::from_lines(lines, kRadius, "", o);
    };
    const BvhStats free = build(0).stats();
    ASSERT_GT(free.bvh_peak_bytes, 1u << 20);
    EXPECT_EQ(free.instanced, kind == 1);
    // Twice what it took: built, within the limit, the same scene.
    const uint64_t room = free.buffer_bytes + 2 * free.bvh_peak_bytes;
    const BvhStats within = build(room).stats();
    EXPECT_EQ(within.primitives, free.primitives);
    EXPECT_LE(within.buffer_bytes + within.bvh_peak_bytes, room);
    // Half of what its BVH took: Embree's monitor stops the build, and the error says why.
    const uint64_t half = free.buffer_bytes + free.bvh_peak_bytes / 2;
    try {
      build(half);
      ADD_FAILURE() << "a build past its limit was not refused";
    } catch (const BudgetExceeded& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("Embree's BVH over " + std::to_string(free.primitives) +
                          (triangles ? " triangles" : " segments") + " needs more than the " +
                          format_bytes(half)),
                std::string::npos)
          << what;
      EXPECT_NE(what.find("raise --memory-budget"), std::string::npos) << what;
    }
    // Less than its own input buffers (curves: linebake's; triangles share the mesh's): refused
    // before Embree builds anything.
    if (!triangles) {
      EXPECT_THROW(build(free.buffer_bytes / 2), BudgetExceeded);
    }
  }
}

TEST(Camera, CentreRayIsTheViewDirectionAndTheBoundsFit) {
  Bounds b;
  b.empty = false;
  b.min = {-1, -2, -0.5f};
  b.max = {3, 1, 0.5f};
  const Camera c = frame_bounds(b, 16.0 / 9.0, 40, 25);
  const glm::dvec3 centre = c.ray_direction(0, 0, 1, 1);
  EXPECT_NEAR(glm::length(centre - c.forward()), 0, 1e-12);
  // Every box corner projects inside the image.
  const glm::dvec3 f = c.forward(), r = glm::normalize(glm::cross(f, c.up)), u = glm::cross(r, f);
  const double th = std::tan(c.fov_y_degrees * M_PI / 360), tw = th * 16.0 / 9.0;
  for (int i = 0; i < 8; ++i) {
    const glm::dvec3 p((i & 1) ? b.max[0] : b.min[0], (i & 2) ? b.max[1] : b.min[1],
                       (i & 4) ? b.max[2] : b.min[2]);
    const glm::dvec3 d = p - c.eye;
    const double z = glm::dot(d, f);
    EXPECT_GT(z, c.near);
    EXPECT_LT(z, c.far);
    EXPECT_LE(std::abs(glm::dot(d, r) / z), tw);
    EXPECT_LE(std::abs(glm::dot(d, u) / z), th);
  }
}

TEST(Camera, OrbitDistanceFitsTheBoxTightlyFromEveryAzimuth) {
  // An elongated box (like the aneurysm): along the orbit, the tightest frame puts some corner
  // exactly at the 5% margin, and none beyond it.
  Bounds b;
  b.empty = false;
  b.min = {-4, -1, -0.5f};
  b.max = {4, 1, 0.5f};
  FlightOptions o;
  o.kind = FlightKind::Orbit;
  o.frames = 360;  // one frame per degree: the azimuths the fit samples
  const double aspect = 16.0 / 9.0;
  const auto cams = make_flight(b, aspect, o);
  double tightest = 0;
  for (const Camera& c : cams) {
    const glm::dvec3 f = c.forward(), r = glm::normalize(glm::cross(f, c.up)), u = glm::cross(r, f);
    const double th = std::tan(c.fov_y_degrees * M_PI / 360), tw = th * aspect;
    for (int i = 0; i < 8; ++i) {
      const glm::dvec3 p((i & 1) ? b.max[0] : b.min[0], (i & 2) ? b.max[1] : b.min[1],
                         (i & 4) ? b.max[2] : b.min[2]);
      const glm::dvec3 d = p - c.eye;
      const double z = glm::dot(d, f);
      tightest = std::max(
          {tightest, std::abs(glm::dot(d, r)) / z / tw, std::abs(glm::dot(d, u)) / z / th});
    }
  }
  EXPECT_NEAR(tightest, 1 / 1.05, 1e-9);
  // The bounding-sphere fit would stand further off.
  const double sphere_fit = std::sqrt(64.0 + 4 + 1) / 2 / std::sin(20 * M_PI / 180);
  EXPECT_LT(glm::length(cams[0].eye - cams[0].target), 0.9 * sphere_fit);
}

TEST(Camera, OrbitZoomFlightZoomsInTwice) {
  Bounds b;
  b.empty = false;
  b.min = {-1.0f, -1.0f, -1.0f};
  b.max = {1.0f, 1.0f, 1.0f};
  FlightOptions o;
  o.frames = 100;
  const auto zoom = make_flight(b, 1.0, o);
  o.kind = FlightKind::Orbit;
  const auto orbit = make_flight(b, 1.0, o);
  ASSERT_EQ(zoom.size(), 100u);
  const auto distance = [](const Camera& c) { return glm::length(c.eye - c.target); };
  EXPECT_NEAR(distance(zoom[30]), 0.35 * distance(orbit[30]), 1e-9);
  EXPECT_NEAR(distance(zoom[70]), 0.35 * distance(orbit[70]), 1e-9);
  EXPECT_NEAR(distance(zoom[0]), distance(orbit[0]), 1e-9);
  EXPECT_NEAR(distance(zoom[50]), distance(orbit[50]), 1e-9);
  for (const auto& c : orbit) EXPECT_NEAR(distance(c), distance(orbit[0]), 1e-9);
}

TEST(Camera, KeyframesInterpolateAndBadFilesNameThePlace) {
  test::TempDir dir;
  const std::string good = dir.file("k.json"), bad = dir.file("bad.json");
  std::ofstream(good) << R"({"keyframes": [{"eye": [0, 0, 10], "target": [0, 0, 0]},
                                          {"eye": [10, 0, 0], "target": [0, 0, 0], "fov": 60}]})";
  std::ofstream(bad) << R"({"keyframes": [{"eye": [0, 0], "target": [0, 0, 0]}]})";
  Bounds b;
  b.empty = false;
  b.max = {1.0f, 1.0f, 1.0f};
  FlightOptions o;
  o.kind = FlightKind::Keyframes;
  o.keyframes_file = good;
  o.frames = 3;
  const auto cams = make_flight(b, 1.0, o);
  ASSERT_EQ(cams.size(), 3u);
  EXPECT_NEAR(glm::length(cams[1].eye - glm::dvec3(5, 0, 5)), 0, 1e-12);
  EXPECT_NEAR(cams[1].fov_y_degrees, 50, 1e-12);
  o.keyframes_file = bad;
  try {
    make_flight(b, 1.0, o);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.where(), "keyframe 0");
  }
  // An up along the view direction makes no camera (its rays would be NaN): refused, naming
  // the keyframe and the reason.
  const std::string parallel = dir.file("parallel.json");
  std::ofstream(parallel) << R"({"keyframes": [{"eye": [0, 0, 10], "target": [0, 0, 0]},
                                 {"eye": [0, 3, 0], "target": [0, 0, 0], "up": [0, 2, 0]}]})";
  o.keyframes_file = parallel;
  // The flight refused where `where` says, because its up lies along the view.
  const auto refused_along_the_view = [&](const std::string& where) {
    try {
      make_flight(b, 1.0, o);
      ADD_FAILURE() << "made";
    } catch (const InputError& e) {
      EXPECT_EQ(e.where(), where);
      EXPECT_NE(std::string(e.what()).find("up lies along the view direction"), std::string::npos);
    }
  };
  refused_along_the_view("keyframe 1");
  // Two good keyframes whose interpolated middle frame looks straight down along its up (eye
  // (0, 0, 3) over the target, up (0, 0, 1)): refused, naming that frame, not rendered (Embree
  // aborted on its NaN rays).
  const std::string opposite = dir.file("opposite.json");
  std::ofstream(opposite) << R"({"keyframes": [
      {"eye": [3, 3, 3], "target": [0, 0, 0], "up": [0, 0, 1]},
      {"eye": [-3, -3, 3], "target": [0, 0, 0], "up": [0, 0, 1]}]})";
  o.keyframes_file = opposite;
  o.frames = 3;
  refused_along_the_view("frame 1 (between keyframes 0 and 1)");
  o.frames = 2;  // the keyframes alone are good cameras
  EXPECT_EQ(make_flight(b, 1.0, o).size(), 2u);
}

// Each thing that makes a camera unusable, by hand, and a good one.
TEST(Camera, ProblemsAreNamed) {
  Camera c;
  EXPECT_EQ(camera_problem(c), "");
  Camera on = c;
  on.eye = on.target;
  EXPECT_EQ(camera_problem(on), "the eye is on the target");
  Camera nan = c;
  nan.eye.x = std::nan("");
  EXPECT_EQ(camera_problem(nan), "eye, target and up must be finite numbers (below 1e18)");
  Camera huge = c;
  huge.eye.z = 2e18;  // past Embree's ray origins
  EXPECT_EQ(camera_problem(huge), camera_problem(nan));
  Camera far = c;
  far.eye.z = 9e17;
  EXPECT_EQ(camera_problem(far), "");
  Camera flat = c;
  flat.up = {0, 0, -3};  // along eye - target
  EXPECT_EQ(camera_problem(flat), "up lies along the view direction");
  Camera zero = c;
  zero.up = {0, 0, 0};
  EXPECT_EQ(camera_problem(zero), "up has zero length");
  for (double fov : {0.0, 180.0, -30.0, std::nan("")}) {
    Camera f = c;
    f.fov_y_degrees = fov;
    EXPECT_EQ(camera_problem(f), "fov must be in (0, 180) degrees") << fov;
  }
}

TEST(TransferFunction, PresetsAndJsonRoundTrip) {
  const TransferFunction opaque = transfer_function_preset("opaque");
  EXPECT_EQ(opaque.at(0.3).a, 1.0);
  EXPECT_NEAR(transfer_function_preset("transparent").at(0.9).a, 0.1, 1e-12);
  const TransferFunction semi = transfer_function_preset("semi");
  EXPECT_LT(semi.at(0.1).a, 0.1);
  EXPECT_EQ(semi.at(1.0).a, 1.0);
  // Between points: linear. semi has (0.4, 0.08) and (1, 1): at 0.7, 0.54.
  EXPECT_NEAR(semi.at(0.7).a, 0.54, 1e-12);
  EXPECT_NEAR(rgb_tf().at(0.25).g, srgb_to_linear(0.5), 1e-12);  // interpolated in sRGB
  test::TempDir dir;
  TransferFunction tf = rgb_tf();
  save_transfer_function(tf, dir.file("tf.json"));
  const TransferFunction back = load_transfer_function(dir.file("tf.json"));
  for (const double t : {0.0, 0.1, 0.5, 0.77, 1.0}) {
    EXPECT_EQ(back.at(t).r, tf.at(t).r);
    EXPECT_EQ(back.at(t).a, tf.at(t).a);
  }
  EXPECT_EQ(back.range, tf.range);
  std::ofstream(dir.file("broken.json"))
      << R"({"colours": [[0, 1, 0, 0]], "opacities": [[0.5, 2]]})";
  try {
    load_transfer_function(dir.file("broken.json"));
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.where(), "opacities[0]");
  }
  EXPECT_THROW(transfer_function_preset("rainbow"), Error);
  // A range runs upwards or is [0, 0] (the data's own): a reversed or empty one had mapped every
  // value to the colours' middle.
  for (const char* range : {"[3.14, 0.087]", "[1, 1]", "[-1, -1]"}) {
    std::ofstream(dir.file("range.json"))
        << R"({"colours": [[0, 1, 0, 0]], "opacities": [[0, 1]], "range": )" << range << "}";
    try {
      load_transfer_function(dir.file("range.json"));
      ADD_FAILURE() << range;
    } catch (const InputError& e) {
      EXPECT_EQ(e.where(), "range") << range;
    }
  }
  for (const char* range : {"[0, 0]", "[-2, 0.5]"}) {
    std::ofstream(dir.file("range.json"))
        << R"({"colours": [[0, 1, 0, 0]], "opacities": [[0, 1]], "range": )" << range << "}";
    EXPECT_NO_THROW(load_transfer_function(dir.file("range.json"))) << range;
  }
}

}  // namespace
}  // namespace linebake
