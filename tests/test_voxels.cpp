// Voxelizer: hand-computed chords for straight lines, quantisation bounds, kept line ends,
// overflow, determinism.

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstring>

#include "core/error.hpp"
#include "lines/line_reader.hpp"
#include "lines/line_set.hpp"
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
  EXPECT_THROW(parse_grid("12x3", o), UsageError);
  // Numbers outside 1..4096, each said as such (0 had meant auto; 5 digits and more were "not
  // N"; 5000 passed the parse and failed the bake with exit 4).
  parse_grid("4096x1x4096", o);
  EXPECT_EQ(*o.resolution, (std::array<uint32_t, 3>{4096, 1, 4096}));
  for (const char* bad : {"0", "4097", "5000", "100000", "0x4x4", "4x4x99999999999999999999"}) {
    try {
      parse_grid(bad, o);
      ADD_FAILURE() << bad;
    } catch (const UsageError& e) {
      EXPECT_NE(std::string(e.what()).find("is outside 1..4096"), std::string::npos) << e.what();
    }
  }
  // NxNxN past a grid's 2^32 - 1 voxels is known from the option: a usage error (it had been a
  // BudgetExceeded, exit 4, once the data was read). 4096 x 1024 x 1023 = 4,290,772,992 fits.
  parse_grid("4096x1024x1023", o);
  try {
    parse_grid("2048x2048x1024", o);
    ADD_FAILURE();
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("--grid: 2048x2048x1024 is 4294967296 voxels, more than "
                                         "the 2^32 - 1 a grid may hold"),
              std::string::npos)
        << e.what();
  }
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

// Collects voxel ranges merged by several builders into whole-grid arrays.
class CollectingSink : public VoxelSink {
 public:
  std::vector<uint32_t> offsets, chords;
  std::vector<uint8_t> line_counts;
  std::vector<float> density;
  void begin(const VoxelGrid&, uint64_t) override {}
  void voxels(uint64_t first, uint64_t count, const uint32_t* o, const uint8_t* lc, const float* d,
              const uint32_t* c, uint64_t chord_count) override {
    if (offsets.size() < first + count) {
      offsets.resize(first + count), line_counts.resize(first + count);
      density.resize(first + count);
    }
    std::copy_n(o, count, offsets.begin() + long(first));
    std::copy_n(lc, count, line_counts.begin() + long(first));
    std::copy_n(d, count, density.begin() + long(first));
    if (chord_count == 0) return;
    const uint64_t at = 2 * uint64_t(o[0]);
    if (chords.size() < at + 2 * chord_count) chords.resize(at + 2 * chord_count);
    std::copy_n(c, 2 * chord_count, chords.begin() + long(at));
  }
  void end(const VoxelGrid&, uint32_t, std::vector<Array<float>>) override {}
};

// A rank's piece of a wave comes sorted by unit, not by voxel within a unit (each unit's records
// run by run, in line order): a piece inside one unit whose last voxel is the lower is taken
// (it had been refused as out of order), one whose units go down is not.
TEST(Voxels, AReceivedPieceInOneUnitNeedNotBeSortedByVoxel) {
  LineSet lines;
  for (int i = 0; i < 50; ++i) lines.append_point(float(i), float(i * 7 % 50), float(i * 13 % 50));
  lines.end_line();
  VoxelOptions o;
  o.grid = 40;
  VoxelStreamBuilder b(lines, compute_stats(lines), o);
  const uint64_t unit = b.unit_voxels();
  ASSERT_GE(unit, 4u);
  ASSERT_GT(b.description().voxel_count(), 5 * unit);
  const auto piece = [](std::initializer_list<uint32_t> voxels) {
    Array<VoxelRecord> buffer(voxels.size());
    size_t i = 0;
    for (const uint32_t v : voxels) buffer[i++] = VoxelRecord{v, 0, 0, 1.0f};
    return buffer;
  };
  const uint32_t u3 = uint32_t(3 * unit), u4 = uint32_t(4 * unit);
  b.receive_records(piece({u3 + 3, u3 + 1}), {2});
  b.receive_records(piece({u3 + 2, u4 + 1, u4}), {1, 2});
  EXPECT_THROW(b.receive_records(piece({u4 + 1, u3 + 2}), {2}), Error);
  b.adopt_received();
  EXPECT_EQ(b.unit_records()[3], 3u);
  EXPECT_EQ(b.unit_records()[4], 2u);
}

