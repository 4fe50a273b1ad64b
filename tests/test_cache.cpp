// Asset cache: bit-exact round trips for every compression, zero-copy loads, integrity checks,
// and bake's reuse of unchanged steps.

#include <gtest/gtest.h>
#include <hdf5.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <thread>

#include "cache/embree_store.hpp"
#include "cache/group_copy.hpp"
#include "cache/line_store.hpp"
#include "cache/tube_store.hpp"
#include "core/error.hpp"
#include "core/measure.hpp"
#include "formats/registry.hpp"
#include "pipeline/bake.hpp"
#include "pipeline/report.hpp"
#include "test_util.hpp"

namespace linebake {
namespace {

// The mapping of this process that holds `p` (/proc/self/smaps): its start, the file it maps
// ("" for anonymous memory) and its resident bytes.
struct Mapping {
  uintptr_t start = 0;
  std::string path;
  uint64_t rss_bytes = 0;
};
Mapping mapping_of(const void* p) {
  std::ifstream smaps("/proc/self/smaps");
  std::string line;
  bool inside = false;
  Mapping m;
  while (std::getline(smaps, line)) {
    uintptr_t begin = 0, end = 0;
    char dash = 0;
    std::istringstream head(line);
    if (head >> std::hex >> begin >> dash >> end && dash == '-') {
      if (inside) break;
      inside = uintptr_t(p) >= begin && uintptr_t(p) < end;
      if (inside) {
        m.start = begin;
        std::string perms, offset, device, inode;
        head >> perms >> offset >> device >> inode;
        std::getline(head >> std::ws, m.path);
      }
    } else if (inside && line.rfind("Rss:", 0) == 0) {
      m.rss_bytes = std::stoull(line.substr(4)) * 1024;
    }
  }
  if (m.path.rfind('[', 0) == 0) m.path.clear();  // [heap], [anon:...]
  return m;
}

using test::quiet_bake;
using test::TempDir;

LineSet curly_lines(int count) {
  LineSet lines;
  lines.attributes.push_back({"speed", {}});
  lines.line_attributes.push_back({"seed/id %", {}});
  for (int l = 0; l < count; ++l) {
    const int points = 2 + (l * 31) % 17;
    for (int i = 0; i < points; ++i) {
      const double t = 0.4 * i + 0.01 * l;
      lines.append_point(float(std::cos(t) + l % 10), float(std::sin(t) + l / 10), float(0.3 * t));
      lines.attributes[0].values.push_back(float(t * t));
    }
    lines.line_attributes[0].values.push_back(float(l));
    lines.end_line();
  }
  lines.metadata["units"] = "m";
  return lines;
}

template <class A>
bool same_array(const A& a, const A& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.bytes()) == 0);
}

void expect_same_mesh(const TubeMesh& a, const TubeMesh& b) {
  EXPECT_EQ(a.sides, b.sides);
  EXPECT_EQ(a.radius, b.radius);
  EXPECT_EQ(a.normals, b.normals);
  EXPECT_EQ(a.attribute, b.attribute);
  EXPECT_EQ(a.attribute_range, b.attribute_range);
  ASSERT_EQ(a.chunks.size(), b.chunks.size());
  for (size_t c = 0; c < a.chunks.size(); ++c) {
    EXPECT_EQ(a.chunks[c].first_line, b.chunks[c].first_line);
    EXPECT_EQ(a.chunks[c].line_count, b.chunks[c].line_count);
    EXPECT_TRUE(same_array(a.chunks[c].positions, b.chunks[c].positions));
    EXPECT_TRUE(same_array(a.chunks[c].normals, b.chunks[c].normals));
    EXPECT_TRUE(same_array(a.chunks[c].normals_oct, b.chunks[c].normals_oct));
    EXPECT_TRUE(same_array(a.chunks[c].attribute, b.chunks[c].attribute));
    EXPECT_TRUE(same_array(a.chunks[c].indices, b.chunks[c].indices));
  }
}

Provenance provenance_for(const std::string& step) {
  Provenance p;
  p.step = step;
  p.key = "k";
  p.input_hash = "h";
  return p;
}

void write_cache(const std::string& path, const LineSet& lines, const TubeMesh& mesh,
                 Compression compression) {
  CacheWriter writer(path, compression);
  store_lines(writer, lines, provenance_for("lines"));
  store_tubes(writer, mesh, provenance_for("tubes"));
  writer.commit();
}

class CacheRoundTrip : public ::testing::TestWithParam<const char*> {};

TEST_P(CacheRoundTrip, BitExact) {
  TempDir dir;
  const Compression compression = parse_compression(GetParam());
  const LineSet lines = curly_lines(300);
  for (NormalEncoding normals : {NormalEncoding::Float32, NormalEncoding::Oct16}) {
    TubeOptions o;
    o.normals = normals;
    o.max_chunk_bytes = 64 * 1024;  // several chunks
    const TubeMesh mesh = build_tubes(lines, o);
    ASSERT_GT(mesh.chunks.size(), 2u);
    const std::string path = dir.file("c.lbc.h5");
    write_cache(path, lines, mesh, compression);
    const CacheReader cache(path);
    const LineSet back = load_lines(cache);
    EXPECT_TRUE(back.same_data(lines));
    EXPECT_EQ(back.metadata, lines.metadata);
    EXPECT_EQ(content_hash(back), content_hash(lines));
    const TubeMesh loaded = load_tubes(cache);
    expect_same_mesh(mesh, loaded);
    const auto p = cache.provenance(kTubesGroup);
    ASSERT_TRUE(p);
    EXPECT_EQ(p->memory_bytes, mesh.bytes());
    if (compression == Compression::None) {
      // Zero-copy: the arrays are views of one mapping of the file.
      const Mapping a = mapping_of(loaded.chunks[0].positions.data());
      EXPECT_EQ(a.path, std::filesystem::canonical(path).string());
      EXPECT_EQ(a.start, mapping_of(loaded.chunks[1].indices.data()).start);
      EXPECT_GE(p->disk_bytes, mesh.bytes());
    } else {
      EXPECT_NE(loaded.chunks[0].positions.owner(), loaded.chunks[1].indices.owner());
      EXPECT_TRUE(mapping_of(loaded.chunks[0].positions.data()).path.empty());
      EXPECT_LT(p->disk_bytes, mesh.bytes());  // curly lines compress
    }
  }
  EXPECT_EQ(dir.entries().size(), 1u);  // no temporary left behind
}

