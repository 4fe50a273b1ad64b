// Voxelizer: hand-computed chords for straight lines, quantisation bounds, kept line ends,
// overflow, determinism.

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstring>

#include "core/error.hpp"
#include "voxels/voxelizer.hpp"

namespace linebake {
namespace {

LineSet polyline(const std::vector<std::array<float, 3>>& points) {
  LineSet lines;
  for (const auto& p : points) lines.append_point(p[0], p[1], p[2]);
  lines.end_line();
  return lines;
}

// A frame of 8 corner points (a second line) pins the bounding box to [0, 8]^3, so with a
// 8-voxel grid voxel (i, j, k) spans [i, i+1] x [j, j+1] x [k, k+1] up to the 1e-6 padding.
LineSet in_unit_grid(std::vector<std::array<float, 3>> points) {
  LineSet lines = polyline(points);
  lines.append_point(0, 0, 0);
  lines.append_point(8, 8, 8);
  lines.end_line();
  return lines;
}

VoxelOptions grid8(uint32_t q = 32) {
  VoxelOptions o;
  o.grid = 8;
  o.quantization = q;
  o.attribute = "none";
  return o;
}

struct Chord {
  uint64_t voxel;
  DecodedChord decoded;
  uint32_t start_face, end_face;
};

std::vector<Chord> chords_of_line(const VoxelGrid& g, uint32_t line_bits) {
  std::vector<Chord> out;
  for (uint64_t v = 0; v < g.voxel_count(); ++v)
    for (uint32_t i = g.offsets[v]; i < g.offsets[v + 1]; ++i) {
      const uint32_t w0 = g.chords[2 * i], w1 = g.chords[2 * i + 1];
      const DecodedChord d = unpack_chord(w0, w1, g.quantization);
      if (d.line_bits == line_bits) out.push_back({v, d, w0 & 7, (w0 >> 3) & 7});
    }
  return out;
}

TEST(Voxels, AutomaticResolution) {
  EXPECT_EQ(automatic_grid_resolution(1000), 64u);       // cbrt 10 -> 16 -> 32 -> clamp 64
  EXPECT_EQ(automatic_grid_resolution(100000), 128u);    // cbrt 46.4 -> 64 -> 128
  EXPECT_EQ(automatic_grid_resolution(39600000), 512u);  // cbrt 341 -> 512 -> 1024 -> 512
  VoxelOptions o;
  parse_grid("113x110x128", o);
  EXPECT_EQ(*o.resolution, (std::array<uint32_t, 3>{113, 110, 128}));
  parse_grid("256", o);
  EXPECT_EQ(o.grid, 256u);
  EXPECT_FALSE(o.resolution);
  EXPECT_THROW(parse_grid("12x3", o), Error);
}

TEST(Voxels, GridCoversTheBoundsWithCubicVoxels) {
  LineSet lines = polyline({{0, 0, 0}, {16, 4, 2}});
  VoxelOptions o;
  o.grid = 64;
  const VoxelGrid g = voxelize(lines, o);
  EXPECT_EQ(g.resolution, (std::array<uint32_t, 3>{64, 16, 8}));
  EXPECT_NEAR(g.voxel_size, 0.25, 1e-5);
  EXPECT_NEAR(g.origin[0], 0, 1e-4);
}

// Along x at y = z = 3.45: voxels (1..4, 3, 3), entering at the -x face and leaving at the +x
// face, both at face cell (14, 14) of 32 (0.45 * 32 = 14.4); the ends are inside.
TEST(Voxels, StraightLineAlongAnAxis) {
  const VoxelGrid g = voxelize(in_unit_grid({{1.3f, 3.45f, 3.45f}, {4.7f, 3.45f, 3.45f}}), grid8());
  ASSERT_EQ(g.resolution, (std::array<uint32_t, 3>{8, 8, 8}));
  const auto chords = chords_of_line(g, 0);
  ASSERT_EQ(chords.size(), 4u);
  for (uint32_t i = 0; i < 4; ++i) {
    EXPECT_EQ(chords[i].voxel, g.index(1 + i, 3, 3));
    EXPECT_EQ(chords[i].start_face, i == 0 ? kInteriorFace : 0u);  // -x face
    EXPECT_EQ(chords[i].end_face, i == 3 ? kInteriorFace : 1u);    // +x face
    // Decoded at cell centres: 16.5/32 on the face; the interior ends at their own cells.
    EXPECT_NEAR(chords[i].decoded.start[1], 14.5 / 32, 1e-6);
    EXPECT_NEAR(chords[i].decoded.end[2], 14.5 / 32, 1e-6);
    if (i > 0) {
      EXPECT_EQ(chords[i].decoded.start[0], 0.0f);  // on the -x face
    }
    if (i < 3) {
      EXPECT_EQ(chords[i].decoded.end[0], 1.0f);  // on the +x face
    }
  }
  // Line ends are kept: x = 0.3 and 0.7 inside their voxels (cells 9 and 22 of 32).
  EXPECT_NEAR(chords[0].decoded.start[0], 9.5 / 32, 1e-6);
  EXPECT_NEAR(chords[3].decoded.end[0], 22.5 / 32, 1e-6);
  EXPECT_EQ(g.chords_dropped, 0u);
}

// The diagonal from (0.5,0.5,0.5) to (2.5,2.5,2.5) goes through voxel corners; the walker
// steps one axis at a time and drops the zero-length pieces, so it visits exactly the three
// diagonal voxels.
TEST(Voxels, DiagonalLineThroughCorners) {
  const VoxelGrid g = voxelize(in_unit_grid({{0.5f, 0.5f, 0.5f}, {2.5f, 2.5f, 2.5f}}), grid8());
  const auto chords = chords_of_line(g, 0);
  ASSERT_EQ(chords.size(), 3u);
  for (uint32_t i = 0; i < 3; ++i) EXPECT_EQ(chords[i].voxel, g.index(i, i, i));
  // The middle chord runs corner to corner of its voxel.
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(chords[1].decoded.start[k], 0.0, 1.0 / 32);
    EXPECT_NEAR(chords[1].decoded.end[k], 1.0, 1.0 / 32);
  }
}

// A general direction: (0.2, 0.3, 0.1) -> (3.7, 1.9, 2.6) crosses x = 1, 2, 3, y = 1 and
// z = 1, 2: 1 + 3 + 1 + 2 = 7 voxels.
TEST(Voxels, GeneralSegmentVisitsEveryCrossedVoxel) {
  const VoxelGrid g = voxelize(in_unit_grid({{0.2f, 0.3f, 0.1f}, {3.7f, 1.9f, 2.6f}}), grid8());
  const auto chords = chords_of_line(g, 0);
  ASSERT_EQ(chords.size(), 7u);
  // Crossing parameters along the segment, by hand: x at t = 0.8/3.5, 1.8/3.5, 2.8/3.5
  // (0.229, 0.514, 0.8), y at t = 0.7/1.6 (0.4375), z at t = 0.9/2.5, 1.9/2.5 (0.36, 0.76).
  // Order: x(0.229) z(0.36) y(0.4375) x(0.514) z(0.76) x(0.8).
  const std::array<std::array<uint32_t, 3>, 7> cells{
      {{0, 0, 0}, {1, 0, 0}, {1, 0, 1}, {1, 1, 1}, {2, 1, 1}, {2, 1, 2}, {3, 1, 2}}};
  std::vector<uint64_t> voxels;
  for (const Chord& c : chords) voxels.push_back(c.voxel);
  for (const auto& cell : cells)
    EXPECT_NE(std::find(voxels.begin(), voxels.end(), g.index(cell[0], cell[1], cell[2])),
              voxels.end())
        << cell[0] << " " << cell[1] << " " << cell[2];
}

TEST(Voxels, QuantisationErrorIsBoundedByCellOverQ) {
  for (uint32_t q : {16u, 32u, 64u}) {
    // Straight lines: the chord is exact up to quantisation, so the error is within the
    // half-diagonal of a face cell, sqrt(2) / (2Q) < 1 / Q (interior ends: coarser w for Q 64).
    LineSet lines = in_unit_grid({{0.13f, 0.71f, 0.37f}, {7.61f, 5.29f, 6.93f}});
    lines.append_point(7.9f, 0.1f, 0.2f);
    lines.append_point(0.3f, 7.7f, 7.1f);
    lines.end_line();
    const VoxelGrid g = voxelize(lines, grid8(q));
    EXPECT_GT(g.max_error, 0);
    EXPECT_LT(g.max_error, (q == 64 ? 1.0 / 32 : 1.0 / q) + 1e-6) << "Q " << q;
    EXPECT_LE(g.mean_error, g.max_error);
  }
}

TEST(Voxels, LineEndsInsideOneVoxelAreKept) {
  // A short line wholly inside voxel (5, 5, 5).
  const VoxelGrid g = voxelize(in_unit_grid({{5.2f, 5.3f, 5.4f}, {5.8f, 5.6f, 5.5f}}), grid8());
  const auto chords = chords_of_line(g, 0);
  ASSERT_EQ(chords.size(), 1u);
  EXPECT_EQ(chords[0].voxel, g.index(5, 5, 5));
  EXPECT_EQ(chords[0].start_face, kInteriorFace);
  EXPECT_EQ(chords[0].end_face, kInteriorFace);
  EXPECT_NEAR(chords[0].decoded.start[0], 0.2, 1.0 / 32);
  EXPECT_NEAR(chords[0].decoded.end[1], 0.6, 1.0 / 32);
}

TEST(Voxels, OverflowIsCountedAndTheFirstLinesKept) {
  LineSet lines;
  for (int l = 0; l < 40; ++l) {  // 40 lines up the column of voxels (4, 2, z)
    lines.append_point(4.1f + 0.02f * float(l), 2.5f, 0.5f);
    lines.append_point(4.1f + 0.02f * float(l), 2.5f, 7.5f);
    lines.end_line();
  }
  lines.append_point(0, 0, 0);
  lines.append_point(8, 8, 8);
  lines.end_line();
  VoxelOptions o = grid8();
  o.max_chords_per_voxel = 32;
  const VoxelGrid g = voxelize(lines, o);
  const uint64_t v = g.index(4, 2, 4);
  EXPECT_EQ(g.offsets[v + 1] - g.offsets[v], 32u);
  EXPECT_EQ(g.voxels_overflowed, 8u);  // z = 0..7 along the column
  EXPECT_EQ(g.chords_dropped, 8u * 8);
  EXPECT_EQ(g.line_counts[v], 40);
  // Kept in line order: lines 0..31.
  for (uint32_t i = 0; i < 32; ++i)
    EXPECT_EQ(
        unpack_chord(g.chords[2 * (g.offsets[v] + i)], g.chords[2 * (g.offsets[v] + i) + 1], 32)
            .line_bits,
        i);
}

TEST(Voxels, AttributesAndDensity) {
  LineSet lines = in_unit_grid({{0.5f, 0.5f, 0.5f}, {3.5f, 0.5f, 0.5f}});
  lines.attributes.push_back({"t", {0, 3, 0, 0}});
  VoxelOptions o = grid8();
  o.attribute = "t";
  o.attribute_range = std::array<float, 2>{0, 3};
  const VoxelGrid g = voxelize(lines, o);
  const auto chords = chords_of_line(g, 0);
  ASSERT_EQ(chords.size(), 4u);
  // Attribute 0 -> 3 linearly along x = 0.5 .. 3.5: at x = 1, 2, 3 it is 0.5, 1.5, 2.5, i.e.
  // unorm8 42.5, 127.5, 212.5 (rounding may go either way at exactly .5).
  EXPECT_EQ(chords[0].decoded.attribute_start, 0);
  EXPECT_NEAR(chords[0].decoded.attribute_end, 42.5, 0.5);
  EXPECT_NEAR(chords[1].decoded.attribute_end, 127.5, 0.5);
  EXPECT_NEAR(chords[2].decoded.attribute_end, 212.5, 0.5);
  EXPECT_EQ(chords[3].decoded.attribute_end, 255);
  // Density: length in voxel units x mean normalised attribute. Voxel (1,0,0): length 1,
  // attribute 0.5 .. 1.5 of 3 -> mean 1/3.
  EXPECT_NEAR(g.density[0][g.index(1, 0, 0)], 1.0 / 3, 2.0 / 255);
  // Mip levels down to one voxel; level 1 averages 2x2x2.
  ASSERT_EQ(g.density.size(), 4u);  // 8, 4, 2, 1
  double sum0 = 0;
  for (float d : g.density[0]) sum0 += d;
  EXPECT_NEAR(g.density[3][0] * 512, sum0, 1e-3);
}

TEST(Voxels, SameBytesForAnyThreadCount) {
  LineSet lines;
  for (int l = 0; l < 3000; ++l) {
    for (int i = 0; i < 30; ++i) {
      const double t = 0.2 * i + 0.01 * l;
      lines.append_point(float(std::cos(t) * (1 + l % 7)), float(std::sin(1.3 * t) * 3),
                         float(0.1 * t + l % 5));
    }
    lines.end_line();
  }
  lines.attributes.push_back({"a", std::vector<float>(lines.point_count(), 0.5f)});
  VoxelOptions o;
  o.grid = 48;
  o.max_chords_per_voxel = 8;  // exercise the cap as well
  VoxelGrid one, two;
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
    one = voxelize(lines, o);
  }
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 2);
    two = voxelize(lines, o);
  }
  ASSERT_GT(one.chords_dropped, 0u);
  EXPECT_EQ(one.chords_dropped, two.chords_dropped);
  ASSERT_EQ(one.chords.size(), two.chords.size());
  EXPECT_EQ(std::memcmp(one.chords.data(), two.chords.data(), one.chords.bytes()), 0);
  EXPECT_EQ(std::memcmp(one.offsets.data(), two.offsets.data(), one.offsets.bytes()), 0);
  EXPECT_EQ(std::memcmp(one.density[0].data(), two.density[0].data(), one.density[0].bytes()), 0);
  EXPECT_EQ(one.max_error, two.max_error);
  EXPECT_EQ(one.mean_error, two.mean_error);
}

}  // namespace
}  // namespace linebake
