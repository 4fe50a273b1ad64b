// Pipeline files: parsing (with errors naming the JSON path), and planning into steps whose
// order respects dependencies and whose keys change exactly when their inputs change.

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>

#include "core/error.hpp"
#include "pipeline/pipeline.hpp"
#include "test_util.hpp"

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

// A file under the temporary directory, named for this process (two checkouts' tests may run
// at once).
std::string write_temp(const std::string& name, const std::string& text) {
  const auto path = std::filesystem::temp_directory_path() /
                    ("linebake-test-" + std::to_string(::getpid()) + "-" + name);
  std::ofstream(path) << text;
  return path.string();
}

std::map<std::string, std::string> plan_keys(const Pipeline& p) {
  PlanContext context;
  context.file_hash = &fake_hash;
  std::map<std::string, std::string> keys;
  for (const PipelineStep& s : plan_pipeline(p, context)) keys[s.id] = s.key + s.skip_reason;
  return keys;
}

TEST(Pipeline, YamlReadsAsTheSameJson) {
  // small() written in YAML: plain scalars get their types, quoted ones stay strings.
  const std::string yaml = write_temp("t.yaml", R"(# comment
name: t
output: out/t
datasets:
  - {name: a, source: "synth:aneurysm?scale=0.01"}
  - name: b
    source: data/b.binlines
assets:
  assets: [tubes, voxels]
  grid: 32
  caps: true
  radius: 0.002
techniques:
  - reference
  - technique: ll
    options: {sort: shell}
  - rtx
transfer_functions: [semi, opaque]
frames: 3
size: "64x48"
)");
  const std::string json = write_temp("t.json", small().dump());
  const Pipeline from_yaml = load_pipeline(yaml), from_json = load_pipeline(json);
  EXPECT_EQ(from_yaml.bake_options, from_json.bake_options);
  EXPECT_EQ(from_yaml.frame_count, 3);
  // Same steps, same command lines (the data set path is relative to each file: same folder).
  EXPECT_EQ(plan_keys(from_yaml), plan_keys(from_json));
  // The extension may be left out: .json first, then .yaml.
  const std::string stem = json.substr(0, json.size() - 5);
  EXPECT_EQ(load_pipeline(stem).file, json);
  std::filesystem::remove(json);
  EXPECT_EQ(load_pipeline(stem).file, yaml);
}

TEST(Pipeline, FindPipelineTakesFilesThenExtensionsThenTheShippedOnes) {
  const test::TempDir dir;
  std::filesystem::create_directories(dir.file("shipped"));
  std::ofstream(dir.file("shipped/demo.yaml")) << "name: demo\n";
  std::ofstream(dir.file("p.yml")) << "name: p\n";
  // A directory of the pipeline's name (its output, say) is not the pipeline file.
  std::filesystem::create_directories(dir.file("p"));
  const std::string shipped = dir.file("shipped");
  EXPECT_EQ(find_pipeline(dir.file("p")), dir.file("p.yml"));
  EXPECT_EQ(find_pipeline(dir.file("p.yml"), shipped), dir.file("p.yml"));
  // A bare name, or pipelines/NAME, not found here is looked up among the shipped ones.
  const std::string bare = "demo";
  ASSERT_FALSE(std::filesystem::exists(bare + ".yaml"));
  EXPECT_EQ(find_pipeline(bare, shipped), dir.file("shipped/demo.yaml"));
  EXPECT_EQ(find_pipeline("pipelines/demo", shipped), dir.file("shipped/demo.yaml"));
  EXPECT_EQ(find_pipeline(bare), bare);
  // A path elsewhere is only that path; nothing found gives it back as given.
  EXPECT_EQ(find_pipeline(dir.file("demo"), shipped), dir.file("demo"));
  EXPECT_EQ(find_pipeline(dir.file("none"), shipped), dir.file("none"));
  // The directory alone, as given: load_pipeline says what it is.
  std::filesystem::remove(dir.file("p.yml"));
  EXPECT_EQ(find_pipeline(dir.file("p")), dir.file("p"));
}

TEST(Pipeline, YamlErrorsNameLineAndColumnOrTheEntry) {
  const std::string bad_syntax =
      write_temp("bad.yaml", "name: t\ndatasets:\n  - {name: a, source: [\n");
  try {
    load_pipeline(bad_syntax);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().rfind("line ", 0), 0u) << e.where();
    EXPECT_NE(std::string(e.what()).find("bad.yaml"), std::string::npos);
  }
  const std::string bad_entry =
      write_temp("bad2.yaml",
                 "datasets: [{name: a, source: s.binlines}]\ntechniques: [{technique: ll, "
                 "options: {sort: {x: 1}}}]\nreference: ll\n");
  try {
    load_pipeline(bad_entry);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where(), "techniques[0].options.sort");
  }
}

