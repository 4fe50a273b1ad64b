// Voxel grid through the cache (bit-exact) and through OpenVDB (read back with OpenVDB).

#include <gtest/gtest.h>
#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>

#include <cmath>
#include <cstring>
#include <fstream>

#include "cache/voxel_store.hpp"
#include "core/error.hpp"
#include "formats/vdb.hpp"
#include "test_util.hpp"
#include "voxels/voxelizer.hpp"

namespace linebake {
namespace {

LineSet wavy_lines() {
  LineSet lines;
  lines.attributes.push_back({"speed", {}});
  for (int l = 0; l < 200; ++l) {
    for (int i = 0; i < 40; ++i) {
      const double t = 0.15 * i;
      lines.append_point(float(t + 0.05 * l), float(std::sin(t + l) * 2),
                         float(std::cos(0.7 * t) + 0.01 * l));
      lines.attributes[0].values.push_back(float(i % 9));
    }
    lines.end_line();
  }
  return lines;
}

template <class A>
bool same(const A& a, const A& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.bytes()) == 0);
}

TEST(VoxelStore, CacheRoundTripIsBitExact) {
  test::TempDir dir;
  VoxelOptions o;
  o.grid = 40;
  o.max_chords_per_voxel = 6;
  const VoxelGrid g = voxelize(wavy_lines(), o);
  ASSERT_GT(g.chords_dropped, 0u);
  for (const char* c : {"none", "lz4"}) {
    const std::string path = dir.file(std::string(c) + ".lbc.h5");
    {
      CacheWriter writer(path, parse_compression(c));
      Provenance p;
      p.step = "voxels";
      store_voxels(writer, g, p);
      writer.commit();
    }
    const VoxelGrid back = load_voxels(CacheReader(path));
    EXPECT_EQ(back.resolution, g.resolution);
    EXPECT_EQ(back.origin, g.origin);
    EXPECT_EQ(back.voxel_size, g.voxel_size);
    EXPECT_EQ(back.attribute_range, g.attribute_range);
    EXPECT_EQ(back.chords_dropped, g.chords_dropped);
    EXPECT_EQ(back.max_error, g.max_error);
    EXPECT_TRUE(same(back.offsets, g.offsets));
    EXPECT_TRUE(same(back.chords, g.chords));
    EXPECT_TRUE(same(back.line_counts, g.line_counts));
    ASSERT_EQ(back.density.size(), g.density.size());
    for (size_t l = 0; l < g.density.size(); ++l) EXPECT_TRUE(same(back.density[l], g.density[l]));
    EXPECT_EQ(CacheReader(path).provenance(kVoxelsGroup)->memory_bytes, g.representation_bytes());
  }
}

// OpenVDB's transforms cannot hold voxels smaller than about 1.45e-5 units: such a grid is
// refused naming its voxel size, before anything is written; voxels of 2e-5 are written.
TEST(VoxelStore, VoxelsTooSmallForOpenVdbAreRefusedNamingTheirSize) {
  test::TempDir dir;
  for (const auto& [span, refused] : {std::pair(1e-5, true), std::pair(2e-5, false)}) {
    SCOPED_TRACE(span);
    LineSet lines = wavy_lines();
    float lo = lines.positions[0], hi = lo;
    for (float p : lines.positions) lo = std::min(lo, p), hi = std::max(hi, p);
    // Scaled so that the largest extent, 32 voxels, spans 32 x `span`.
    for (float& p : lines.positions) p = float(double(p) * 32 * span / double(hi - lo));
    VoxelOptions o;
    o.grid = 32;
    const VoxelGrid g = voxelize(lines, o);
    const std::string path = dir.file("small.vdb");
    if (!refused) {
      EXPECT_LT(std::abs(g.voxel_size / span - 1), 0.2) << g.voxel_size;
      write_vdb(path, g);
      EXPECT_TRUE(std::filesystem::exists(path));
      continue;
    }
    try {
      write_vdb(path, g);
      ADD_FAILURE() << "written";
    } catch (const OutputError& e) {
      char size[32];
      std::snprintf(size, sizeof size, "%.3g", g.voxel_size);  // about 8.9e-6: the grid's margin
      EXPECT_NE(std::string(e.what()).find(std::string("OpenVDB cannot hold voxels of ") + size +
                                           " units"),
                std::string::npos)
          << e.what();
    }
    EXPECT_FALSE(std::filesystem::exists(path));
  }
}

