#include "flight_plan.hpp"

#include <cstdio>
#include <regex>

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/memory_budget.hpp"
#include "whole_output.hpp"

namespace linebake::cli {

std::array<int, 2> parse_image_size(const std::string& text) {
  static const std::regex pattern(R"((\d{1,5})x(\d{1,5}))");
  std::smatch m;
  if (!std::regex_match(text, m, pattern)) throw Error("--size: expected WxH, got '" + text + "'");
  const int w = std::stoi(m[1]), h = std::stoi(m[2]);
  if (w < 1 || h < 1 || w > 16384 || h > 16384) throw Error("--size: 1..16384 per axis");
  return {w, h};
}

CLI::Validator image_size_check() {
  return CLI::Validator(
      [](std::string& text) {
        try {
          parse_image_size(text);
        } catch (const std::exception& e) {
          // CLI11 names the option itself.
          const std::string message = e.what();
          return message.rfind("--size: ", 0) == 0 ? message.substr(8) : message;
        }
        return std::string();
      },
      "WxH");
}

std::string frame_path(const std::string& path, int frame, bool numbered) {
  if (!numbered) return path;
  const auto dot = path.find_last_of('.');
  const auto slash = path.find_last_of('/');
  char number[16];
  std::snprintf(number, sizeof number, "_%03d", frame);
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return path + number;
  return path.substr(0, dot) + number + path.substr(dot);
}

FlightPlan plan_flight(const std::string& flight_name, int frame_count, int frame,
                       const std::string& frames, const Bounds& bounds, int width, int height) {
  if (frame >= frame_count && frames.empty())
    throw Error("--frame " + std::to_string(frame) + " is past the flight's " +
                std::to_string(frame_count) + " frames");
  FlightOptions flight;
  flight.kind = parse_flight_kind(flight_name);
  if (flight.kind == FlightKind::Keyframes) flight.keyframes_file = flight_name;
  flight.frames = frame_count;
  FlightPlan plan;
  plan.kind = flight.kind;
  plan.cameras = make_flight(bounds, double(width) / height, flight);
  plan.frames = planned_frames(frame_count, frame, frames);
  return plan;
}

std::vector<int> planned_frames(int frame_count, int frame, const std::string& frames) {
  std::vector<int> planned;
  if (frames == "all")
    for (int i = 0; i < frame_count; ++i) planned.push_back(i);
  else
    planned.push_back(frame);
  return planned;
}

void check_frame_outputs(const std::vector<std::string>& per_frame,
                         const std::vector<std::string>& once, const std::vector<int>& frames,
                         const std::vector<std::string>& inputs) {
  std::vector<std::string> outputs = once;
  for (const std::string& path : per_frame)
    if (!path.empty())
      for (const int frame : frames) outputs.push_back(frame_path(path, frame, frames.size() > 1));
  refuse_clashing_outputs(outputs, inputs);
}

void check_depth_image_output(const std::string& path) {
  if (path.empty()) return;
  if (path.size() < 4 || path.compare(path.size() - 4, 4, ".png") != 0)
    throw OutputError(path, "depth complexity is written as a 16-bit PNG: use .png");
  check_output_location(path);
}

void check_frame_memory(const std::string& what, const std::string& size, uint64_t bytes,
                        const std::string& budget, uint64_t kept) {
  if (budget == "unlimited") return;
  const uint64_t limit = memory_budget_bytes(budget);
  if (bytes + kept > limit)
    throw BudgetExceeded("a " + size + " " + what + " frame needs about " + format_bytes(bytes) +
                         (kept > 0 ? ", and the earlier rows' frames 0, kept for the quality "
                                     "figures, hold " +
                                         format_bytes(kept) + ":"
                                   : ",") +
                         " more than the memory budget of " + format_bytes(limit) +
                         "; lower --size" + (what == "ll" ? " or --capacity" : "") +
                         ", or raise --memory-budget");
}

}  // namespace linebake::cli
