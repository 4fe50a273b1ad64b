// Tube mesher: topology, geometry, frames, chunking and determinism.

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstring>
#include <map>
#include <numbers>

#include "core/error.hpp"
#include "tubes/tube_builder.hpp"

namespace linebake {
namespace {

struct V {
  double x, y, z;
};
V sub(V a, V b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}
double dot(V a, V b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
double norm(V a) {
  return std::sqrt(dot(a, a));
}
V unit(V a) {
  const double l = norm(a);
  return {a.x / l, a.y / l, a.z / l};
}
V cross(V a, V b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

V vertex(const TubeChunk& c, uint64_t v) {
  return {c.positions[3 * v], c.positions[3 * v + 1], c.positions[3 * v + 2]};
}
V normal(const TubeChunk& c, uint64_t v) {
  return {c.normals[3 * v], c.normals[3 * v + 1], c.normals[3 * v + 2]};
}

LineSet polyline(const std::vector<V>& points) {
  LineSet lines;
  for (V p : points) lines.append_point(float(p.x), float(p.y), float(p.z));
  lines.end_line();
  return lines;
}

TubeOptions absolute(float radius, int sides) {
  TubeOptions o;
  o.radius = radius;
  o.radius_absolute = true;
  o.sides = sides;
  return o;
}

std::vector<V> helix(double a, double b, int points_per_turn, int turns) {
  std::vector<V> p;
  for (int i = 0; i <= points_per_turn * turns; ++i) {
    const double t = 2 * std::numbers::pi * i / points_per_turn;
    p.push_back({a * std::cos(t), a * std::sin(t), b * t});
  }
  return p;
}

// Undirected edge -> number of triangles using it; directed edge -> count.
struct EdgeCounts {
  std::map<std::pair<uint32_t, uint32_t>, int> undirected, directed;
};
EdgeCounts count_edges(const TubeChunk& c) {
  EdgeCounts e;
  for (uint64_t t = 0; t < c.triangle_count(); ++t) {
    for (int k = 0; k < 3; ++k) {
      const uint32_t a = c.indices[3 * t + k], b = c.indices[3 * t + (k + 1) % 3];
      e.undirected[{std::min(a, b), std::max(a, b)}] += 1;
      e.directed[{a, b}] += 1;
    }
  }
  return e;
}

TEST(Tubes, StraightLineTopology) {
  const int n = 5;
  const LineSet lines = polyline({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}});
  const TubeMesh mesh = build_tubes(lines, absolute(0.1f, n));
  ASSERT_EQ(mesh.chunks.size(), 1u);
  const TubeChunk& c = mesh.chunks[0];
  EXPECT_EQ(c.vertex_count(), 4u * n);
  EXPECT_EQ(c.indices.size(), 3u * 6 * n);  // 6n indices per segment
  for (uint32_t i : c.indices) EXPECT_LT(i, c.vertex_count());
  // Open tube: ring edges at both ends are used once, every other edge twice.
  const EdgeCounts e = count_edges(c);
  int boundary = 0;
  for (const auto& [edge, count] : e.undirected) {
    EXPECT_TRUE(count == 1 || count == 2);
    boundary += count == 1;
  }
  EXPECT_EQ(boundary, 2 * n);  // the two end rings, closed (j = n-1 connects back to 0)
  for (const auto& [edge, count] : e.directed) EXPECT_EQ(count, 1) << "inconsistent winding";
}

TEST(Tubes, CapsMakeAClosedManifold) {
  for (int n : {3, 4, 8}) {
    const LineSet lines = polyline(helix(1, 0.2, 12, 1));
    TubeOptions o = absolute(0.05f, n);
    o.caps = true;
    const TubeMesh mesh = build_tubes(lines, o);
    const TubeChunk& c = mesh.chunks[0];
    const uint64_t points = 13;
    EXPECT_EQ(c.vertex_count(), points * n + 2);
    EXPECT_EQ(c.indices.size(), (points - 1) * 6 * n + 2 * 3 * n);
    const EdgeCounts e = count_edges(c);
    for (const auto& [edge, count] : e.undirected) EXPECT_EQ(count, 2);
    for (const auto& [edge, count] : e.directed) EXPECT_EQ(count, 1);
    // Euler characteristic of a sphere: V - E + F = 2.
    const int64_t chi =
        int64_t(c.vertex_count()) - int64_t(e.undirected.size()) + int64_t(c.triangle_count());
    EXPECT_EQ(chi, 2) << "sides " << n;
  }
}

TEST(Tubes, TrianglesFaceOutwards) {
  const LineSet lines = polyline(helix(1, 0.3, 16, 2));
  TubeOptions o = absolute(0.05f, 6);
  o.caps = true;
  const TubeMesh mesh = build_tubes(lines, o);
  const TubeChunk& c = mesh.chunks[0];
  for (uint64_t t = 0; t < c.triangle_count(); ++t) {
    const uint32_t* i = &c.indices[3 * t];
    const V geometric =
        cross(sub(vertex(c, i[1]), vertex(c, i[0])), sub(vertex(c, i[2]), vertex(c, i[0])));
    V shading{0, 0, 0};
    for (int k = 0; k < 3; ++k) {
      const V nk = normal(c, i[k]);
      shading = {shading.x + nk.x, shading.y + nk.y, shading.z + nk.z};
    }
    EXPECT_GT(dot(geometric, shading), 0) << "triangle " << t;
  }
}

TEST(Tubes, RingGeometryOnAHelix) {
  const double a = 1, b = 0.25;
  const int per_turn = 48;
  const std::vector<V> p = helix(a, b, per_turn, 3);
  const float radius = 0.02f;
  const int n = 7;
  const TubeMesh mesh = build_tubes(polyline(p), absolute(radius, n));
  const TubeChunk& c = mesh.chunks[0];
  for (size_t i = 0; i < p.size(); ++i) {
    // Equal spacing: the central difference is the tangent the mesher must be perpendicular to.
    const V t = i == 0              ? unit(sub(p[1], p[0]))
                : i + 1 == p.size() ? unit(sub(p[i], p[i - 1]))
                                    : unit(sub(p[i + 1], p[i - 1]));
    for (int j = 0; j < n; ++j) {
      const uint64_t v = i * n + j;
      const V nv = normal(c, v);
      EXPECT_NEAR(norm(nv), 1.0, 1e-6);
      EXPECT_NEAR(dot(nv, t), 0.0, 1e-5);
      const V offset = sub(vertex(c, v), p[i]);
      EXPECT_NEAR(norm(offset), radius, 1e-6);
      EXPECT_NEAR(dot(unit(offset), nv), 1.0, 1e-5);  // normal = (vertex - p) / r
    }
    // Consecutive ring vertices are 2*pi/n apart.
    const double angle =
        std::acos(std::clamp(dot(normal(c, i * n), normal(c, i * n + 1)), -1.0, 1.0));
    EXPECT_NEAR(angle, 2 * std::numbers::pi / n, 1e-4);
  }
}

// On a helix the rotation-minimising normal turns against the Frenet frame at minus the torsion:
// with U = cos(phi) N + sin(phi) B and U' having no N/B part, phi' = -tau. A frame that twists
// (or a projection method that drifts) accumulates a different angle over several turns.
TEST(Tubes, NoTwistAccumulatesAlongAHelix) {
  const double a = 1, b = 0.4, c2 = a * a + b * b, tau = b / c2;
  const int per_turn = 200, turns = 4;
  const std::vector<V> p = helix(a, b, per_turn, turns);
  const TubeMesh mesh = build_tubes(polyline(p), absolute(0.01f, 3));
  const TubeChunk& c = mesh.chunks[0];
  double phi0 = 0, previous = 0, unwrapped = 0;
  double worst = 0;
  for (size_t i = 1; i + 1 < p.size(); ++i) {
    const double t = 2 * std::numbers::pi * double(i) / per_turn;
    const V T = unit({-a * std::sin(t), a * std::cos(t), b});
    const V N = {-std::cos(t), -std::sin(t), 0};
    const V B = cross(T, N);
    const V u = normal(c, i * 3);
    const double phi = std::atan2(dot(u, B), dot(u, N));
    if (i == 1) {
      phi0 = unwrapped = previous = phi;
    } else {
      double d = phi - previous;
      d -= 2 * std::numbers::pi * std::round(d / (2 * std::numbers::pi));
      unwrapped += d;
      previous = phi;
    }
    const double s = std::sqrt(c2) * (t - 2 * std::numbers::pi / per_turn);
    worst = std::max(worst, std::fabs((unwrapped - phi0) - (-tau * s)));
  }
  // Total turn over 4 turns is tau*s = 0.4/1.16*sqrt(1.16)*8*pi ~ 9.3 rad; the discrete frame
  // follows it to well under a degree.
  EXPECT_LT(worst, 0.01);
}

TEST(Tubes, PlanarCurveKeepsItsPlaneNormal) {
  std::vector<V> p;
  for (int i = 0; i < 100; ++i) p.push_back({std::cos(0.1 * i) * i, std::sin(0.07 * i) * 5, 0});
  const TubeMesh mesh = build_tubes(polyline(p), absolute(0.1f, 3));
  const TubeChunk& c = mesh.chunks[0];
  // The first frame is either in the plane or across it; a rotation-minimising frame keeps it so.
  const double first = std::fabs(normal(c, 0).z);
  EXPECT_TRUE(first < 1e-6 || first > 1 - 1e-6);
  for (size_t i = 0; i < p.size(); ++i)
    EXPECT_NEAR(std::fabs(normal(c, i * 3).z), first, 1e-5) << "point " << i;
}

TEST(Tubes, SharpBendsAndRepeatedPointsStayFinite) {
  // A full U-turn, a right angle and repeated points.
  const LineSet lines = polyline(
      {{0, 0, 0}, {1, 0, 0}, {1, 0, 0}, {1, 0, 0}, {0, 0, 0}, {0, 1, 0}, {0, 1, 0}, {0, 1, 1}});
  const float radius = 0.05f;
  const TubeMesh mesh = build_tubes(lines, absolute(radius, 4));
  EXPECT_EQ(mesh.points_skipped, 3u);
  const TubeChunk& c = mesh.chunks[0];
  ASSERT_EQ(c.vertex_count(), 5u * 4);
  for (float v : c.positions) EXPECT_TRUE(std::isfinite(v));
  for (float v : c.normals) EXPECT_TRUE(std::isfinite(v));
  for (uint64_t ring = 0; ring < 5; ++ring) {
    for (int j = 0; j < 4; ++j) {
      EXPECT_NEAR(norm(normal(c, ring * 4 + j)), 1.0, 1e-6);
      for (int k = 0; k < j; ++k)  // no collapsed ring: vertices stay apart
        EXPECT_GT(norm(sub(vertex(c, ring * 4 + j), vertex(c, ring * 4 + k))), radius);
    }
  }
}

TEST(Tubes, DegenerateLinesAreDroppedAndCounted) {
  LineSet lines = polyline({{0, 0, 0}, {1, 1, 1}});
  lines.append_point(5, 5, 5);
  lines.append_point(5, 5, 5);
  lines.end_line();
  lines.append_point(2, 2, 2);
  lines.end_line();
  const TubeMesh mesh = build_tubes(lines, absolute(0.1f, 3));
  EXPECT_EQ(mesh.lines_dropped, 2u);
  EXPECT_EQ(mesh.vertex_count(), 6u);
  EXPECT_EQ(mesh.chunks[0].line_count, 3u);
  LineSet none;
  none.append_point(1, 1, 1);
  none.append_point(1, 1, 1);
  none.end_line();
  EXPECT_THROW(build_tubes(none, absolute(0.1f, 3)), Error);
}

TEST(Tubes, OptionsOutOfRangeAreErrors) {
  const LineSet lines = polyline({{0, 0, 0}, {1, 0, 0}});
  EXPECT_THROW(build_tubes(lines, absolute(0.1f, 2)), Error);
  EXPECT_THROW(build_tubes(lines, absolute(0.1f, 33)), Error);
  EXPECT_THROW(build_tubes(lines, absolute(-1.0f, 3)), Error);
  TubeOptions o = absolute(0.1f, 3);
  o.attribute = "missing";
  EXPECT_THROW(build_tubes(lines, o), Error);
}

TEST(Tubes, RelativeRadiusAndRadiusAttribute) {
  LineSet lines = polyline({{0, 0, 0}, {3, 0, 0}, {3, 4, 0}});  // diagonal 5
  lines.attributes.push_back({"width", {1, 2, 4}});
  TubeOptions o;
  o.radius = 0.01f;
  o.sides = 3;
  TubeMesh mesh = build_tubes(lines, o);
  EXPECT_FLOAT_EQ(mesh.radius, 0.05f);
  o.radius_attribute = "width";
  mesh = build_tubes(lines, o);
  const TubeChunk& c = mesh.chunks[0];
  const V pts[] = {{0, 0, 0}, {3, 0, 0}, {3, 4, 0}};
  const double expect[] = {0.05 * 0.25, 0.05 * 0.5, 0.05};
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(norm(sub(vertex(c, i * 3), pts[i])), expect[i], 1e-6);
}

TEST(Tubes, AttributeIsUnorm16OverTheRange) {
  LineSet lines = polyline({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}});
  lines.attributes.push_back({"speed", {-1, 0, 3}});
  lines.line_attributes.push_back({"id", {7}});
  TubeMesh mesh = build_tubes(lines, absolute(0.1f, 3));
  EXPECT_EQ(mesh.attribute, "speed");
  EXPECT_EQ(mesh.attribute_range, (std::array<float, 2>{-1, 3}));
  const TubeChunk& c = mesh.chunks[0];
  EXPECT_EQ(c.attribute[0], 0);
  EXPECT_EQ(c.attribute[3], 16384);  // 0.25 * 65535 = 16383.75
  EXPECT_EQ(c.attribute[8], 65535);
  EXPECT_NEAR(decode_unorm16(c.attribute[3], mesh.attribute_range), 0.0f, 1e-4);
  TubeOptions o = absolute(0.1f, 3);
  o.attribute = "speed";
  o.attribute_range = std::array<float, 2>{0, 1};
  mesh = build_tubes(lines, o);
  EXPECT_EQ(mesh.chunks[0].attribute[0], 0);  // clamped
  EXPECT_EQ(mesh.chunks[0].attribute[8], 65535);
  o.attribute = "id";  // a line attribute is broadcast to the line's vertices
  o.attribute_range = std::array<float, 2>{0, 14};
  mesh = build_tubes(lines, o);
  for (uint16_t v : mesh.chunks[0].attribute) EXPECT_EQ(v, 32768);
  o.attribute = "none";
  mesh = build_tubes(lines, o);
  EXPECT_TRUE(mesh.chunks[0].attribute.empty());
  EXPECT_EQ(mesh.attribute, "");
}

TEST(Tubes, OctahedralNormals) {
  const LineSet lines = polyline(helix(1, 0.3, 20, 2));
  TubeOptions o = absolute(0.05f, 8);
  const TubeMesh exact = build_tubes(lines, o);
  o.normals = NormalEncoding::Oct16;
  const TubeMesh packed = build_tubes(lines, o);
  ASSERT_EQ(packed.chunks[0].normals_oct.size(), 2 * exact.chunks[0].vertex_count());
  EXPECT_TRUE(packed.chunks[0].normals.empty());
  EXPECT_EQ(packed.bytes() + 8 * exact.vertex_count(), exact.bytes());
  for (uint64_t v = 0; v < exact.vertex_count(); ++v) {
    const auto d = decode_octahedral(packed.chunks[0].normals_oct[2 * v],
                                     packed.chunks[0].normals_oct[2 * v + 1]);
    const V n = normal(exact.chunks[0], v);
    EXPECT_GT(d[0] * n.x + d[1] * n.y + d[2] * n.z, std::cos(1e-3));  // within 0.06 degrees
  }
  for (V axis : std::vector<V>{{0, 0, -1}, {1, 0, 0}, {0, -1, 0}, {0, 0, 1}}) {
    const auto e = encode_octahedral(float(axis.x), float(axis.y), float(axis.z));
    const auto d = decode_octahedral(e[0], e[1]);
    EXPECT_NEAR(d[0], axis.x, 1e-6);
    EXPECT_NEAR(d[1], axis.y, 1e-6);
    EXPECT_NEAR(d[2], axis.z, 1e-6);
  }
}

// 10,000 curved lines of 2..40 points, with an attribute.
LineSet many_lines() {
  LineSet lines;
  lines.attributes.push_back({"phase", {}});
  for (int l = 0; l < 10000; ++l) {
    const int points = 2 + (l * 7919) % 39;
    for (int i = 0; i < points; ++i) {
      const double t = 0.3 * i + 0.001 * l;
      lines.append_point(float(std::cos(t) + l % 100), float(std::sin(1.3 * t) + l / 100),
                         float(0.2 * t));
      lines.attributes[0].values.push_back(float(std::sin(t)));
    }
    lines.end_line();
  }
  return lines;
}

bool same_bytes(const TubeMesh& a, const TubeMesh& b) {
  if (a.chunks.size() != b.chunks.size()) return false;
  const auto eq = [](const auto& x, const auto& y) {
    return x.size() == y.size() && (x.empty() || std::memcmp(x.data(), y.data(), x.bytes()) == 0);
  };
  for (size_t i = 0; i < a.chunks.size(); ++i) {
    const TubeChunk &x = a.chunks[i], &y = b.chunks[i];
    if (!eq(x.positions, y.positions) || !eq(x.normals, y.normals) ||
        !eq(x.normals_oct, y.normals_oct) || !eq(x.attribute, y.attribute) ||
        !eq(x.indices, y.indices) || x.first_line != y.first_line)
      return false;
  }
  return true;
}

TEST(Tubes, SameBytesForAnyThreadCount) {
  const LineSet lines = many_lines();
  ASSERT_GT(lines.line_count(), 4096u * 2);  // several progress batches
  TubeOptions o;
  o.caps = true;
  TubeMesh one, two;
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    one = build_tubes(lines, o);
  }
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
    two = build_tubes(lines, o);
  }
  EXPECT_TRUE(same_bytes(one, two));
  EXPECT_EQ(one.triangle_count(), 2 * 3 * (lines.segment_count() - one.points_skipped) +
                                      2 * 3 * (lines.line_count() - one.lines_dropped));
}