// The VDB read back with OpenVDB itself: every grid a FloatGrid (what pyopenvdb and Blender
// read), the same active voxels, values against the grid they came from.
TEST(VoxelStore, VdbRoundTrip) {
  test::TempDir dir;
  VoxelOptions o;
  o.grid = 32;
  const VoxelGrid g = voxelize(wavy_lines(), o);
  ASSERT_FALSE(g.attribute.empty());
  write_vdb(dir.file("g.vdb"), g);
  openvdb::initialize();
  openvdb::io::File file(dir.file("g.vdb"));
  file.open();
  const auto meta = file.getMetadata();
  const double scale = meta->metaValue<double>("linebake_density_scale");
  auto grid = [&](const char* name) {
    return openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid(name));
  };
  auto density = grid("density"), weighted = grid("attribute_density"), count = grid("line_count"),
       attribute = grid("attribute_chord_max");
  file.close();
  ASSERT_TRUE(density && weighted && count && attribute);
  EXPECT_EQ(density->getGridClass(), openvdb::GRID_FOG_VOLUME);
  for (const auto& v : {density, weighted, count})
    EXPECT_EQ(v->activeVoxelCount(), g.voxels_occupied);
  uint64_t checked = 0, saturated = 0;
  auto d = density->getConstAccessor();
  auto w = weighted->getConstAccessor();
  auto n = count->getConstAccessor();
  auto a = attribute->getConstAccessor();
  for (uint32_t z = 0; z < g.resolution[2]; ++z)
    for (uint32_t y = 0; y < g.resolution[1]; ++y)
      for (uint32_t x = 0; x < g.resolution[0]; ++x) {
        const uint64_t v = g.index(x, y, z);
        const openvdb::Coord ijk{int(x), int(y), int(z)};
        ASSERT_EQ(n.isValueOn(ijk), g.line_counts[v] > 0);
        if (!g.line_counts[v]) continue;
        double length = 0;  // of the voxel's chords, in voxel units
        for (uint32_t c = g.offsets[v]; c < g.offsets[v + 1]; ++c) {
          const DecodedChord k = unpack_chord(g.chords[2 * c], g.chords[2 * c + 1], g.quantization);
          length += std::hypot(k.end[0] - k.start[0], k.end[1] - k.start[1], k.end[2] - k.start[2]);
        }
        EXPECT_NEAR(d.getValue(ijk), std::min(1.0, length / scale), 1e-5);
        saturated += d.getValue(ijk) == 1.0f;
        EXPECT_EQ(w.getValue(ijk), g.density[0][v]);
        EXPECT_EQ(n.getValue(ijk), float(g.line_counts[v]));
        EXPECT_GE(a.getValue(ijk), g.attribute_range[0]);
        EXPECT_LE(a.getValue(ijk), g.attribute_range[1] + 1e-5f);
        ++checked;
      }
  EXPECT_EQ(checked, g.voxels_occupied);
  // The scale is the 99th percentile: about 1 % of the voxels saturate.
  EXPECT_GE(saturated, 1u);
  EXPECT_LE(saturated, checked / 50 + 1);
  // Index (i, j, k) is the centre of our voxel (i, j, k) in world space.
  const openvdb::Vec3d centre = density->transform().indexToWorld(openvdb::Coord(3, 5, 7));
  EXPECT_NEAR(centre[0], g.origin[0] + 3.5 * g.voxel_size, 1e-5);
  EXPECT_NEAR(centre[1], g.origin[1] + 5.5 * g.voxel_size, 1e-5);
  EXPECT_NEAR(centre[2], g.origin[2] + 7.5 * g.voxel_size, 1e-5);
}

