#pragma once
// Pipelines: a declarative file (docs/pipelines.md) naming data sets, asset options, techniques,
// transfer functions, a flight and an image size, planned into steps (bake, render, compare) that
// run as a dependency graph. Planning is pure: it turns the file into command lines and keys; the
// runner (tools/cmd_run.cpp) executes them and reuses steps whose key is unchanged.

#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace linebake {

struct PipelineTechnique {
  std::string technique;             // a `render --technique` name
  std::vector<std::string> options;  // extra render arguments
  std::string label;                 // output name; default: technique
  // Where the technique runs: empty = every data set / transfer function of the pipeline. Lets a
  // pipeline leave a technique out where it would take too long (DP on the largest sets).
  std::vector<std::string> only_datasets;
  std::vector<std::string> only_transfer_functions;
};

struct PipelineDataset {
  std::string name;
  std::string source;  // file (relative to the pipeline file) or synth:...
};

struct Pipeline {
  std::string name;
  std::string file;    // where it was read from
  std::string output;  // output directory
  std::vector<PipelineDataset> datasets;
  std::vector<std::string> bake_options;  // extra bake arguments
  std::vector<PipelineTechnique> techniques;
  std::vector<std::string> transfer_functions{"semi"};
  // Transfer functions given as files found next to the pipeline file: name -> that path, so
  // a shipped pipeline's own transfer function works from any directory. Other file names are
  // read from the working directory, as they are written.
  std::map<std::string, std::string> transfer_function_files;
  std::string flight = "orbit-zoom";
  int frame_count = 4;
  // Frames each render step renders first, untimed (render --warm-up): a Vulkan technique's
  // first frame compiles its pipelines, which the means would count.
  int warm_up = 1;
  std::string size = "320x180";
  std::string reference = "reference";  // the technique the others are compared with
};

// The assets the pipeline's bakes build: its `--assets` list, else the bake's default (tubes).
std::vector<std::string> pipeline_assets(const Pipeline& p);

// The pipeline file `path` names: the file as given, else with .json, .yaml or .yml added, else
// (where `shipped_dir` is given and `path` is a bare name or pipelines/NAME) the same in
// `shipped_dir`. A directory is no pipeline file: `run quickstart` beside a quickstart/
// directory still finds quickstart.json. The path as given when none exists, so the error names
// it.
std::string find_pipeline(const std::string& path, const std::string& shipped_dir = "");
// Reads a pipeline: JSON, or YAML for .yaml/.yml; the file find_pipeline(path) names.
// InputError naming the file and the JSON path of a bad entry (YAML syntax errors: the line and
// column).
Pipeline load_pipeline(const std::string& path);
Pipeline parse_pipeline(const nlohmann::json& json, const std::string& file);

struct PipelineStep {
  std::string id;                    // "bake/aneurysm", "render/aneurysm/ll/semi", ...
  std::string kind;                  // bake | render | compare
  std::vector<std::string> depends;  // step ids
  std::vector<std::string> args;     // linebake arguments (without the program)
  std::string stdout_file;           // where the step's standard output goes ("" = inherit)
  std::vector<std::string> outputs;  // files the step makes (all must exist to reuse it)
  // Files the step may make, which only its run can tell (a render's depth-complexity images:
  // techniques that count no fragments or hits write none). The run records those it made; they
  // must exist too.
  std::vector<std::string> optional_outputs;
  std::string key;          // hash of the arguments and the dependencies' keys
  std::string skip_reason;  // non-empty: not run, and why (a missing device feature)
};

struct PlanContext {
  bool vulkan = true;        // some Vulkan device exists
  bool ray_tracing = false;  // some device can ray trace
  // Content hash of a local input file (bake keys); empty for synth sources.
  std::string (*file_hash)(const std::string& path) = nullptr;
};

// Steps in an order where every step follows its dependencies.
std::vector<PipelineStep> plan_pipeline(const Pipeline& pipeline, const PlanContext& context);

// Error images of the compare steps: |technique - reference| amplified by this gain, so that the
// few-percent differences of good techniques show (the report states it in the captions).
constexpr double kErrorImageGain = 10;

// What `render --tf` gets for one of the pipeline's transfer functions: the preset name, or the
// file's path.
std::string transfer_function_argument(const Pipeline& p, const std::string& tf);

// Paths the report reads.
std::string cache_path(const Pipeline& p, const std::string& dataset);
std::string render_stem(const Pipeline& p, const std::string& dataset, const std::string& label,
                        const std::string& tf);  // <output>/<dataset>/<label>-<tf>
std::string frame_file(const std::string& stem, int frame, const char* suffix);
// A frame's output as the pipeline names it: stem_NNN.suffix, or stem.suffix for one frame.
std::string frame_output(const Pipeline& p, const std::string& stem, int frame, const char* suffix);

}  // namespace linebake
