#include "render/camera.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>

#include "core/error.hpp"
#include "core/json_file.hpp"
#include "core/nearest.hpp"

namespace linebake {

std::string camera_problem(const Camera& c) {
  // Embree refuses rays whose origin lies past about 1.8e18 (its ray.valid(), an assertion), and
  // the GPU techniques compute in float32: positions past 1e18 are no camera of ours.
  const auto usable = [](const glm::dvec3& v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z) && glm::length(v) < 1e18;
  };
  if (!usable(c.eye) || !usable(c.target) || !usable(c.up))
    return "eye, target and up must be finite numbers (below 1e18)";
  const glm::dvec3 view = c.target - c.eye;
  if (!(glm::length(view) > 0)) return "the eye is on the target";
  if (!(glm::length(c.up) > 0)) return "up has zero length";
  if (glm::length(glm::cross(glm::normalize(view), glm::normalize(c.up))) < 1e-9)
    return "up lies along the view direction";
  if (!(c.fov_y_degrees > 0 && c.fov_y_degrees < 180)) return "fov must be in (0, 180) degrees";
  return "";
}

namespace {

double radians(double degrees) {
  return degrees * std::numbers::pi / 180.0;
}

struct Sphere {
  glm::dvec3 centre{0};
  double radius = 1;
};

Sphere bounding_sphere(const Bounds& b) {
  if (b.empty) return {};
  const glm::dvec3 lo(b.min[0], b.min[1], b.min[2]), hi(b.max[0], b.max[1], b.max[2]);
  const double r = 0.5 * glm::length(hi - lo);
  return {0.5 * (lo + hi), r > 0 ? r : 1.0};
}

// Near and far that hold the whole bounding sphere (near never zero: depth precision).
void fit_clip_planes(Camera& c, const Sphere& s) {
  const double d = glm::length(s.centre - c.eye);
  c.near = std::max(d - s.radius, s.radius * 1e-4);
  c.far = d + s.radius;
}

glm::dvec3 read_vec3(const nlohmann::json& j, const char* key, const std::string& file, size_t i) {
  if (!j.contains(key) || !j[key].is_array() || j[key].size() != 3)
    throw InputError(file, "keyframe " + std::to_string(i),
                     std::string("'") + key + "' must be an array of 3 numbers");
  glm::dvec3 v;
  for (int k = 0; k < 3; ++k) {
    if (!j[key][k].is_number())
      throw InputError(file, "keyframe " + std::to_string(i),
                       std::string("'") + key + "' must be an array of 3 numbers");
    v[k] = j[key][k].get<double>();
  }
  return v;
}

std::vector<Camera> read_keyframes(const std::string& file) {
  if (std::error_code ec; !std::filesystem::exists(file, ec))
    throw InputError(file, "",
                     "neither a flight (orbit-zoom, orbit) nor a keyframe file: no such file" +
                         did_you_mean(file, {"orbit-zoom", "orbit"}));
  if (std::error_code ec; std::filesystem::is_directory(file, ec))
    throw InputError(file, "", "is a directory, not a keyframe file");
  const nlohmann::json j = read_json_file(file, "keyframe file");
  if (!j.is_object() || !j.contains("keyframes") || !j["keyframes"].is_array() ||
      j["keyframes"].empty())
    throw InputError(file, "", "expected {\"keyframes\": [ ... ]} with at least one keyframe");
  std::vector<Camera> keys;
  for (size_t i = 0; i < j["keyframes"].size(); ++i) {
    const auto& k = j["keyframes"][i];
    Camera c;
    c.eye = read_vec3(k, "eye", file, i);
    c.target = read_vec3(k, "target", file, i);
    c.up = k.contains("up") ? read_vec3(k, "up", file, i) : glm::dvec3(0, 1, 0);
    if (k.contains("fov") && !k["fov"].is_number())
      throw InputError(file, "keyframe " + std::to_string(i), "fov: expected a number");
    c.fov_y_degrees = k.value("fov", 40.0);
    if (const std::string problem = camera_problem(c); !problem.empty())
      throw InputError(file, "keyframe " + std::to_string(i), problem);
    keys.push_back(c);
  }
  return keys;
}

}  // namespace

Camera::ImagePlane Camera::image_plane(int width, int height) const {
  const glm::dvec3 f = forward();
  const glm::dvec3 r = glm::normalize(glm::cross(f, up));
  const glm::dvec3 u = glm::cross(r, f);
  const double half_h = std::tan(radians(fov_y_degrees) / 2);
  const double half_w = half_h * double(width) / double(height);
  return {f, half_w * r, half_h * u};
}

glm::dvec3 Camera::ray_direction(double x, double y, int width, int height) const {
  const ImagePlane p = image_plane(width, height);
  const double sx = 2 * (x + 0.5) / width - 1;
  const double sy = 1 - 2 * (y + 0.5) / height;
  return glm::normalize(p.forward + sx * p.right + sy * p.up);
}