// A JSON error's place is the failing character's offset from 0, counted by hand; an input that
// ends too soon is at the file's end (nlohmann counts the end as one more character, and an
// empty file had been "byte offset 1").
TEST(Pipeline, JsonErrorsNameTheByteOffsetFromZeroOrTheEnd) {
  const auto where_of = [](const std::string& path) {
    try {
      load_pipeline(path);
    } catch (const InputError& e) {
      return e.where() + " | " + e.what();
    }
    return std::string("no error");
  };
  EXPECT_EQ(
      where_of(write_temp("empty.json", "")).rfind("the end of the file (byte offset 0) |", 0), 0u);
  const std::string cut = where_of(write_temp("cut.json", "{\"a\": "));
  EXPECT_EQ(cut.rfind("the end of the file (byte offset 6) |", 0), 0u) << cut;
  EXPECT_NE(cut.find("unexpected end of input"), std::string::npos) << cut;
  const std::string bad = where_of(write_temp("bad.json", "{\"a\": x}"));
  EXPECT_EQ(bad.rfind("byte offset 6 |", 0), 0u) << bad;  // the x
}

// What readers would take silently or expand without bound: a key given twice (JSON and YAML),
// a second YAML document, aliases nested into billions of nodes (which took 24 GiB before the
// kernel killed the process).
TEST(Pipeline, TwiceGivenKeysSecondDocumentsAndAliasBombsAreRefused) {
  const auto error_of = [](const std::string& path) -> std::pair<std::string, std::string> {
    try {
      load_pipeline(path);
    } catch (const InputError& e) {
      return {e.where(), e.what()};
    }
    return {"", "no error"};
  };
  const std::string good = R"("datasets": [{"name": "a", "source": "s.binlines"}],
                              "techniques": ["ll"])";
  auto [where, what] =
      error_of(write_temp("twice.json", "{\"frames\": 2, " + good + ", \"frames\": 3}"));
  EXPECT_EQ(where, "key 'frames'") << what;
  std::tie(where, what) =
      error_of(write_temp("nested.json", R"({"datasets": [{"name": "a", "name": "b",
                                              "source": "s.binlines"}], "techniques": ["ll"]})"));
  EXPECT_EQ(where, "key 'name'") << what;
  std::tie(where, what) = error_of(write_temp(
      "twice.yaml", "frames: 2\ndatasets: [{name: a, source: s.binlines}]\nframes: 3\n"));
  EXPECT_EQ(where, "line 3, key 'frames'") << what;
  std::tie(where, what) = error_of(write_temp("two.yaml",
                                              "datasets: [{name: a, source: s.binlines}]\n"
                                              "techniques: [ll]\n---\nframes: 3\n"));
  EXPECT_EQ(where, "line 4") << what;
  EXPECT_NE(what.find("a second YAML document"), std::string::npos) << what;
  // Nine levels of nine aliases: 9^9 scalars; refused past 100,000 nodes, at once.
  std::string bomb = "a: &a [x, x, x, x, x, x, x, x, x]\n";
  for (char level = 'b'; level <= 'i'; ++level) {
    const std::string previous = "*" + std::string(1, char(level - 1));
    bomb += std::string(1, level) + ": &" + std::string(1, level) + " [";
    for (int k = 0; k < 9; ++k) bomb += (k ? ", " : "") + previous;
    bomb += "]\n";
  }
  std::tie(where, what) = error_of(write_temp("bomb.yaml", bomb));
  EXPECT_NE(what.find("expands to more than 100000 YAML nodes"), std::string::npos) << what;
  // An alias inside what it names never ends (a stack overflow before the node count).
  for (const char* cycle : {"datasets: &a [*a]\ntechniques: [ll]\n", "datasets: &a {x: *a}\n"}) {
    std::tie(where, what) = error_of(write_temp("cycle.yaml", cycle));
    EXPECT_NE(what.find("nests deeper than 256 levels"), std::string::npos) << what;
  }
  // A document ended by `... # a comment` and followed by another: refused too.
  std::tie(where, what) =
      error_of(write_temp("ended.yaml",
                          "datasets: [{name: a, source: s.binlines}]\ntechniques: [ll]\nreference: "
                          "ll\n... # end\nbogus: [x]\n"));
  EXPECT_EQ(where, "line 5") << what;
  // What is no second document: a byte-order mark before a leading ---, a trailing --- with
  // an empty document ended by `...`.
  for (const char* ends : {"---\n...\n", "---\n\n...\n"})
    EXPECT_NO_THROW(load_pipeline(write_temp(
        "empty-end.yaml", std::string("datasets: [{name: a, source: s.binlines}]\ntechniques: "
                                      "[ll]\nreference: ll\n") +
                              ends)));
  EXPECT_NO_THROW(load_pipeline(
      write_temp("bom.yaml",
                 "\xEF\xBB\xBF# comment\n---\ndatasets: [{name: a, source: s.binlines}]\n"
                 "techniques: [ll]\nreference: ll\n")));
  // An empty document after a trailing --- holds nothing: the pipeline reads.
  EXPECT_NO_THROW(load_pipeline(write_temp(
      "trailing.yaml",
      "datasets: [{name: a, source: s.binlines}]\ntechniques: [ll]\nreference: ll\n---\n")));
}