INSTANTIATE_TEST_SUITE_P(Compressions, CacheRoundTrip,
                         ::testing::Values("none", "deflate", "lz4", "blosc-zstd"));

void expect_input_error(const std::function<void()>& f, const std::string& part1,
                        const std::string& part2) {
  try {
    f();
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(part1), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(part2), std::string::npos) << e.what();
  }
}

class CacheCorruption : public ::testing::TestWithParam<const char*> {};

TEST_P(CacheCorruption, FlippedByteIsDetectedAndNamed) {
  TempDir dir;
  const LineSet lines = curly_lines(50);
  const TubeMesh mesh = build_tubes(lines, {});
  const std::string path = dir.file("c.lbc.h5");
  write_cache(path, lines, mesh, parse_compression(GetParam()));
  const std::string dataset = "/assets/tubes/chunk_000000/positions";
  test::flip_byte(path, test::data_offset(path, dataset));
  const CacheReader cache(path);
  EXPECT_NO_THROW(load_lines(cache));  // other datasets are fine
  expect_input_error([&] { load_tubes(cache); }, path, "dataset " + dataset);
}

INSTANTIATE_TEST_SUITE_P(Compressions, CacheCorruption,
                         ::testing::Values("none", "deflate", "lz4", "blosc-zstd"));

TEST(Cache, TruncatedFileIsAnError) {
  TempDir dir;
  const LineSet lines = curly_lines(200);
  const TubeMesh mesh = build_tubes(lines, {});
  for (const char* compression : {"none", "lz4"}) {
    const std::string path = dir.file(std::string("c-") + compression + ".lbc.h5");
    write_cache(path, lines, mesh, parse_compression(compression));
    const auto size = std::filesystem::file_size(path);
    std::filesystem::resize_file(path, size / 2);
    try {
      const CacheReader cache(path);
      load_lines(cache);
      load_tubes(cache);
      ADD_FAILURE() << "truncated cache loaded";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos);
    }
  }
}

TEST(Cache, ForeignFilesAreRefused) {
  TempDir dir;
  test::write_text(dir.file("text.lbc.h5"), "not hdf5 at all");
  expect_input_error([&] { CacheReader(dir.file("text.lbc.h5")); }, "text.lbc.h5", "not an HDF5");
  write_line_set(curly_lines(3), dir.file("lines.h5"));  // HDF5, but a line set
  expect_input_error([&] { CacheReader(dir.file("lines.h5")); }, "lines.h5",
                     "not a linebake cache");
  expect_input_error([&] { CacheReader(dir.file("missing.lbc.h5")); }, "missing", "no such");
  CacheWriter writer(dir.file("empty.lbc.h5"), Compression::None);
  writer.commit();
  const CacheReader empty(dir.file("empty.lbc.h5"));
  expect_input_error([&] { load_tubes(empty); }, "empty.lbc.h5", "no tube mesh");
}

TEST(Cache, LinkNamesRoundTrip) {
  for (const std::string name : {"plain", "a/b", "100%", ".hidden", "", "x%2Fy"}) {
    const std::string encoded = encode_link_name(name);
    EXPECT_EQ(encoded.find('/'), std::string::npos);
    EXPECT_NE(encoded, ".");
    EXPECT_EQ(decode_link_name(encoded), name);
  }
}

