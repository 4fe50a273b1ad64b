// Pipeline files: parsing (with errors naming the JSON path), and planning into steps whose
// order respects dependencies and whose keys change exactly when their inputs change.

#include <gtest/gtest.h>

#include <map>

#include "core/error.hpp"
#include "pipeline/pipeline.hpp"

namespace linebake {
namespace {

nlohmann::json small() {
  return nlohmann::json::parse(R"({
    "name": "t", "output": "out/t",
    "datasets": [{"name": "a", "source": "synth:aneurysm?scale=0.01"},
                 {"name": "b", "source": "data/b.binlines"}],
    "assets": {"assets": ["tubes", "voxels"], "grid": 32, "caps": true, "radius": 0.002},
    "techniques": ["reference", {"technique": "ll", "options": {"sort": "shell"}}, "rtx"],
    "transfer_functions": ["semi", "opaque"],
    "frames": 3, "size": "64x48"})");
}

std::string fake_hash(const std::string& path) {
  return "hash-of-" + path;
}

TEST(Pipeline, ParsesOptionsIntoCommandLineArguments) {
  const Pipeline p = parse_pipeline(small(), "/p/pipelines/t.json");
  ASSERT_EQ(p.datasets.size(), 2u);
  EXPECT_EQ(p.datasets[1].source, "/p/pipelines/data/b.binlines");  // relative to the file
  EXPECT_EQ(p.bake_options, (std::vector<std::string>{"--assets", "tubes,voxels", "--caps",
                                                      "--grid", "32", "--radius", "0.002"}));
  ASSERT_EQ(p.techniques.size(), 3u);
  EXPECT_EQ(p.techniques[1].options, (std::vector<std::string>{"--sort", "shell"}));
  EXPECT_EQ(p.frame_count, 3);
}

TEST(Pipeline, BadEntriesNameTheirPlace) {
  const auto error_of = [](nlohmann::json j) -> std::string {
    try {
      parse_pipeline(j, "p.json");
    } catch (const InputError& e) {
      return e.where();
    }
    return "no error";
  };
  auto j = small();
  j["techniques"][1]["options"] = {{"sort", nlohmann::json::object()}};
  EXPECT_EQ(error_of(j), "techniques[1].options.sort");
  j = small();
  j["datasets"][1]["name"] = "a";
  EXPECT_EQ(error_of(j), "datasets[1].name");
  j = small();
  j["datasets"][0]["name"] = "../up";
  EXPECT_EQ(error_of(j), "datasets[0].name");
  j = small();
  j["reference"] = "embree";
  EXPECT_EQ(error_of(j), "reference");
  j = small();
  j["colour"] = "red";
  EXPECT_EQ(error_of(j), "colour");
  j = small();
  j["techniques"].push_back("ll");
  EXPECT_EQ(error_of(j), "techniques[3]");
}

TEST(Pipeline, PlanOrdersStepsAndSkipsWhatTheMachineCannotRun) {
  const Pipeline p = parse_pipeline(small(), "t.json");
  PlanContext context;
  context.file_hash = &fake_hash;
  const auto steps = plan_pipeline(p, context);
  // 2 bakes, 2 x 2 x 3 renders, 2 x 2 x 2 techniques x 3 frames compares.
  EXPECT_EQ(steps.size(), 2u + 12u + 24u);
  std::map<std::string, size_t> position;
  for (size_t i = 0; i < steps.size(); ++i) position[steps[i].id] = i;
  for (size_t i = 0; i < steps.size(); ++i)
    for (const std::string& d : steps[i].depends) {
      ASSERT_TRUE(position.count(d)) << d;
      EXPECT_LT(position[d], i) << steps[i].id << " before " << d;
    }
  for (const PipelineStep& s : steps) {
    const bool rtx = s.id.find("/rtx/") != std::string::npos;
    EXPECT_EQ(!s.skip_reason.empty(), rtx) << s.id;
  }
  context.ray_tracing = true;
  for (const PipelineStep& s : plan_pipeline(p, context)) EXPECT_TRUE(s.skip_reason.empty());
}

TEST(Pipeline, KeysChangeWithTheirInputsOnly) {
  PlanContext context;
  context.file_hash = &fake_hash;
  const auto key_map = [&](const nlohmann::json& j) {
    std::map<std::string, std::string> keys;
    for (const PipelineStep& s : plan_pipeline(parse_pipeline(j, "t.json"), context))
      keys[s.id] = s.key;
    return keys;
  };
  const auto base = key_map(small());
  EXPECT_EQ(key_map(small()), base);  // deterministic
  // Another ll sort: its renders and compares change, nothing else.
  auto j = small();
  j["techniques"][1]["options"]["sort"] = "heap";
  const auto sorted = key_map(j);
  for (const auto& [id, key] : base) {
    const bool ll = id.find("/ll/") != std::string::npos;
    EXPECT_EQ(sorted.at(id) != key, ll) << id;
  }
  // Another grid: every step of every data set downstream of the bakes changes.
  j = small();
  j["assets"]["grid"] = 64;
  for (const auto& [id, key] : key_map(j)) EXPECT_NE(base.at(id), key) << id;
  // A changed input file changes data set b's steps, not a's.
  context.file_hash = [](const std::string& path) { return "other-" + path; };
  for (const auto& [id, key] : key_map(small()))
    EXPECT_EQ(base.at(id) != key, id.find("/b") != std::string::npos) << id;
}

}  // namespace
}  // namespace linebake