// YAML 1.2's core schema, as the documentation promises: 0x and 0o integers (to 64 bits), .inf;
// what YAML 1.1 (PyYAML) reads otherwise is refused naming its line and column: a plain
// yes/no/on/off (`early-termination: yes` had reached the flag as a value) and a leading zero.
TEST(Pipeline, YamlReadsCoreIntegersAndRefusesWhatYaml11ReadsOtherwise) {
  const Pipeline p = load_pipeline(write_temp("core.yaml", R"(name: 0x1p3
datasets: [{name: a, source: s.binlines}]
assets: {attribute-range: [0.1, 2.5], grid: 0x20, radius: 0o17, seed: 0xFFFFFFFFFFFFFFFF,
         seeds: 18446744073709551615}
techniques:
  - {technique: ll, options: {capacity: [1, .inf, -.Inf], early: n, early-termination: "yes",
                              max: +.inf, sort: y}}
reference: ll
frames: 0o7
)"));
  EXPECT_EQ(p.name, "0x1p3");  // C's hexadecimal float, a string in YAML
  EXPECT_EQ(p.frame_count, 7);
  // A list's finite floats as JSON writes them (as before: the steps' keys hold them).
  EXPECT_EQ(p.bake_options,
            (std::vector<std::string>{"--attribute-range", "0.1,2.5", "--grid", "32", "--radius",
                                      "15", "--seed", "18446744073709551615", "--seeds",
                                      "18446744073709551615"}));
  ASSERT_EQ(p.techniques.size(), 1u);
  // y and n are strings in both (PyYAML's booleans are yes, no, on, off).
  EXPECT_EQ(
      p.techniques[0].options,
      (std::vector<std::string>{"--capacity", "1,inf,-inf", "--early", "n", "--early-termination",
                                "yes", "--max", "inf", "--sort", "y"}));
  const auto error_of = [](const std::string& value) -> std::pair<std::string, std::string> {
    try {
      load_pipeline(write_temp("yaml11.yaml",
                               "datasets: [{name: a, source: s.binlines}]\n"
                               "techniques:\n  - technique: ll\n    options:\n"
                               "      early-termination: " +
                                   value + "\nreference: ll\n"));
    } catch (const InputError& e) {
      return {e.where(), e.what()};
    }
    return {"", "taken"};
  };
  for (const char* plain : {"yes", "No", "ON", "off"}) {
    const auto [where, what] = error_of(plain);
    EXPECT_EQ(where, "line 5, column 26") << what;
    EXPECT_NE(what.find("plain '" + std::string(plain) + "' is a boolean in YAML 1.1"),
              std::string::npos)
        << what;
  }
  for (const char* leading_zero : {"012", "-07", "00"}) {
    const auto [where, what] = error_of(leading_zero);
    EXPECT_EQ(where, "line 5, column 26") << what;
    EXPECT_NE(what.find("has a leading zero: octal in YAML 1.1"), std::string::npos) << what;
  }
  const auto [where, what] = error_of("0x10000000000000000");
  EXPECT_NE(what.find("needs more than 64 bits"), std::string::npos) << what;
}

// A damaged pipeline (a fuzzer's; tests/fuzz/known/pipeline_yaml/) on which yaml-cpp 0.7's
// YAML::LoadAll produced documents without end, past 2 GiB: read as one document, refused as
// not a mapping, at once.
TEST(Pipeline, ADamagedFileThatLoadAllReadForEverIsRead) {
  const std::string damaged = write_temp(
      "damaged.yaml",
      R"FUZZ(# The paper's evaluurce: "synth:cid's offluu transfer functions as a check of the GPU path.
  - tjchnique: vrc
    label: vrcn
  , aneurysm withexceed lavapipe's 128 MiB storage buffers, so it runs on
  # aneurysm with two transfer functions as a check of the GPU path.
  - technique: vrc
    label: vrc-gpu
    options: {"on": gpu}
    datasets: [aneurzsm]
    transfer_functions: [opaque, NULL]
  - rtx
  # The% compute-onlconvection is exact but#  slow oTnh)FUZZ");
  try {
    load_pipeline(damaged);
    FAIL() << "read";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("a pipeline is an object"), std::string::npos) << e.what();
  }
}

TEST(Pipeline, TechniquesCanBeLimitedToSomeDataSetsAndTransferFunctions) {
  auto j = small();
  j["techniques"][1]["datasets"] = {"b"};
  j["techniques"][1]["transfer_functions"] = {"opaque"};
  PlanContext context;
  context.file_hash = &fake_hash;
  context.ray_tracing = true;
  size_t ll_renders = 0;
  for (const PipelineStep& s : plan_pipeline(parse_pipeline(j, "t.json"), context)) {
    if (s.id.find("/ll/") == std::string::npos) {
      EXPECT_EQ(s.skip_reason, "") << s.id;
      continue;
    }
    const bool runs = s.id.find("/b/ll/opaque") != std::string::npos;
    EXPECT_EQ(s.skip_reason.empty(), runs) << s.id;
    if (s.id.rfind("render/", 0) == 0) ++ll_renders;
    if (s.id == "render/a/ll/opaque") {
      EXPECT_EQ(s.skip_reason, "left out of this pipeline on a (it runs on b)");
    }
    if (s.id == "compare/b/ll/semi/2") {
      EXPECT_EQ(s.skip_reason, "left out of this pipeline for semi (it runs with opaque)");
    }
  }
  EXPECT_EQ(ll_renders, 4u);  // planned (and reported) everywhere, run in one place
  // Names must be the pipeline's own.
  j["techniques"][1]["datasets"] = {"c"};
  EXPECT_THROW(parse_pipeline(j, "t.json"), InputError);
  j = small();
  j["techniques"][1]["transfer_functions"] = {"transparent"};
  EXPECT_THROW(parse_pipeline(j, "t.json"), InputError);
  j = small();
  j["techniques"][1]["frames"] = 2;
  try {
    parse_pipeline(j, "t.json");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where(), "techniques[1].frames");
  }
}

