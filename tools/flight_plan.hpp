#pragma once
// What `render` and `depth-complexity` share on the command line: the image size, the flight's
// cameras and which frames to draw, and numbered output names for multi-frame runs.

#include <CLI/CLI.hpp>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "lines/line_set.hpp"
#include "render/camera.hpp"

namespace linebake::cli {

// "WxH", 1..16384 per axis.
std::array<int, 2> parse_image_size(const std::string& text);
// parse_image_size as a CLI11 check, so a bad size is a usage error found when the command line is
// read.
CLI::Validator image_size_check();

// A 16-bit PNG of counts per pixel (render --depth-complexity, depth-complexity -o): .png, in a
// directory that exists and takes files; "" passes. Throws OutputError.
void check_depth_image_output(const std::string& path);

// "out.png" -> "out_007.png" for frame 7 of a multi-frame render.
std::string frame_path(const std::string& path, int frame, bool numbered);

struct FlightPlan {
  FlightKind kind = FlightKind::OrbitZoom;
  std::vector<Camera> cameras;
  std::vector<int> frames;  // --frame F, or every frame for --frames all
};

// The frames drawn: --frame `frame`, or every frame of `frame_count` for --frames all.
std::vector<int> planned_frames(int frame_count, int frame, const std::string& frames);

// Before any work: the files of `per_frame` outputs (images; numbered as for `frames`) and of
// `once` outputs (--stats) are none of the command's `inputs` and each its own. Throws
// OutputError (refuse_clashing_outputs).
void check_frame_outputs(const std::vector<std::string>& per_frame,
                         const std::vector<std::string>& once, const std::vector<int>& frames,
                         const std::vector<std::string>& inputs);

// flight: orbit-zoom | orbit | KEYFRAMES.json; frames: "" or "all".
FlightPlan plan_flight(const std::string& flight, int frame_count, int frame,
                       const std::string& frames, const Bounds& bounds, int width, int height);

// Throws BudgetExceeded with the figures when a frame of `bytes` (estimate_frame_bytes in
// lib/techniques for a technique; `what` names it), with `kept` bytes the command holds besides
// (bench render's frames 0, kept for the quality figures), exceeds `budget` ("": half of
// physical memory).
void check_frame_memory(const std::string& what, const std::string& size, uint64_t bytes,
                        const std::string& budget, uint64_t kept = 0);

}  // namespace linebake::cli