// HDF5 prints its error stacks from each thread unless told not to on that thread: a reader
// opened on one thread and read on another (a Python thread, TBB's) must leave that one quiet.
TEST(Cache, AThreadReadingACacheGetsNoHdf5Printing) {
  TempDir dir;
  BakeOptions o;
  write_line_set(curly_lines(10), dir.file("in.binlines"));
  o.input = dir.file("in.binlines");
  o.cache = dir.file("in.lbc.h5");
  o.progress = false;
  bake(o);
  const CacheReader cache(o.cache);
  testing::internal::CaptureStderr();
  std::thread reader([&] {
    EXPECT_TRUE(cache.exists("/lines"));
    // A failing HDF5 call on this thread, after the read: printed unless the read quietened it.
    const hid_t file = H5Fopen(o.cache.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    EXPECT_LT(H5Dopen2(file, "/no/such/dataset", H5P_DEFAULT), 0);
    H5Fclose(file);
  });
  reader.join();
  EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
}

// --- bake ---

BakeOptions small_bake(const TempDir& dir) {
  write_line_set(curly_lines(120), dir.file("in.obj"));
  BakeOptions o;
  o.input = dir.file("in.obj");
  o.cache = dir.file("in.lbc.h5");
  o.progress = false;
  return o;
}

TEST(Bake, UnchangedStepsAreNotRebuilt) {
  TempDir dir;
  BakeOptions o = small_bake(dir);
  BakeResult first = bake(o);
  ASSERT_EQ(first.steps.size(), 2u);
  EXPECT_TRUE(first.written);
  EXPECT_TRUE(first.steps[0].built && first.steps[1].built);
  const auto stamp = std::filesystem::last_write_time(o.cache);

  BakeResult again = bake(o);
  EXPECT_FALSE(again.written);
  EXPECT_FALSE(again.steps[0].built || again.steps[1].built);
  EXPECT_EQ(std::filesystem::last_write_time(o.cache), stamp);
  EXPECT_EQ(again.steps[1].provenance.key, first.steps[1].provenance.key);

  o.tubes.sides = 5;  // new parameters: tubes rebuilt from the cached lines
  BakeResult changed = bake(o);
  EXPECT_TRUE(changed.written);
  EXPECT_FALSE(changed.steps[0].built);
  EXPECT_TRUE(changed.steps[1].built);
  EXPECT_EQ(load_tubes(CacheReader(o.cache)).sides, 5);

  o.force = true;
  BakeResult forced = bake(o);
  EXPECT_TRUE(forced.steps[0].built && forced.steps[1].built);

  o.force = false;
  LineSet other = curly_lines(121);  // new input bytes: everything rebuilt
  write_line_set(other, o.input);
  BakeResult fresh = bake(o);
  EXPECT_TRUE(fresh.steps[0].built && fresh.steps[1].built);
  EXPECT_TRUE(load_lines(CacheReader(o.cache)).same_data(read_line_set(o.input)));
  EXPECT_EQ(dir.entries().size(), 2u);  // input and cache, no temporaries
}

TEST(Bake, ProvenanceRecordsTheBuild) {
  TempDir dir;
  BakeOptions o = small_bake(dir);
  o.compression = Compression::Deflate;
  bake(o);
  const CacheReader cache(o.cache);
  const auto lines = cache.provenance("/lines");
  const auto tubes = cache.provenance(kTubesGroup);
  ASSERT_TRUE(lines && tubes);
  const LineSet stored = load_lines(cache);
  EXPECT_EQ(tubes->input_hash, content_hash(stored));
  EXPECT_EQ(lines->stats["segments"].get<uint64_t>(), stored.segment_count());
  EXPECT_EQ(tubes->parameters["sides"], 3);
  EXPECT_EQ(tubes->linebake_version, LINEBAKE_VERSION);
  EXPECT_EQ(tubes->compression, "deflate");
  const TubeMesh mesh = load_tubes(cache);
  EXPECT_EQ(tubes->memory_bytes, mesh.bytes());
  uint64_t disk = 0;
  for (size_t c = 0; c < mesh.chunks.size(); ++c)
    for (const char* d : {"positions", "normals", "attribute", "indices"})
      disk += cache.stored_bytes("/assets/tubes/chunk_00000" + std::to_string(c) + "/" + d);
  EXPECT_EQ(tubes->disk_bytes, disk);
  EXPECT_GT(tubes->build.wall_s, 0);
  EXPECT_GE(tubes->build.peak_rss, tubes->build.rss_before);
  EXPECT_GT(tubes->build.peak_rss, 0u);
  EXPECT_EQ(tubes->stats["triangles"].get<uint64_t>(), mesh.triangle_count());
}

TEST(Bake, EmbreeBuffersRoundTripAndRebuildToTheSameScene) {
  TempDir dir;
  BakeOptions o = small_bake(dir);
  o.assets = {"tubes", "embree"};
  const BakeResult first = bake(o);
  ASSERT_EQ(first.steps.size(), 3u);
  EXPECT_TRUE(first.steps[2].built);
  const CacheReader cache(o.cache);
  const auto p = cache.provenance(kEmbreeGroup);
  ASSERT_TRUE(p);
  const LineSet lines = load_lines(cache);
  EXPECT_EQ(p->stats["primitives"].get<uint64_t>(), lines.segment_count());
  EXPECT_EQ(p->memory_bytes,
            p->stats["buffer_bytes"].get<uint64_t>() + p->stats["bvh_bytes"].get<uint64_t>());
  EXPECT_GT(p->stats["bvh_bytes"].get<uint64_t>(), 0u);
  // The curves share the tubes' radius, and the stored buffers are what a fresh build prepares.
  const StoredCurves stored = load_embree(cache);
  EXPECT_FLOAT_EQ(stored.radius, load_tubes(cache).radius);
  const EmbreeScene fresh = EmbreeScene::from_lines(lines, stored.radius, stored.attribute, {});
  const auto parts = fresh.prepared_curves();
  ASSERT_EQ(parts.size(), stored.parts.size());
  for (size_t i = 0; i < parts.size(); ++i) {
    EXPECT_TRUE(std::equal(parts[i].vertices.begin(), parts[i].vertices.end(),
                           stored.parts[i].vertices.begin(), stored.parts[i].vertices.end()));
    EXPECT_TRUE(std::equal(parts[i].indices.begin(), parts[i].indices.end(),
                           stored.parts[i].indices.begin(), stored.parts[i].indices.end()));
    EXPECT_TRUE(std::equal(parts[i].flags.begin(), parts[i].flags.end(),
                           stored.parts[i].flags.begin(), stored.parts[i].flags.end()));
  }
  EXPECT_FALSE(bake(o).steps[2].built);  // unchanged: reused
  o.embree.quality = BuildQuality::High;
  EXPECT_TRUE(bake(o).steps[2].built);
}

// Arrays read from an uncompressed cache are views of its mapping. When the last copy of a view
// goes its pages leave the process's resident set (the memory budget counts resident memory, and
// a mesh already uploaded would count against it for the reader's life); read again, the views
// give the same bytes.
TEST(Cache, MappedViewsGiveTheirPagesBackWhenTheyGo) {
  TempDir dir;
  BakeOptions o = quiet_bake(dir, "synth:aneurysm?scale=0.05", "none.lbc.h5");
  o.compression = Compression::None;
  bake(o);
  const CacheReader cache(o.cache);
  const auto sum_of = [](const TubeMesh& mesh) {
    double sum = 0;
    for (const TubeChunk& chunk : mesh.chunks) {
      for (float x : chunk.positions) sum += x;
      for (float x : chunk.normals) sum += x;
      for (uint16_t a : chunk.attribute) sum += a;
      for (uint32_t i : chunk.indices) sum += i;
    }
    return sum;
  };
  uint64_t bytes = 0;
  double sum = 0;
  Mapping held;
  {
    const TubeMesh mesh = load_tubes(cache);
    bytes = mesh.bytes();
    ASSERT_GT(bytes, 8u << 20);
    sum = sum_of(mesh);
    held = mapping_of(mesh.chunks[0].indices.data());
    ASSERT_EQ(held.path, std::filesystem::canonical(o.cache).string());
    EXPECT_GE(held.rss_bytes, bytes / 10 * 9);
  }
  const Mapping let_go = mapping_of(reinterpret_cast<const void*>(held.start));
  EXPECT_EQ(let_go.start, held.start);
  EXPECT_LT(let_go.rss_bytes, 1u << 20);
  EXPECT_EQ(sum_of(load_tubes(cache)), sum);
}

// bake builds the Embree BVH where its estimate (the line set and three times the buffers) fits
// the budget, held by Embree's memory monitor to what the budget leaves beside the line set.
// The estimate errs low here (the BVH's peak is about three times the buffers, beside them), so
// of budgets swept upward the first that the estimate passes is refused by the monitor: the cache
// is complete, its buffers are those of an unlimited bake, and the provenance and the notes say
// render builds the BVH. A budget with room builds it.
TEST(Bake, EmbreeBvhAtBakeStaysWithinTheBudget) {
  TempDir dir;
  BakeOptions o = quiet_bake(dir, "synth:aneurysm?scale=0.05", "unlimited.lbc.h5");
  o.assets = {"embree"};
  o.memory_budget = BakeOptions::kUnlimited;
  bake(o);
  uint64_t buffers = 0, peak = 0;
  {
    const CacheReader cache(o.cache);
    const auto p = cache.provenance(kEmbreeGroup);
    buffers = p->stats["buffer_bytes"].get<uint64_t>();
    peak = p->stats["bvh_peak_bytes"].get<uint64_t>();
  }
  ASSERT_GT(peak, 2 * buffers) << "the estimate no longer errs low; the sweep tests nothing";
  const StoredCurves unlimited = load_embree(CacheReader(o.cache));
  // From the least budget bake takes (what the process holds and 32 MiB to work in) upward, in
  // steps of a quarter of what the estimate misses.
  bool monitored = false, built = false;
  const uint64_t step = (peak - 2 * buffers) / 4;
  for (int k = 0; k < 200 && !built; ++k) {
    o.cache = dir.file("b" + std::to_string(k) + ".lbc.h5");
    o.memory_budget = current_rss_bytes() + (33u << 20) + uint64_t(k) * step;
    BakeResult result;
    try {
      result = bake(o);
    } catch (const BudgetExceeded&) {
      continue;  // too little for the line set's own steps
    }
    const CacheReader cache(o.cache);
    const auto p = cache.provenance(kEmbreeGroup);
    ASSERT_TRUE(p);
    const StoredCurves stored = load_embree(cache);
    ASSERT_EQ(stored.parts.size(), unlimited.parts.size());
    EXPECT_TRUE(std::equal(stored.parts[0].vertices.begin(), stored.parts[0].vertices.end(),
                           unlimited.parts[0].vertices.begin(), unlimited.parts[0].vertices.end()));
    if (p->stats.contains("bvh_bytes")) {
      built = true;
      EXPECT_EQ(p->memory_bytes, buffers + p->stats["bvh_bytes"].get<uint64_t>());
      continue;
    }
    const std::string why = p->stats["bvh"].get<std::string>();
    EXPECT_EQ(p->memory_bytes, buffers);
    EXPECT_NE(std::find(result.notes.begin(), result.notes.end(), "embree: " + why),
              result.notes.end());
    if (why.rfind("not built at bake: Embree's BVH over ", 0) == 0) {
      monitored = true;
      EXPECT_NE(why.find("; render builds it"), std::string::npos) << why;
    } else {
      EXPECT_EQ(why.rfind("not built at bake: the line set, buffers and BVH need about ", 0), 0u)
          << why;
      EXPECT_FALSE(monitored) << "the estimate refused a budget larger than one it passed";
    }
  }
  EXPECT_TRUE(monitored);
  EXPECT_TRUE(built);
}

// The one rule for where a bake writes, which bake() and the callers that lock its output
// (the CLI's report, Python's) share: Python had locked <stem>.lbc.lbc.h5 for a cache baked in
// place, in the working directory.
// Steps built in one pass over the data say so: their peak is the pass's, and tubes and voxels,
// built side by side, overlap in time (the report marks their cells). A step built alone does
// not (the lines' pass, which plans the tubes, is the lines' own).
TEST(Bake, StepsBuiltInOnePassSaySo) {
  TempDir dir;
  BakeOptions o = quiet_bake(dir, "synth:aneurysm?scale=0.002", "a.lbc.h5");
  bake(o);
  {
    const CacheReader cache(o.cache);
    EXPECT_TRUE(cache.provenance("/lines")->build.built_with.empty());
    EXPECT_TRUE(cache.provenance("/assets/tubes")->build.built_with.empty());
    EXPECT_EQ(report_table_note({summarize_cache(cache)}), "");
  }
  o.assets = {"tubes", "voxels"};
  o.tubes.sides = 4;  // the tubes again, beside the voxels
  bake(o);
  const CacheReader cache(o.cache);
  EXPECT_EQ(cache.provenance("/assets/tubes")->build.built_with,
            std::vector<std::string>{"voxels"});
  EXPECT_EQ(cache.provenance("/assets/voxels")->build.built_with,
            std::vector<std::string>{"tubes"});
  const std::vector<CacheSummary> summary{summarize_cache(cache)};
  EXPECT_EQ(report_table_note(summary).rfind("* tubes, voxels: built from the same batches", 0), 0u)
      << report_table_note(summary);
  EXPECT_NE(report_markdown(summary).find(" ms * |"), std::string::npos)
      << report_markdown(summary);
  // Escaped in Markdown: a line that starts "* " would be a list item, its mark gone.
  EXPECT_NE(report_markdown(summary).find("\n\\* tubes, voxels: "), std::string::npos)
      << report_markdown(summary);
}

TEST(Bake, TheOutputPathIsOneRuleForEveryCaller) {
  TempDir dir;
  BakeOptions o = quiet_bake(dir, "synth:aneurysm?scale=0.002", "a.lbc.h5");
  bake(o);
  BakeOptions in_place;
  in_place.input = o.cache;
  EXPECT_EQ(bake_output_path(in_place), o.cache);
  in_place.cache = dir.file("b.lbc.h5");
  EXPECT_EQ(bake_output_path(in_place), dir.file("b.lbc.h5"));
  BakeOptions file;
  file.input = dir.file("run/traj.binlines");
  EXPECT_EQ(bake_output_path(file), "traj.lbc.h5");
  BakeOptions synthetic;
  synthetic.input = "synth:clouds?scale=0.1";
  EXPECT_EQ(bake_output_path(synthetic), "clouds.lbc.h5");
  BakeOptions several;
  several.inputs = {dir.file("a.binlines"), dir.file("b.binlines")};
  EXPECT_EQ(bake_output_path(several), "");
}

TEST(Bake, BadInputLeavesTheOldCacheAlone) {
  TempDir dir;
  BakeOptions o = small_bake(dir);
  bake(o);
  const auto size = std::filesystem::file_size(o.cache);
  test::write_text(o.input, "v 1 2 3\nl 1 9\n");  // index out of range
  o.on_invalid = InvalidPolicy::reject;
  EXPECT_THROW(bake(o), InputError);
  EXPECT_EQ(std::filesystem::file_size(o.cache), size);
  EXPECT_EQ(dir.entries().size(), 2u);
}

}  // namespace
}  // namespace linebake

