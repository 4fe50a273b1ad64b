// The streamed bake: the same cache bytes for any memory budget and thread count, spill files
// used and removed, budgets too small for one line refused before anything is written.

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <filesystem>
#include <map>

#include "cache/cache.hpp"
#include "core/error.hpp"
#include "core/measure.hpp"
#include "formats/registry.hpp"
#include "lines/line_reader.hpp"
#include "pipeline/bake.hpp"
#include "pipeline/bake_budget.hpp"
#include "synth/synth.hpp"
#include "test_util.hpp"

namespace linebake {
namespace {

using test::TempDir;

// Every dataset of a cache with its stored XXH3-128 (the hash of its bytes).
std::map<std::string, std::string> dataset_hashes(const std::string& path) {
  const CacheReader cache(path);
  std::map<std::string, std::string> out;
  std::vector<std::string> groups{"/"};
  while (!groups.empty()) {
    const std::string g = groups.back();
    groups.pop_back();
    for (const std::string& name : cache.members(g)) {
      const std::string child = (g == "/" ? "" : g) + "/" + name;
      if (auto hash = cache.attribute(child, "xxh3_128_blocks"))
        out[child] = *hash;
      else
        groups.push_back(child);
    }
  }
  return out;
}

// A budget of `working` bytes on top of what this process holds now: the test process alone is
// larger than a 16 or 64 MiB budget. The bake keeps at least 24 MiB of it for fixed buffers
// (encoded chunks in flight, HDF5), so 40 MiB leaves it 16 MiB to work in, 88 MiB leaves 64.
uint64_t working_budget(uint64_t working) {
  return current_rss_bytes() + working;
}

BakeOptions streamed_options(const std::string& input, const std::string& cache, uint64_t budget) {
  BakeOptions o;
  o.input = input;
  o.cache = cache;
  o.assets = {"tubes", "voxels", "embree"};
  o.tubes.max_chunk_bytes = 1 << 20;  // several tube chunks, so batches cross chunk boundaries
  o.voxels.grid = 64;
  o.memory_budget = budget;
  o.progress = false;
  return o;
}

// The bound the bake reserves every batch's voxel run index by (16 KiB a batch, kept to the
// merge; uncounted, it took turbulence at scale 1.0 under 60M to 84 MiB): at least the batches a
// reader makes, whatever the batch size, and the figure of that bake's refusal by hand
// (17,600,188 points, 100,188 lines of at most 350 points, batches of 11,094: each but the last
// holds at least 10,745 points, so at most 1,638).
TEST(BakeStream, TheBatchBoundHoldsEveryBatchTheReaderMakes) {
  EXPECT_EQ(most_batches(17600188, 100188, 11094, 350), 17600188u / 10745 + 1);
  EXPECT_EQ(most_batches(17600188, 100188, 11094, 350), 1638u);
  EXPECT_EQ(most_batches(1000, 10, 50, 300), 10u);  // lines longer than a batch come alone
  TempDir dir;
  const std::string input = dir.file("b.binlines");
  const LineSet lines = synth::generate({"turbulence", 0.002, 5, false});
  write_line_set(lines, input);
  uint64_t longest = 0;
  for (size_t l = 0; l < lines.line_count(); ++l)
    longest = std::max<uint64_t>(longest, lines.line_size(l));
  for (const uint64_t batch_points :
       {uint64_t{1}, longest / 2, longest, longest + 1, 2 * longest, uint64_t{5000}}) {
    const std::unique_ptr<LineReader> reader = open_line_reader(input);
    LineSet batch;
    uint64_t batches = 0;
    while (reader->next(batch, batch_points)) ++batches;
    const uint64_t bound =
        most_batches(lines.point_count(), lines.line_count(), batch_points, longest);
    EXPECT_GE(bound, batches) << batch_points;
    EXPECT_LE(bound, batches + lines.point_count() / std::max<uint64_t>(batch_points, 1) + 1)
        << batch_points;  // not wildly above it
  }
}

TEST(BakeStream, SameDatasetsForEveryBudgetAndThreadCount) {
  TempDir dir;
  // 792k segments of clouds in a 160-voxel grid: small enough for a test, large enough for many
  // batches and for its chord records (~10 MB) to spill where 16 MiB is all there is.
  const std::string input = dir.file("k.binlines");
  write_line_set(synth::generate({"clouds", 0.02, 3, false}), input);
  std::map<std::string, std::string> reference;
  struct Run {
    uint64_t working;  // 0: unlimited
    int threads;
  };
  for (const Run run :
       {Run{0, 2}, Run{40 << 20, 2}, Run{88 << 20, 2}, Run{40 << 20, 1}, Run{0, 1}}) {
    tbb::global_control threads(tbb::global_control::max_allowed_parallelism, size_t(run.threads));
    const std::string cache =
        dir.file("c" + std::to_string(run.working) + "-" + std::to_string(run.threads) + ".lbc.h5");
    BakeOptions o = streamed_options(
        input, cache, run.working ? working_budget(run.working) : BakeOptions::kUnlimited);
    o.voxels.grid = 160;
    const BakeResult result = bake(o);
    const auto hashes = dataset_hashes(cache);
    ASSERT_GT(hashes.size(), 20u);
    if (reference.empty()) {
      reference = hashes;
      continue;
    }
    EXPECT_EQ(hashes, reference) << run.working << " bytes, " << run.threads << " threads";
    if (run.working == 40u << 20) {
      // A small budget really does cut the work: many batches, and the voxel records spill.
      EXPECT_LT(result.batch_points, 100000u);
      const CacheReader c(cache, false);
      EXPECT_GT(c.provenance("/assets/voxels")->spill_bytes, 0u);
      EXPECT_EQ(c.provenance("/assets/voxels")->memory_budget, result.memory_budget_bytes);
    }
  }
  // Nothing but the caches and the input is left in the directory.
  for (const std::string& name : dir.entries())
    EXPECT_EQ(name.find(".tmp-"), std::string::npos) << name;
}

TEST(BakeStream, EqualsTheWholeBuildersOutput) {
  TempDir dir;
  const LineSet lines = synth::generate({"aneurysm", 0.005, 1, false});
  const std::string input = dir.file("a.binlines");
  write_line_set(lines, input);
  BakeOptions o = streamed_options(input, dir.file("a.lbc.h5"), working_budget(40 << 20));
  bake(o);
  const CacheReader cache(o.cache);
  // The streamed tubes and voxels equal the in-memory builders' on the whole line set.
  const TubeMesh mesh = build_tubes(lines, o.tubes);
  ASSERT_EQ(cache.members("/assets/tubes").size(), mesh.chunks.size());
  for (size_t c = 0; c < mesh.chunks.size(); ++c) {
    char name[64];
    std::snprintf(name, sizeof name, "/assets/tubes/chunk_%06zu/positions", c);
    const Array<float> positions = cache.read<float>(name);
    ASSERT_EQ(positions.size(), mesh.chunks[c].positions.size());
    EXPECT_TRUE(std::equal(positions.begin(), positions.end(), mesh.chunks[c].positions.begin()));
  }
  const VoxelGrid grid = voxelize(lines, o.voxels);
  const Array<uint32_t> chords = cache.read<uint32_t>("/assets/voxels/chords");
  ASSERT_EQ(chords.size(), grid.chords.size());
  EXPECT_TRUE(std::equal(chords.begin(), chords.end(), grid.chords.begin()));
  const Array<float> density = cache.read<float>("/assets/voxels/density_1");
  ASSERT_EQ(density.size(), grid.density[1].size());
  EXPECT_TRUE(std::equal(density.begin(), density.end(), grid.density[1].begin()));
}

TEST(BakeStream, ABudgetTooSmallForOneLineFailsNamingTheLineAndLeavesNothing) {
  TempDir dir;
  LineSet lines;
  for (int i = 0; i < 20; ++i) lines.append_point(float(i), 0, 0);  // a short line
  lines.end_line();
  for (int i = 0; i < 400000; ++i)  // a long one: 400k points, ~150 MB to bake
    lines.append_point(float(i % 1000), float(i / 1000), float(i % 7));
  lines.end_line();
  const std::string input = dir.file("long.binlines");
  write_line_set(lines, input);
  BakeOptions o = streamed_options(input, dir.file("long.lbc.h5"), working_budget(40 << 20));
  try {
    bake(o);
    FAIL() << "baked";
  } catch (const BudgetExceeded& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("line 1 has 400000 points"), std::string::npos) << message;
    EXPECT_NE(message.find("memory budget"), std::string::npos) << message;
  }
  EXPECT_EQ(dir.entries(), std::vector<std::string>{"long.binlines"});
  // A line larger than what the budget leaves for reading (18 MB against about 9 MiB): the
  // reader refuses it at its place (after the header's 12 bytes and the short line's 244)
  // before reading it.
  for (int i = 400000; i < 1500000; ++i)
    lines.append_point(float(i % 1000), float(i / 1000), float(i % 7));
  lines.line_offsets.back() = lines.point_count();
  write_line_set(lines, input);
  o = streamed_options(input, dir.file("long.lbc.h5"), working_budget(36 << 20));
  try {
    bake(o);
    FAIL() << "baked";
  } catch (const BudgetExceeded& e) {
    const std::string message = e.what();
    EXPECT_NE(
        message.find("long.binlines: line 1 (byte offset 256) has 1500000 points, read whole: "
                     "about 17.17 MiB"),
        std::string::npos)
        << message;
  }
  EXPECT_EQ(dir.entries(), std::vector<std::string>{"long.binlines"});
}

// Lines a trillionth of a unit across are refused for tubes and Embree (float32 geometry: their
// squared distances underflow), naming the input, before anything is written; voxels alone
// bake. Lines of one repeated point have no extent at all.
TEST(BakeStream, LinesTooSmallForFloatGeometryAreRefusedNamingTheInput) {
  TempDir dir;
  for (const double scale : {1e-30, 1e-14}) {
    LineSet lines;
    for (int i = 0; i < 3; ++i) lines.append_point(float(i * scale), float(i * scale), 0);
    lines.end_line();
    const std::string input = dir.file("tiny.binlines");
    write_line_set(lines, input);
    BakeOptions o = streamed_options(input, dir.file("tiny.lbc.h5"), BakeOptions::kUnlimited);
    o.assets = {"tubes", "voxels"};
    try {
      bake(o);
      FAIL() << "baked";
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), input);
      EXPECT_NE(std::string(e.what()).find(scale == 1e-30 ? "the lines span 2.83e-30 units"
                                                          : "the lines span 2.83e-14 units"),
                std::string::npos)
          << e.what();
    }
    EXPECT_FALSE(std::filesystem::exists(dir.file("tiny.lbc.h5")));
    o.assets = {"voxels"};
    EXPECT_TRUE(bake(o).written);
    std::filesystem::remove(dir.file("tiny.lbc.h5"));
  }
}