std::string file_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

std::string store(const test::TempDir& dir, const VoxelGrid& g, const char* compression) {
  const std::string path = dir.file(std::string("g-") + compression + ".lbc.h5");
  CacheWriter writer(path, parse_compression(compression));
  Provenance p;
  p.step = "voxels";
  store_voxels(writer, g, p);
  writer.commit();
  return path;
}

// The VDB of a cached grid read a piece at a time, in blocks and runs smaller than the grid (down
// to one voxel, and runs whose room is less than one voxel's chords), is the VDB of the grid in
// memory, to the byte.
TEST(VoxelStore, VdbFromCachePiecesIsTheGridsVdb) {
  test::TempDir dir;
  VoxelOptions o;
  o.grid = 40;
  const VoxelGrid g = voxelize(wavy_lines(), o);
  uint32_t most = 0;  // chords in one voxel
  for (uint64_t v = 0; v < g.voxel_count(); ++v)
    most = std::max(most, g.offsets[v + 1] - g.offsets[v]);
  ASSERT_GT(most, 3u);
  ASSERT_GT(g.voxel_count(), 4096u);
  write_vdb(dir.file("memory.vdb"), g);
  const std::string whole = file_bytes(dir.file("memory.vdb"));
  for (const char* compression : {"none", "lz4"}) {
    const CacheReader cache(store(dir, g, compression));
    for (const VdbPieces sizes : {VdbPieces{}, VdbPieces{1000, 50}, VdbPieces{4096, 2},
                                  VdbPieces{1, 1}, VdbPieces{g.voxel_count() + 7, 1000000}}) {
      write_vdb(dir.file("pieces.vdb"), *voxel_pieces(cache), sizes);
      EXPECT_EQ(file_bytes(dir.file("pieces.vdb")), whole)
          << compression << ", blocks of " << sizes.voxels << ", runs of " << sizes.chords;
    }
  }
}

// A cached grid whose chords or offsets were damaged: the export stops naming the dataset, and
// leaves no file. A flipped chord is found by its hash once read whole; a flipped offset by the
// offsets' order or, where it stays in order, by the hash.
TEST(VoxelStore, VdbOfADamagedCacheIsRefusedAndWritesNothing) {
  VoxelOptions o;
  o.grid = 40;
  const VoxelGrid g = voxelize(wavy_lines(), o);
  for (const char* dataset : {"/assets/voxels/chords", "/assets/voxels/offsets",
                              "/assets/voxels/line_counts", "/assets/voxels/density_0"}) {
    test::TempDir dir;
    const std::string path = store(dir, g, "none");
    test::flip_byte(path, test::data_offset(path, dataset));
    const CacheReader cache(path);
    try {
      write_vdb(dir.file("out.vdb"), *voxel_pieces(cache));
      ADD_FAILURE() << dataset << ": no error";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("dataset " + std::string(dataset)), std::string::npos)
          << e.what();
    }
    EXPECT_EQ(dir.entries().size(), 1u) << dataset;  // the cache alone: no VDB, no temporary
  }
}

// A grid without an attribute has no attribute grids, and its density level 0 is not read:
// still the in-memory grid's bytes.
TEST(VoxelStore, VdbFromCachePiecesWithoutAnAttribute) {
  test::TempDir dir;
  VoxelOptions o;
  o.grid = 40;
  o.attribute = "none";
  const VoxelGrid g = voxelize(wavy_lines(), o);
  ASSERT_TRUE(g.attribute.empty());
  write_vdb(dir.file("memory.vdb"), g);
  const CacheReader cache(store(dir, g, "lz4"));
  write_vdb(dir.file("pieces.vdb"), *voxel_pieces(cache), VdbPieces{1000, 50});
  EXPECT_EQ(file_bytes(dir.file("pieces.vdb")), file_bytes(dir.file("memory.vdb")));
}

