// Fuzz target for keyframe flights (--flight KEYS.json): the cameras of a 16-frame flight.

#include "fuzz_input.hpp"
#include "render/camera.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return linebake::fuzz::with_input_file(data, size, "json", [](const std::string& path) {
    linebake::FlightOptions flight;
    flight.kind = linebake::FlightKind::Keyframes;
    flight.frames = 16;
    flight.keyframes_file = path;
    linebake::Bounds bounds;
    bounds.min = {0, 0, 0}, bounds.max = {1, 1, 1}, bounds.empty = false;
    (void)linebake::make_flight(bounds, 4.0 / 3.0, flight);
  });
}