// A transfer-function file beside the pipeline file is found from any working directory (the
// shipped quickstart's is); other file names stay as written. Editing the file renders again.
TEST(Pipeline, TransferFunctionFilesBesideThePipelineFile) {
  const test::TempDir temp;
  const std::filesystem::path dir = temp.file("pipeline");
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "vivid.json") << R"({"colours": [[0, 1, 0, 0]], "opacities": [[0, 1]]})";
  auto j = small();
  j["transfer_functions"] = {"semi", "vivid.json", "elsewhere.json"};
  const Pipeline p = parse_pipeline(j, (dir / "t.json").string());
  EXPECT_EQ(transfer_function_argument(p, "semi"), "semi");
  EXPECT_EQ(transfer_function_argument(p, "vivid.json"), (dir / "vivid.json").string());
  EXPECT_EQ(transfer_function_argument(p, "elsewhere.json"), "elsewhere.json");
  PlanContext context;
  context.file_hash = &fake_hash;
  std::map<std::string, std::string> tf_of, key_of;
  for (const PipelineStep& s : plan_pipeline(p, context)) {
    key_of[s.id] = s.key;
    const auto tf = std::find(s.args.begin(), s.args.end(), "--tf");
    if (tf != s.args.end()) tf_of[s.id] = *(tf + 1);
  }
  EXPECT_EQ(tf_of.at("render/a/ll/vivid.json"), (dir / "vivid.json").string());
  EXPECT_EQ(tf_of.at("render/a/ll/elsewhere.json"), "elsewhere.json");
  EXPECT_EQ(tf_of.at("render/a/ll/semi"), "semi");
  context.file_hash = [](const std::string& path) { return "edited-" + path; };
  for (const PipelineStep& s : plan_pipeline(p, context)) {
    // The bake of b hashes its input file too; only vivid.json's renders and compares follow
    // the edited transfer function.
    if (s.id.find("/b") != std::string::npos) continue;
    EXPECT_EQ(s.key != key_of.at(s.id), s.id.find("/vivid.json") != std::string::npos) << s.id;
  }
  std::filesystem::remove_all(dir);
}

// Every compare step amplifies its error image by the gain the report's captions state.
TEST(Pipeline, CompareStepsWriteErrorImagesWithTheStatedGain) {
  PlanContext context;
  context.file_hash = &fake_hash;
  size_t compares = 0;
  for (const PipelineStep& s : plan_pipeline(parse_pipeline(small(), "t.json"), context)) {
    if (s.kind != "compare") continue;
    ++compares;
    const auto scale = std::find(s.args.begin(), s.args.end(), "--error-scale");
    ASSERT_NE(scale, s.args.end()) << s.id;
    ASSERT_NE(scale + 1, s.args.end()) << s.id;
    EXPECT_DOUBLE_EQ(std::stod(*(scale + 1)), kErrorImageGain) << s.id;
  }
  EXPECT_EQ(compares, 24u);
  EXPECT_GT(kErrorImageGain, 1.0);  // a gain of 1 leaves good techniques' errors invisible
}

}  // namespace
}  // namespace linebake