// The export sizes its memory by the description's count of voxels holding lines: a cache whose
// line counts hold more (or fewer) is refused, naming the group, with nothing written.
TEST(VoxelStore, VdbOfACacheWhoseDescriptionMiscountsItsVoxelsIsRefused) {
  VoxelOptions o;
  o.grid = 40;
  VoxelGrid g = voxelize(wavy_lines(), o);
  for (const uint64_t occupied : {uint64_t{5}, g.voxels_occupied + 1}) {
    test::TempDir dir;
    VoxelGrid told = g;
    told.voxels_occupied = occupied;
    const CacheReader cache(store(dir, told, "none"));
    try {
      write_vdb(dir.file("out.vdb"), *voxel_pieces(cache));
      ADD_FAILURE() << occupied << ": no error";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("group /assets/voxels: its description says " +
                                           std::to_string(occupied) + " voxels hold lines"),
                std::string::npos)
          << e.what();
    }
    EXPECT_EQ(dir.entries().size(), 1u);
  }
}

// What export checks against --memory-budget: OpenVDB's trees at most, counted by leaves.
TEST(VoxelStore, VdbBuildBytesCountLeavesAtMostOnePerActiveVoxel) {
  VoxelGrid g;
  g.resolution = {64, 64, 64};  // 512 leaves of 8^3, one internal node of each kind
  g.attribute = "speed";
  g.voxels_occupied = 100000;
  const uint64_t full = vdb_build_bytes(g);
  g.voxels_occupied = 10;
  const uint64_t sparse = vdb_build_bytes(g);
  // 502 leaves fewer in each of the 4 grids, 8 bytes of length fewer a voxel, and a tenth more.
  EXPECT_EQ(full - sparse, (4 * 502 * 2200 + 8 * 99990) * 11 / 10);
  g.attribute.clear();  // two grids
  EXPECT_LT(vdb_build_bytes(g), sparse);
}

// OpenVDB's writer puts a random UUID in the header; write_vdb replaces it with one made from
// the file's other bytes, so the same grid gives the same bytes, and another grid another UUID.
TEST(VoxelStore, TheSameGridGivesTheSameVdbBytes) {
  test::TempDir dir;
  VoxelOptions o;
  o.grid = 32;
  const VoxelGrid g = voxelize(wavy_lines(), o);
  write_vdb(dir.file("a.vdb"), g);
  write_vdb(dir.file("b.vdb"), g);
  o.grid = 31;
  write_vdb(dir.file("c.vdb"), voxelize(wavy_lines(), o));
  const auto bytes = [&](const char* name) {
    std::ifstream in(dir.file(name), std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  const std::string a = bytes("a.vdb"), c = bytes("c.vdb");
  EXPECT_EQ(a, bytes("b.vdb"));
  const std::string uuid = a.substr(21, 36), other = c.substr(21, 36);
  EXPECT_NE(uuid, other);
  for (const std::string& u : {uuid, other}) {
    EXPECT_EQ(u.size(), 36u);
    EXPECT_EQ(u[14], '8') << u;  // version 8 (RFC 9562)
    EXPECT_NE(std::string("89ab").find(u[19]), std::string::npos) << u;
    EXPECT_EQ(u.find_first_not_of("0123456789abcdef-"), std::string::npos) << u;
  }
  // OpenVDB reads it and reports that UUID.
  openvdb::initialize();
  openvdb::io::File file(dir.file("a.vdb"));
  file.open();
  EXPECT_EQ(file.getUniqueTag(), uuid);
  EXPECT_TRUE(file.readGrid("density"));
  file.close();
}

}  // namespace
}  // namespace linebake
