#pragma once
// A pinhole camera and the flights the paper renders along: an orbit around the data with two
// zoom-ins, a plain orbit, or keyframes from a file.

#include <array>
#include <glm/glm.hpp>
#include <string>
#include <vector>

#include "lines/line_set.hpp"

namespace linebake {

struct Camera {
  glm::dvec3 eye{0, 0, 1}, target{0, 0, 0}, up{0, 1, 0};
  double fov_y_degrees = 40;
  double near = 1e-3, far = 1e3;  // distances along the view direction

  // Primary ray through the centre of pixel (x, y) of a width x height image; y grows downwards.
  // Returns the unit direction; the origin is `eye`.
  glm::dvec3 ray_direction(double x, double y, int width, int height) const;
  // The image plane ray_direction() spans: direction = normalize(forward + sx right + sy up)
  // with sx, sy in [-1, 1] from the left / bottom edge; right and up carry the half extents.
  struct ImagePlane {
    glm::dvec3 forward, right, up;
  };
  ImagePlane image_plane(int width, int height) const;
  glm::dvec3 forward() const { return glm::normalize(target - eye); }
};

// What makes `camera` unusable, or "" when nothing does: a coordinate that is not finite (or so
// large that the view's arithmetic overflows), an eye on its target, an up of zero length or
// along the view direction, a field of view outside (0, 180) degrees. Renderers are handed only
// cameras without one (Embree asserts on the NaN rays the others would make).
std::string camera_problem(const Camera& camera);

// Widens c's near and far planes (never narrows them) so that they hold the bounding sphere of
// `b`: geometry drawn past the box a flight was framed on (render --radius larger than the
// cached tubes') is not cut off by them (embree's rays are clipped to them, rasterisation too).
void hold_in_clip_planes(Camera& c, const Bounds& b);

// The camera that looks at the centre of `bounds` from direction (azimuth, elevation), at the
// nearest distance where the whole box fits the view from every azimuth at this elevation (plus
// 5%), times `distance_scale`: an orbit keeps one distance and elongated data fills the frame.
Camera frame_bounds(const Bounds& bounds, double aspect, double azimuth_degrees,
                    double elevation_degrees, double distance_scale = 1.0,
                    double fov_y_degrees = 40);

enum class FlightKind { OrbitZoom, Orbit, Keyframes };
FlightKind parse_flight_kind(const std::string& name);  // orbit-zoom | orbit | FILE.json
const char* to_string(FlightKind kind);

struct FlightOptions {
  FlightKind kind = FlightKind::OrbitZoom;
  int frames = 64;
  std::string keyframes_file;     // FlightKind::Keyframes
  double elevation_degrees = 20;  // orbits
  double fov_y_degrees = 40;
};

// One camera per frame. Orbit: a full turn at constant distance. OrbitZoom: the same turn with
// two zoom-ins, centred at 30% and 70% of the flight, that bring the camera to 35% of its
// distance (the data then covers the whole viewport). Keyframes: {"keyframes": [{"eye": [x,y,z],
// "target": [x,y,z], "up": [x,y,z], "fov": degrees}, ...]} interpolated linearly, the first
// keyframe at frame 0 and the last at the last frame.
std::vector<Camera> make_flight(const Bounds& bounds, double aspect, const FlightOptions& options);

}  // namespace linebake
