#include "render/transfer_function.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <vector>

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/json_file.hpp"
#include "core/nearest.hpp"

namespace linebake {

double srgb_to_linear(double c) {
  return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}

double linear_to_srgb(double c) {
  c = std::clamp(c, 0.0, 1.0);
  return c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1 / 2.4) - 0.055;
}

namespace {

template <class Point, class Get>
auto interpolate(const std::vector<Point>& points, double t, Get get) {
  if (t <= points.front().x) return get(points.front());
  if (t >= points.back().x) return get(points.back());
  const auto hi = std::upper_bound(points.begin(), points.end(), t,
                                   [](double v, const Point& p) { return v < p.x; });
  const auto lo = hi - 1;
  const double w = hi->x > lo->x ? (t - lo->x) / (hi->x - lo->x) : 0.0;
  auto a = get(*lo), b = get(*hi);
  for (size_t k = 0; k < a.size(); ++k) a[k] += w * (b[k] - a[k]);
  return a;
}

const std::vector<TransferFunction::ColourPoint> kCoolWarm = {
    {0.0, {0.230, 0.299, 0.754}}, {0.5, {0.865, 0.865, 0.865}}, {1.0, {0.706, 0.016, 0.150}}};

}  // namespace

Rgba TransferFunction::at(double t) const {
  t = std::clamp(std::isfinite(t) ? t : 0.0, 0.0, 1.0);
  // Interpolated in sRGB, as colour-map points are designed, then linearised.
  const auto c = interpolate(colours, t, [](const ColourPoint& p) { return p.srgb; });
  const auto a = interpolate(
      opacities, t, [](const OpacityPoint& p) { return std::array<double, 1>{p.opacity}; });
  return {srgb_to_linear(c[0]), srgb_to_linear(c[1]), srgb_to_linear(c[2]),
          std::clamp(a[0], 0.0, 1.0)};
}

bool is_transfer_function_preset(const std::string& name) {
  return name == "opaque" || name == "semi" || name == "transparent";
}

TransferFunction transfer_function_preset(const std::string& name) {
  TransferFunction tf;
  tf.name = name;
  tf.colours = kCoolWarm;
  if (name == "opaque")
    tf.opacities = {{0.0, 1.0}, {1.0, 1.0}};
  else if (name == "semi")
    tf.opacities = {{0.0, 0.02}, {0.4, 0.08}, {1.0, 1.0}};
  else if (name == "transparent")
    tf.opacities = {{0.0, 0.1}, {1.0, 0.1}};
  else
    throw Error("unknown transfer function preset '" + name + "' (opaque, semi, transparent)");
  return tf;
}

TransferFunction load_transfer_function(const std::string& path) {
  const nlohmann::json j = read_json_file(path, "transfer function");
  TransferFunction tf;
  const auto number = [&](const nlohmann::json& v, const std::string& where) {
    if (!v.is_number()) throw InputError(path, where, "expected a number");
    const double x = v.get<double>();
    if (!std::isfinite(x)) throw InputError(path, where, "not a finite number");
    return x;
  };
  const auto points = [&](const char* key, size_t width) {
    if (!j.is_object() || !j.contains(key) || !j[key].is_array() || j[key].empty())
      throw InputError(path, key, "expected a non-empty array of points");
    std::vector<std::vector<double>> out;
    for (size_t i = 0; i < j[key].size(); ++i) {
      const std::string where = std::string(key) + "[" + std::to_string(i) + "]";
      const auto& p = j[key][i];
      if (!p.is_array() || p.size() != width)
        throw InputError(path, where, "expected " + std::to_string(width) + " numbers");
      std::vector<double> v;
      for (size_t k = 0; k < width; ++k) v.push_back(number(p[k], where));
      if (v[0] < 0 || v[0] > 1 || (!out.empty() && v[0] < out.back()[0]))
        throw InputError(path, where, "positions must lie in [0, 1] and not decrease");
      for (size_t k = 1; k < width; ++k)
        if (v[k] < 0 || v[k] > 1) throw InputError(path, where, "values must lie in [0, 1]");
      out.push_back(v);
    }
    return out;
  };
  for (const auto& p : points("colours", 4)) tf.colours.push_back({p[0], {p[1], p[2], p[3]}});
  for (const auto& p : points("opacities", 2)) tf.opacities.push_back({p[0], p[1]});
  if (j.contains("name") && !j["name"].is_string())
    throw InputError(path, "name", "expected a string");
  tf.name = j.value("name", path);
  if (j.contains("range")) {
    if (!j["range"].is_array() || j["range"].size() != 2)
      throw InputError(path, "range", "expected [low, high]");
    tf.range = {number(j["range"][0], "range"), number(j["range"][1], "range")};
    // [0, 0] is the data's own range; any other must run upwards (a reversed one had mapped every
    // value to the middle of the colours, silently).
    if (!(tf.range[0] == 0 && tf.range[1] == 0) && !(tf.range[0] < tf.range[1]))
      throw InputError(path, "range",
                       "[low, high] with low below high, or [0, 0] for the data's own range; to "
                       "reverse the colours, reverse their positions instead");
  }
  return tf;
}

void save_transfer_function(const TransferFunction& tf, const std::string& path) {
  nlohmann::json j;
  j["name"] = tf.name;
  j["range"] = {tf.range[0], tf.range[1]};
  j["colours"] = nlohmann::json::array();
  for (const auto& p : tf.colours) j["colours"].push_back({p.x, p.srgb[0], p.srgb[1], p.srgb[2]});
  j["opacities"] = nlohmann::json::array();
  for (const auto& p : tf.opacities) j["opacities"].push_back({p.x, p.opacity});
  write_file_atomically(path, json_text(j, 2) + "\n");
}

TransferFunction resolve_transfer_function(const std::string& name_or_path) {
  if (is_transfer_function_preset(name_or_path)) return transfer_function_preset(name_or_path);
  // Neither a preset nor a file: say which presets there are, and the nearest one.
  // A bare name is a mistyped preset (a bad command line); a path is a missing file (bad input).
  if (!std::filesystem::exists(name_or_path)) {
    const std::string message =
        "neither a transfer-function preset (opaque, semi, transparent) nor a file" +
        did_you_mean(name_or_path, {"opaque", "semi", "transparent"});
    if (name_or_path.find_first_of("./") == std::string::npos)
      throw UsageError(name_or_path + ": " + message);
    throw InputError(name_or_path, "", message);
  }
  return load_transfer_function(name_or_path);
}

}  // namespace linebake