namespace {

glm::dvec3 view_direction(double azimuth, double elevation) {
  return {std::cos(elevation) * std::sin(azimuth), std::sin(elevation),
          std::cos(elevation) * std::cos(azimuth)};
}

// The smallest distance from the box centre at which every box corner projects inside the
// frustum, for every azimuth of the orbit at this elevation: constant along an orbit and much
// tighter than the bounding sphere for elongated data. Per corner offset o and view direction d
// (from the centre towards the eye), depth is D - o.d and the corner fits when
// |o.right| <= tan(fov_x/2) (D - o.d) and |o.up| <= tan(fov_y/2) (D - o.d).
double orbit_fit_distance(const Bounds& b, double aspect, double elevation, double fov_y) {
  const Sphere s = bounding_sphere(b);
  if (b.empty) return s.radius / std::sin(fov_y / 2);
  const double th = std::tan(fov_y / 2) / 1.05, tw = th * aspect;  // a 5% margin
  double distance = 0;
  for (int a = 0; a < 360; ++a) {
    const glm::dvec3 d = view_direction(radians(a), elevation);
    const glm::dvec3 right = glm::normalize(glm::cross(-d, glm::dvec3(0, 1, 0)));
    const glm::dvec3 up = glm::cross(right, -d);
    for (int i = 0; i < 8; ++i) {
      const glm::dvec3 corner((i & 1) ? b.max[0] : b.min[0], (i & 2) ? b.max[1] : b.min[1],
                              (i & 4) ? b.max[2] : b.min[2]);
      const glm::dvec3 o = corner - s.centre;
      distance = std::max(distance, glm::dot(o, d) + std::max(std::abs(glm::dot(o, right)) / tw,
                                                              std::abs(glm::dot(o, up)) / th));
    }
  }
  // Never inside the sphere: the near plane must stay in front of the data.
  return std::max(distance, 1.01 * s.radius);
}

}  // namespace

void hold_in_clip_planes(Camera& c, const Bounds& b) {
  if (b.empty) return;
  Camera wide = c;
  fit_clip_planes(wide, bounding_sphere(b));
  c.near = std::min(c.near, wide.near);
  c.far = std::max(c.far, wide.far);
}

Camera frame_bounds(const Bounds& bounds, double aspect, double azimuth_degrees,
                    double elevation_degrees, double distance_scale, double fov_y_degrees) {
  const Sphere s = bounding_sphere(bounds);
  const double el = radians(elevation_degrees);
  const double distance =
      orbit_fit_distance(bounds, aspect, el, radians(fov_y_degrees)) * distance_scale;
  Camera c;
  c.target = s.centre;
  c.eye = s.centre + distance * view_direction(radians(azimuth_degrees), el);
  c.up = {0, 1, 0};
  c.fov_y_degrees = fov_y_degrees;
  fit_clip_planes(c, s);
  return c;
}

FlightKind parse_flight_kind(const std::string& name) {
  if (name == "orbit-zoom") return FlightKind::OrbitZoom;
  if (name == "orbit") return FlightKind::Orbit;
  return FlightKind::Keyframes;
}

const char* to_string(FlightKind kind) {
  switch (kind) {
    case FlightKind::OrbitZoom:
      return "orbit-zoom";
    case FlightKind::Orbit:
      return "orbit";
    case FlightKind::Keyframes:
      return "keyframes";
  }
  return "?";
}

std::vector<Camera> make_flight(const Bounds& bounds, double aspect, const FlightOptions& o) {
  if (o.frames < 1) throw Error("flight: at least one frame");
  std::vector<Camera> cameras;
  if (o.kind == FlightKind::Keyframes) {
    const std::vector<Camera> keys = read_keyframes(o.keyframes_file);
    const Sphere s = bounding_sphere(bounds);
    for (int i = 0; i < o.frames; ++i) {
      const double at = o.frames > 1 ? double(i) / (o.frames - 1) * double(keys.size() - 1) : 0;
      const size_t k = std::min(size_t(at), keys.size() - 1);
      const size_t k1 = std::min(k + 1, keys.size() - 1);
      const double t = at - double(k);
      Camera c;
      c.eye = glm::mix(keys[k].eye, keys[k1].eye, t);
      c.target = glm::mix(keys[k].target, keys[k1].target, t);
      c.up = glm::mix(keys[k].up, keys[k1].up, t);
      c.fov_y_degrees =
          keys[k].fov_y_degrees + t * (keys[k1].fov_y_degrees - keys[k].fov_y_degrees);
      fit_clip_planes(c, s);
      // Good keyframes can make a bad camera between them (an up that turns along the view, an
      // eye that passes through the target): refused, naming the frame and its keyframes.
      if (const std::string problem = camera_problem(c); !problem.empty())
        throw InputError(o.keyframes_file,
                         "frame " + std::to_string(i) + " (between keyframes " + std::to_string(k) +
                             " and " + std::to_string(k1) + ")",
                         problem);
      cameras.push_back(c);
    }
    return cameras;
  }
  for (int i = 0; i < o.frames; ++i) {
    const double s = double(i) / o.frames;
    double zoom = 0;
    if (o.kind == FlightKind::OrbitZoom)
      for (const double centre : {0.3, 0.7}) {
        const double x = std::abs(s - centre) / 0.12;  // each zoom-in spans 24% of the flight
        if (x < 1) zoom = std::max(zoom, 0.5 * (1 + std::cos(std::numbers::pi * x)));
      }
    cameras.push_back(frame_bounds(bounds, aspect, 360.0 * s, o.elevation_degrees,
                                   1.0 - 0.65 * zoom, o.fov_y_degrees));
    if (const std::string problem = camera_problem(cameras.back()); !problem.empty())
      throw Error("flight " + std::string(to_string(o.kind)) + ", frame " + std::to_string(i) +
                  ": the data's bounds make no camera: " + problem);
  }
  return cameras;
}

}  // namespace linebake