// Several files, one line set: a batch's problems are a message about its file, its lines
// numbered in that file (as linebake-mpi numbers them).
TEST(BakeStream, ARejectedBatchOfSeveralFilesNamesItsFileAndItsLine) {
  TempDir dir;
  const auto lines_with_nan_at = [](int bad_line) {
    LineSet lines;
    for (int l = 0; l < 30; ++l) {
      for (int i = 0; i < 3; ++i)
        lines.append_point(float(l), float(i), l == bad_line && i == 1 ? NAN : 0.0f);
      lines.end_line();
    }
    return lines;
  };
  // The message of the error the bake of both files under `budget` ends in ("" if none).
  const auto refusal = [&](uint64_t budget, InvalidPolicy policy) -> std::string {
    BakeOptions o = streamed_options("", dir.file("m.lbc.h5"), budget);
    o.inputs = {dir.file("m1.binlines"), dir.file("m2.binlines")};
    o.on_invalid = policy;
    try {
      bake(o);
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  };
  write_line_set(lines_with_nan_at(-1), dir.file("m1.binlines"));
  write_line_set(lines_with_nan_at(7), dir.file("m2.binlines"));
  std::string message = refusal(BakeOptions::kUnlimited, InvalidPolicy::reject);
  EXPECT_NE(message.find(dir.file("m2.binlines") + " (lines 0..29): invalid line set"),
            std::string::npos)
      << message;
  EXPECT_NE(message.find("the first: line 7, point 1 (from 0)"), std::string::npos) << message;
  // A line past the budget in the second file: named there, numbered there.
  LineSet lines = lines_with_nan_at(-1);
  for (int i = 0; i < 400000; ++i) lines.append_point(float(i % 1000), float(i / 1000), 1);
  lines.end_line();
  write_line_set(lines, dir.file("m2.binlines"));
  message = refusal(working_budget(40 << 20), InvalidPolicy::repair);
  EXPECT_NE(message.find(dir.file("m2.binlines") + ": line 30 has 400000 points"),
            std::string::npos)
      << message;
}

TEST(BakeStream, SpillFilesAreRemovedAfterAFailure) {
  TempDir dir;
  const std::string input = dir.file("c.binlines");
  write_line_set(synth::generate({"convection", 0.01, 3, false}), input);
  // Cut the file in the middle of a line: the read fails after many batches were spooled.
  std::filesystem::resize_file(input, std::filesystem::file_size(input) / 2);
  BakeOptions o = streamed_options(input, dir.file("c.lbc.h5"), working_budget(40 << 20));
  EXPECT_THROW(bake(o), InputError);
  EXPECT_EQ(dir.entries(), std::vector<std::string>{"c.binlines"});
}

TEST(BakeStream, ReusedLinesStreamFromTheOldCache) {
  TempDir dir;
  const std::string input = dir.file("c.binlines");
  write_line_set(synth::generate({"convection", 0.005, 2, false}), input);
  BakeOptions o = streamed_options(input, dir.file("c.lbc.h5"), working_budget(40 << 20));
  o.assets = {"tubes"};
  bake(o);
  // Voxels added later: /lines is reused, read back in batches from the cache itself.
  o.assets = {"voxels"};
  o.memory_budget = working_budget(40 << 20);  // this process has grown since the first bake
  const BakeResult second = bake(o);
  ASSERT_EQ(second.steps.size(), 2u);
  EXPECT_FALSE(second.steps[0].built);
  EXPECT_TRUE(second.steps[1].built);
  const CacheReader cache(o.cache);
  std::vector<std::string> assets = cache.assets();
  std::sort(assets.begin(), assets.end());
  EXPECT_EQ(assets, (std::vector<std::string>{"tubes", "voxels"}));
  BakeOptions whole = streamed_options(input, dir.file("w.lbc.h5"), BakeOptions::kUnlimited);
  whole.assets = {"tubes", "voxels"};
  bake(whole);
  const auto a = dataset_hashes(o.cache), b = dataset_hashes(whole.cache);
  EXPECT_EQ(a, b);
}

}  // namespace
}  // namespace linebake