// What linebake-mpi does with three ranks, in one process: each "rank" walks a third of the
// lines, the records go to the owners of z slabs in two waves, each owner merges its slab in two
// pieces, and the tallies and level 1 sums are combined. The grid must equal voxelize()'s bit for
// bit: chords, offsets, line counts, every density level and the statistics.
TEST(Voxels, DistributedBuildEqualsTheSerialOne) {
  LineSet lines;
  for (int l = 0; l < 900; ++l) {
    for (int i = 0; i < 40; ++i) {
      const double t = 0.2 * i + 0.013 * l;
      lines.append_point(float(std::cos(t) * (1 + l % 7)), float(std::sin(1.3 * t) * 3),
                         float(0.1 * t + l % 5));
    }
    lines.end_line();
  }
  std::vector<float> a(lines.point_count());
  for (size_t i = 0; i < a.size(); ++i) a[i] = float(i % 97);
  lines.attributes.push_back({"a", a});
  VoxelOptions o;
  o.grid = 40;
  o.max_chords_per_voxel = 6;
  const VoxelGrid serial = voxelize(lines, o);
  ASSERT_GT(serial.chords_dropped, 0u);

  const LineSetStats stats = compute_stats(lines);
  const uint64_t line_cuts[4] = {0, 250, 610, 900};
  std::vector<std::unique_ptr<VoxelStreamBuilder>> ranks;
  for (int r = 0; r < 3; ++r) {
    ranks.push_back(std::make_unique<VoxelStreamBuilder>(lines, stats, o));
    ranks[size_t(r)]->start_at_line(line_cuts[r]);
    LineSet part = header_of(lines);
    copy_lines(lines, size_t(line_cuts[r]), size_t(line_cuts[r + 1]), part);
    ranks[size_t(r)]->add(part);
  }
  const VoxelGrid& grid = ranks[0]->description();
  const uint64_t voxels = grid.voxel_count();
  const uint64_t slab = 2 * uint64_t(grid.resolution[0]) * grid.resolution[1];
  ASSERT_GT(grid.resolution[2], 8u);
  // Owners of z slabs (not at unit boundaries), and two waves cut elsewhere.
  const uint64_t owners[4] = {0, 2 * slab, 3 * slab, voxels};
  const uint64_t waves[3] = {0, 5 * slab / 2 + 17, voxels};
  for (int w = 0; w < 2; ++w)
    for (int owner = 0; owner < 3; ++owner) {
      const uint64_t v0 = std::max(waves[w], owners[owner]);
      const uint64_t v1 = std::min(waves[w + 1], owners[owner + 1]);
      std::vector<VoxelRecord> incoming;
      std::vector<uint64_t> counts;
      for (auto& sender : ranks) {
        const size_t before = incoming.size();
        if (v0 < v1) sender->append_records(v0, v1, incoming);
        counts.push_back(incoming.size() - before);
      }
      // Kept beside the owner's own records, which it still sends from in the next wave.
      Array<VoxelRecord> buffer(incoming.size());
      std::copy(incoming.begin(), incoming.end(), buffer.begin());
      ranks[size_t(owner)]->receive_records(std::move(buffer), counts);
    }
  CollectingSink sink;
  Array<float> level1 = zero_level1_sums(grid);
  VoxelTallies tallies;
  uint64_t chords_before = 0;
  for (int owner = 0; owner < 3; ++owner) {
    VoxelStreamBuilder& b = *ranks[size_t(owner)];
    b.adopt_received();
    const uint64_t first = owners[owner], end = owners[owner + 1];
    const uint64_t kept = b.kept_chords(first, end);
    Array<float> mine = zero_level1_sums(grid);
    const uint64_t middle = first + (end - first) / 3;
    uint64_t merged = b.merge(sink, first, middle, chords_before, mine);
    merged += b.merge(sink, middle, end, chords_before + merged, mine);
    EXPECT_EQ(merged, kept);
    chords_before += merged;
    for (uint64_t i = 0; i < level1.size(); ++i) level1[i] += mine[i];
    tallies.add(b.tallies());
  }
  ranks[0]->set_statistics(tallies);
  const VoxelGrid& merged = ranks[0]->description();
  sink.offsets.push_back(uint32_t(chords_before));
  ASSERT_EQ(sink.offsets.size(), serial.offsets.size());
  EXPECT_EQ(std::memcmp(sink.offsets.data(), serial.offsets.data(), serial.offsets.bytes()), 0);
  ASSERT_EQ(sink.chords.size(), serial.chords.size());
  EXPECT_EQ(std::memcmp(sink.chords.data(), serial.chords.data(), serial.chords.bytes()), 0);
  EXPECT_EQ(std::memcmp(sink.line_counts.data(), serial.line_counts.data(), voxels), 0);
  EXPECT_EQ(std::memcmp(sink.density.data(), serial.density[0].data(), 4 * voxels), 0);
  const std::vector<Array<float>> levels = density_levels(grid, std::move(level1));
  ASSERT_EQ(levels.size() + 1, serial.density.size());
  ASSERT_EQ(serial.density.size(), grid.density_level_count());
  for (size_t l = 0; l < levels.size(); ++l)
    EXPECT_EQ(std::memcmp(levels[l].data(), serial.density[l + 1].data(), levels[l].bytes()), 0)
        << "level " << l + 1;
  EXPECT_EQ(merged.voxels_occupied, serial.voxels_occupied);
  EXPECT_EQ(merged.voxels_overflowed, serial.voxels_overflowed);
  EXPECT_EQ(merged.chords_dropped, serial.chords_dropped);
  EXPECT_EQ(merged.max_error, serial.max_error);
  EXPECT_EQ(merged.mean_error, serial.mean_error);
}

}  // namespace
}  // namespace linebake