namespace linebake {

// copy_group_tree against h5py-free expectations: a source written here with the C API (nested
// groups tracking creation order, a chunked deflated dataset, a contiguous one copied in slabs
// of 1,000 bytes, a scalar, a chunked dataset of variable-length strings, a soft and an external
// link, a committed datatype, a variable-length string attribute and a fixed one) reads back the
// same values, chunks stored the same bytes, members and attributes in the same order. A
// dataset of references is refused.
TEST(GroupCopy, EveryObjectAndAttributeArrivesAsStored) {
  test::TempDir dir;
  const std::string from = dir.file("from.h5"), to = dir.file("to.h5");
  {
    const hid_t f = H5Fcreate(from.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    const hid_t gcpl = H5Pcreate(H5P_GROUP_CREATE);
    H5Pset_link_creation_order(gcpl, H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED);
    H5Pset_attr_creation_order(gcpl, H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED);
    const hid_t top = H5Gcreate2(f, "/assets", H5P_DEFAULT, gcpl, H5P_DEFAULT);
    const hid_t g = H5Gcreate2(top, "tubes", H5P_DEFAULT, gcpl, H5P_DEFAULT);
    const hid_t sub = H5Gcreate2(g, "zeta", H5P_DEFAULT, gcpl, H5P_DEFAULT);
    const hid_t sub2 = H5Gcreate2(g, "alpha", H5P_DEFAULT, gcpl, H5P_DEFAULT);
    std::vector<float> values(3000);
    for (size_t i = 0; i < values.size(); ++i) values[i] = float(i) * 0.5f;
    const hsize_t dims[2] = {1000, 3}, chunk[2] = {256, 3};
    const hid_t space = H5Screate_simple(2, dims, nullptr);
    const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    H5Pset_chunk(dcpl, 2, chunk);
    H5Pset_deflate(dcpl, 6);
    const hid_t chunked =
        H5Dcreate2(sub, "positions", H5T_NATIVE_FLOAT, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
    H5Dwrite(chunked, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data());
    const hid_t plain =
        H5Dcreate2(sub2, "normals", H5T_NATIVE_FLOAT, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    H5Dwrite(plain, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data());
    const hid_t scalar_space = H5Screate(H5S_SCALAR);
    const hid_t scalar =
        H5Dcreate2(g, "count", H5T_STD_U64LE, scalar_space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    const uint64_t count = 1234567;
    H5Dwrite(scalar, H5T_NATIVE_UINT64, H5S_ALL, H5S_ALL, H5P_DEFAULT, &count);
    const hid_t vstr = H5Tcopy(H5T_C_S1);
    H5Tset_size(vstr, H5T_VARIABLE);
    const char* text = "{\"step\": \"tubes\"}";
    const hid_t a1 = H5Acreate2(g, "provenance", vstr, scalar_space, H5P_DEFAULT, H5P_DEFAULT);
    H5Awrite(a1, vstr, &text);
    const hid_t fixed = H5Tcopy(H5T_C_S1);
    H5Tset_size(fixed, 3);
    const hid_t a2 = H5Acreate2(g, "b_format", fixed, scalar_space, H5P_DEFAULT, H5P_DEFAULT);
    H5Awrite(a2, fixed, "v42");
    // Variable-length strings in chunks: their chunks hold ids into this file's heap.
    const hsize_t two = 2;
    const hid_t notes_space = H5Screate_simple(1, &two, nullptr);
    const hid_t notes_dcpl = H5Pcreate(H5P_DATASET_CREATE);
    H5Pset_chunk(notes_dcpl, 1, &two);
    const hid_t notes =
        H5Dcreate2(g, "notes", vstr, notes_space, H5P_DEFAULT, notes_dcpl, H5P_DEFAULT);
    const char* lines[2] = {"first", "second"};
    H5Dwrite(notes, vstr, H5S_ALL, H5S_ALL, H5P_DEFAULT, lines);
    H5Lcreate_soft("/assets/tubes/count", g, "soft", H5P_DEFAULT, H5P_DEFAULT);
    // A group linked twice, and the group linked into itself: copied once, linked again.
    H5Lcreate_hard(g, "zeta", g, "again", H5P_DEFAULT, H5P_DEFAULT);
    H5Lcreate_hard(f, "/assets/tubes", g, "loop", H5P_DEFAULT, H5P_DEFAULT);
    // Chunks of arrays of two variable-length strings.
    const hsize_t pair = 2;
    const hid_t pairs_type = H5Tarray_create2(vstr, 1, &pair);
    const hid_t pairs =
        H5Dcreate2(g, "pairs", pairs_type, notes_space, H5P_DEFAULT, notes_dcpl, H5P_DEFAULT);
    const char* words[4] = {"a", "bb", "ccc", "dddd"};
    H5Dwrite(pairs, pairs_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, words);
    H5Dclose(pairs);
    H5Tclose(pairs_type);
    H5Lcreate_external("other.h5", "/x", g, "elsewhere", H5P_DEFAULT, H5P_DEFAULT);
    const hid_t kind = H5Tcopy(H5T_NATIVE_INT16);
    H5Tcommit2(g, "kind", kind, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    H5Tclose(kind);
    H5Dclose(notes);
    H5Sclose(notes_space);
    H5Pclose(notes_dcpl);
    for (hid_t id : {a1, a2}) H5Aclose(id);
    for (hid_t id : {vstr, fixed}) H5Tclose(id);
    for (hid_t id : {chunked, plain, scalar}) H5Dclose(id);
    for (hid_t id : {space, scalar_space}) H5Sclose(id);
    for (hid_t id : {dcpl, gcpl}) H5Pclose(id);
    for (hid_t id : {sub, sub2, g, top}) H5Gclose(id);
    H5Fclose(f);
  }
  {
    const hid_t source = H5Fopen(from.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    const hid_t target = H5Fcreate(to.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    H5Gclose(H5Gcreate2(target, "/assets", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT));
    copy_group_tree(source, from, target, to, "/assets/tubes", 1000);
    H5Fclose(target);
    H5Fclose(source);
  }
  const hid_t a = H5Fopen(from.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  const hid_t b = H5Fopen(to.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  // Members in creation order: zeta before alpha, then count.
  const auto members = [](hid_t f) {
    const hid_t g = H5Gopen2(f, "/assets/tubes", H5P_DEFAULT);
    std::vector<std::string> names;
    for (hsize_t i = 0; i < 3; ++i) {
      char name[64] = {};
      H5Lget_name_by_idx(g, ".", H5_INDEX_CRT_ORDER, H5_ITER_INC, i, name, sizeof name,
                         H5P_DEFAULT);
      names.push_back(name);
    }
    H5Gclose(g);
    return names;
  };
  EXPECT_EQ(members(b), (std::vector<std::string>{"zeta", "alpha", "count"}));
  EXPECT_EQ(members(a), members(b));
  const auto floats = [](hid_t f, const char* path) {
    std::vector<float> v(3000, -1.0f);
    const hid_t d = H5Dopen2(f, path, H5P_DEFAULT);
    EXPECT_GE(H5Dread(d, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()), 0) << path;
    H5Dclose(d);
    return v;
  };
  for (const char* path : {"/assets/tubes/zeta/positions", "/assets/tubes/alpha/normals"}) {
    const std::vector<float> v = floats(b, path);
    EXPECT_EQ(v, floats(a, path)) << path;
    EXPECT_EQ(v[2999], 1499.5f) << path;
  }
  // The chunked dataset's chunks stored as they were: the same filter and the same bytes.
  const auto stored = [](hid_t f) {
    const hid_t d = H5Dopen2(f, "/assets/tubes/zeta/positions", H5P_DEFAULT);
    const hsize_t offset[2] = {512, 0};
    hsize_t size = 0;
    H5Dget_chunk_storage_size(d, offset, &size);
    std::vector<char> bytes(size);
    uint32_t mask = 0;
    H5Dread_chunk(d, H5P_DEFAULT, offset, &mask, bytes.data());
    const hid_t dcpl = H5Dget_create_plist(d);
    const int filters = H5Pget_nfilters(dcpl);
    H5Pclose(dcpl);
    H5Dclose(d);
    return std::make_pair(filters, bytes);
  };
  EXPECT_EQ(stored(b).first, 1);
  EXPECT_EQ(stored(b), stored(a));
  uint64_t count = 0;
  const hid_t scalar = H5Dopen2(b, "/assets/tubes/count", H5P_DEFAULT);
  H5Dread(scalar, H5T_NATIVE_UINT64, H5S_ALL, H5S_ALL, H5P_DEFAULT, &count);
  H5Dclose(scalar);
  EXPECT_EQ(count, 1234567u);
  {
    // Variable-length strings read back through `type` (`n` of them).
    const auto strings = [&](const char* path, hid_t type, size_t n) {
      std::vector<char*> read(n, nullptr);
      const hid_t d = H5Dopen2(b, path, H5P_DEFAULT);
      EXPECT_GE(H5Dread(d, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, read.data()), 0) << path;
      H5Dclose(d);
      std::vector<std::string> out;
      for (char* r : read) {
        out.push_back(r ? r : "");
        H5free_memory(r);
      }
      return out;
    };
    const hid_t vstr = H5Tcopy(H5T_C_S1);
    H5Tset_size(vstr, H5T_VARIABLE);
    EXPECT_EQ(strings("/assets/tubes/notes", vstr, 2),
              (std::vector<std::string>{"first", "second"}));
    const hsize_t pair = 2;
    const hid_t pairs_type = H5Tarray_create2(vstr, 1, &pair);
    const std::vector<std::string> words = strings("/assets/tubes/pairs", pairs_type, 4);
    EXPECT_EQ(words[0], "a");
    EXPECT_EQ(words[3], "dddd");
    H5Tclose(pairs_type);
    H5Tclose(vstr);
    char soft[64] = {};
    ASSERT_GE(H5Lget_val(b, "/assets/tubes/soft", soft, sizeof soft, H5P_DEFAULT), 0);
    EXPECT_STREQ(soft, "/assets/tubes/count");
    H5L_info_t link{};
    ASSERT_GE(H5Lget_info(b, "/assets/tubes/elsewhere", &link, H5P_DEFAULT), 0);
    EXPECT_EQ(link.type, H5L_TYPE_EXTERNAL);
    const auto info_of = [&](const char* path) {
      H5O_info_t info{};
      EXPECT_GE(H5Oget_info_by_name2(b, path, &info, H5O_INFO_BASIC, H5P_DEFAULT), 0) << path;
      return info;
    };
    EXPECT_EQ(info_of("/assets/tubes/kind").type, H5O_TYPE_NAMED_DATATYPE);
    EXPECT_EQ(info_of("/assets/tubes/again").addr, info_of("/assets/tubes/zeta").addr);
    EXPECT_EQ(info_of("/assets/tubes/loop").addr, info_of("/assets/tubes").addr);
  }
  const hid_t g = H5Gopen2(b, "/assets/tubes", H5P_DEFAULT);
  char attribute[64] = {};
  H5Aget_name_by_idx(g, ".", H5_INDEX_CRT_ORDER, H5_ITER_INC, 0, attribute, sizeof attribute,
                     H5P_DEFAULT);
  EXPECT_STREQ(attribute, "provenance");  // created before b_format, though after it by name
  const hid_t a1 = H5Aopen(g, "provenance", H5P_DEFAULT);
  const hid_t vstr = H5Tcopy(H5T_C_S1);
  H5Tset_size(vstr, H5T_VARIABLE);
  char* text = nullptr;
  H5Aread(a1, vstr, &text);
  EXPECT_STREQ(text, "{\"step\": \"tubes\"}");
  H5free_memory(text);
  const hid_t a2 = H5Aopen(g, "b_format", H5P_DEFAULT);
  const hid_t fixed = H5Aget_type(a2);
  char v[4] = {};
  H5Aread(a2, fixed, v);
  EXPECT_STREQ(v, "v42");
  for (hid_t id : {a1, a2}) H5Aclose(id);
  for (hid_t id : {vstr, fixed}) H5Tclose(id);
  H5Gclose(g);
  H5Fclose(a);
  H5Fclose(b);
}

// References point into their own file: a group holding them is refused, naming the dataset.
// Datasets that use a committed datatype use the target's copy of it, as in the source: one
// committed before them (opened there) and one linked after them (committed without a name,
// then linked in its place, the links' creation order kept); a type outside the group copied
// is a copy of the dataset's own. Values and the type's attribute arrive too.
TEST(GroupCopy, DatasetsShareTheirCommittedDatatypes) {
  test::TempDir dir;
  const std::string from = dir.file("from.h5"), to = dir.file("to.h5");
  const std::vector<int16_t> values = {-3, 7, 32000};
  {
    const hid_t f = H5Fcreate(from.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    const hid_t gcpl = H5Pcreate(H5P_GROUP_CREATE);
    H5Pset_link_creation_order(gcpl, H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED);
    const hid_t g = H5Gcreate2(f, "/assets", H5P_DEFAULT, gcpl, H5P_DEFAULT);
    const hsize_t n = values.size();
    const hid_t space = H5Screate_simple(1, &n, nullptr);
    const auto typed = [&](const char* name, hid_t type) {
      const hid_t d = H5Dcreate2(g, name, type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
      H5Dwrite(d, H5T_NATIVE_INT16, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data());
      H5Dclose(d);
    };
    // Committed without a name, used, then linked: the link comes after the dataset's.
    const hid_t late = H5Tcopy(H5T_STD_I16BE);
    H5Tcommit_anon(f, late, H5P_DEFAULT, H5P_DEFAULT);
    const hid_t scalar = H5Screate(H5S_SCALAR);
    const hid_t units = H5Acreate2(late, "units", H5T_NATIVE_INT, scalar, H5P_DEFAULT, H5P_DEFAULT);
    const int unit = 42;
    H5Awrite(units, H5T_NATIVE_INT, &unit);
    H5Aclose(units);
    typed("before", late);
    H5Olink(late, g, "late_kind", H5P_DEFAULT, H5P_DEFAULT);
    const hid_t kind = H5Tcopy(H5T_STD_I16LE);
    H5Tcommit2(g, "kind", kind, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    typed("after", kind);
    typed("again", late);
    const hid_t outside = H5Tcopy(H5T_STD_I32LE);
    H5Tcommit2(f, "/outside_kind", outside, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    typed("foreign", outside);
    for (hid_t id : {late, kind, outside}) H5Tclose(id);
    for (hid_t id : {space, scalar}) H5Sclose(id);
    H5Pclose(gcpl);
    H5Gclose(g);
    H5Fclose(f);
  }
  {
    const hid_t source = H5Fopen(from.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    const hid_t target = H5Fcreate(to.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    copy_group_tree(source, from, target, to, "/assets");
    H5Fclose(target);
    H5Fclose(source);
  }
  const hid_t b = H5Fopen(to.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(b, 0);
  const auto address = [&](const char* path) {
    H5O_info_t info{};
    EXPECT_GE(H5Oget_info_by_name2(b, path, &info, H5O_INFO_BASIC, H5P_DEFAULT), 0) << path;
    return info.addr;
  };
  // Whether the dataset's type is committed, and where; its values.
  const auto type_of = [&](const char* path) {
    const hid_t d = H5Dopen2(b, path, H5P_DEFAULT);
    const hid_t type = H5Dget_type(d);
    H5O_info_t info{};
    const bool committed = H5Tcommitted(type) > 0;
    if (committed) H5Oget_info2(type, &info, H5O_INFO_BASIC);
    std::vector<int16_t> read(values.size(), 0);
    EXPECT_GE(H5Dread(d, H5T_NATIVE_INT16, H5S_ALL, H5S_ALL, H5P_DEFAULT, read.data()), 0) << path;
    EXPECT_EQ(read, values) << path;
    H5Tclose(type);
    H5Dclose(d);
    return committed ? std::optional<haddr_t>(info.addr) : std::nullopt;
  };
  EXPECT_EQ(type_of("/assets/before"), address("/assets/late_kind"));
  EXPECT_EQ(type_of("/assets/again"), address("/assets/late_kind"));
  EXPECT_EQ(type_of("/assets/after"), address("/assets/kind"));
  EXPECT_EQ(type_of("/assets/foreign"), std::nullopt);
  const hid_t late = H5Topen2(b, "/assets/late_kind", H5P_DEFAULT);
  EXPECT_EQ(H5Tget_order(late), H5T_ORDER_BE);
  int unit = 0;
  const hid_t units = H5Aopen(late, "units", H5P_DEFAULT);
  EXPECT_GE(H5Aread(units, H5T_NATIVE_INT, &unit), 0);
  EXPECT_EQ(unit, 42);
  H5Aclose(units);
  H5Tclose(late);
  // The links in the source's creation order.
  const hid_t g = H5Gopen2(b, "/assets", H5P_DEFAULT);
  std::vector<std::string> names;
  for (hsize_t i = 0; i < 5; ++i) {
    char name[64] = {};
    H5Lget_name_by_idx(g, ".", H5_INDEX_CRT_ORDER, H5_ITER_INC, i, name, sizeof name, H5P_DEFAULT);
    names.push_back(name);
  }
  EXPECT_EQ(names, (std::vector<std::string>{"before", "late_kind", "kind", "after", "again"}));
  H5Gclose(g);
  H5Fclose(b);
}

TEST(GroupCopy, ReferencesAreRefused) {
  test::TempDir dir;
  const std::string from = dir.file("from.h5"), to = dir.file("to.h5");
  {
    const hid_t f = H5Fcreate(from.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    const hid_t g = H5Gcreate2(f, "/assets", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    const hid_t scalar = H5Screate(H5S_SCALAR);
    const hid_t refs =
        H5Dcreate2(g, "refs", H5T_STD_REF_OBJ, scalar, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    hobj_ref_t ref{};
    H5Rcreate(&ref, f, "/assets", H5R_OBJECT, -1);
    H5Dwrite(refs, H5T_STD_REF_OBJ, H5S_ALL, H5S_ALL, H5P_DEFAULT, &ref);
    H5Dclose(refs);
    H5Sclose(scalar);
    H5Gclose(g);
    H5Fclose(f);
  }
  const hid_t source = H5Fopen(from.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  const hid_t target = H5Fcreate(to.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  try {
    copy_group_tree(source, from, target, to, "/assets");
    ADD_FAILURE() << "references copied";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where(), "/assets/refs");
  }
  H5Fclose(target);
  H5Fclose(source);
}

}  // namespace linebake