namespace linebake {
namespace {

// The lines of `lines` from `first` to `end` as a line set of their own.
LineSet slice(const LineSet& lines, size_t first, size_t end) {
  LineSet part = header_of(lines);
  copy_lines(lines, first, end, part);
  return part;
}

TEST(BakeMultiFile, SeveralFilesBakeAsTheirConcatenationInSortedOrder) {
  TempDir dir;
  const LineSet lines = synth::generate({"convection", 0.01, 2, false});
  ASSERT_GT(lines.line_count(), 30u);
  const std::string whole = dir.file("whole.binlines");
  write_line_set(lines, whole);
  // Three parts whose sorted names are their order in the set; one of them in another format.
  const size_t n = lines.line_count();
  std::filesystem::create_directories(dir.file("run"));
  write_line_set(slice(lines, 0, n / 3), dir.file("run/part_0.binlines"));
  write_line_set(slice(lines, n / 3, n / 2), dir.file("run/part_1.h5"));
  write_line_set(slice(lines, n / 2, n), dir.file("run/part_2.binlines"));

  BakeOptions one = streamed_options(whole, dir.file("whole.lbc.h5"), BakeOptions::kUnlimited);
  bake(one);
  // A working budget, so the parts stream in batches. Under AddressSanitizer (GCC's macro) its
  // quarantine and shadow memory outgrow it, and the parts' order, the point here, holds
  // without a budget as well. 56 MiB: a bake needs 32 MiB to work in beside what the process
  // holds when it starts, which opening the three parts (HDF5's chunk cache among them) raised
  // by up to 10 MiB past the RSS measured here (a parallel ctest run refused 40 MiB once).
#if defined(__SANITIZE_ADDRESS__)
  const uint64_t budget = BakeOptions::kUnlimited;
#else
  const uint64_t budget = working_budget(56 << 20);
#endif
  BakeOptions many = streamed_options("", dir.file("many.lbc.h5"), budget);
  // Given out of order, as a pattern and a path: expanded and sorted.
  many.inputs = expand_inputs({dir.file("run/part_2.binlines"), dir.file("run/part_[01].*")});
  ASSERT_EQ(many.inputs.size(), 3u);
  EXPECT_EQ(many.inputs[0], dir.file("run/part_0.binlines"));
  const BakeResult result = bake(many);

  // The same datasets as the one-file bake, /lines included.
  EXPECT_EQ(dataset_hashes(many.cache), dataset_hashes(one.cache));
  const CacheReader cache(many.cache, false);
  const Provenance p = *cache.provenance("/lines");
  EXPECT_EQ(p.parameters.at("files").size(), 3u);
  EXPECT_EQ(p.stats.at("lines").get<uint64_t>(), n);
  BakeOptions again = many;
  again.progress = false;
  EXPECT_FALSE(bake(again).written);  // unchanged files: nothing rebuilt
  EXPECT_TRUE(result.written);
}

TEST(BakeMultiFile, MismatchedAttributesEmptyPatternsAndAMissingOutputAreErrors) {
  TempDir dir;
  LineSet a = synth::generate({"convection", 0.005, 1, false});
  write_line_set(a, dir.file("a_0.binlines"));
  a.attributes.at(0).name = "other";
  write_line_set(a, dir.file("a_1.binlines"));
  BakeOptions o = streamed_options("", dir.file("c.lbc.h5"), BakeOptions::kUnlimited);
  o.inputs = expand_inputs({dir.file("a_*.binlines")});
  try {
    bake(o);
    FAIL() << "attributes differ";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("a_1.binlines"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("other"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(o.cache));
  for (const std::string& name : dir.entries())
    EXPECT_EQ(name.find(".tmp-"), std::string::npos) << name;
  EXPECT_THROW(expand_inputs({dir.file("nothing_*.vtp")}), InputError);
  EXPECT_THROW(expand_inputs({dir.file("a_0.binlines"), dir.file("a_0.*")}), InputError);
  o.cache.clear();
  EXPECT_THROW(bake(o), Error);
}

}  // namespace
}  // namespace linebake

namespace linebake {
namespace {

// float32's spacing at 1e6 is 2^(19 - 23) = 0.0625: over an extent of 1 that is 6.25 %, noted;
// at 1e3 over 1, 2^(9 - 23) = 6.1e-5 of the extent, under the 1e-4 the note starts at.
TEST(BakeNotes, LinesFarFromTheOriginForTheirExtentAreNoted) {
  LineSetStats s;
  s.bounds.empty = false;
  s.bounds.min = {1e6f, 1e6f, 0};
  s.bounds.max = {1e6f + 1, 1e6f, 0};
  const std::string note = far_from_origin_note(s);
  EXPECT_NE(note.find("coordinates reach 1e+06 over an extent of 1"), std::string::npos) << note;
  EXPECT_NE(note.find("steps of 0.0625 there, 6.2 % of the extent"), std::string::npos) << note;
  s.bounds.min = {1e3f, 0, 0};
  s.bounds.max = {1e3f + 1, 0, 0};
  EXPECT_EQ(far_from_origin_note(s), "");
  s.bounds.min = {-5, -5, -5};
  s.bounds.max = {5, 5, 5};
  EXPECT_EQ(far_from_origin_note(s), "");
}

}  // namespace
}  // namespace linebake