// A small index limit stands in for 2^32: chunks split at line boundaries, each within the limit,
// and together they are the unsplit mesh with indices rebased.
TEST(Tubes, ChunksSplitAtLineBoundariesUnderTheLimits) {
  const LineSet lines = many_lines();
  TubeOptions o;
  const TubeMesh whole = build_tubes(lines, o);
  ASSERT_EQ(whole.chunks.size(), 1u);
  for (int limit_kind = 0; limit_kind < 2; ++limit_kind) {
    TubeOptions small = o;
    if (limit_kind == 0)
      small.max_chunk_indices = 60000;
    else
      small.max_chunk_bytes = 1 << 20;
    const TubeMesh split = build_tubes(lines, small);
    ASSERT_GT(split.chunks.size(), 3u);
    uint64_t next_line = 0, vertex_offset = 0, index_offset = 0;
    for (const TubeChunk& c : split.chunks) {
      EXPECT_EQ(c.first_line, next_line);
      next_line += c.line_count;
      EXPECT_LE(c.indices.size(), small.max_chunk_indices);
      EXPECT_LE(c.bytes(), small.max_chunk_bytes);
      for (uint64_t i = 0; i < c.indices.size(); ++i)
        ASSERT_EQ(uint64_t(c.indices[i]) + vertex_offset,
                  whole.chunks[0].indices[index_offset + i]);
      EXPECT_EQ(
          std::memcmp(c.positions.data(), whole.chunks[0].positions.data() + 3 * vertex_offset,
                      c.positions.bytes()),
          0);
      vertex_offset += c.vertex_count();
      index_offset += c.indices.size();
    }
    EXPECT_EQ(next_line, lines.line_count());
    EXPECT_EQ(vertex_offset, whole.vertex_count());
    EXPECT_EQ(index_offset, whole.chunks[0].indices.size());
  }
  TubeOptions tiny = o;
  tiny.max_chunk_indices = 10;  // smaller than one line
  EXPECT_THROW(build_tubes(lines, tiny), Error);
}

}  // namespace
}  // namespace linebake
