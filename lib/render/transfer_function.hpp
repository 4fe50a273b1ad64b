#pragma once
// Transfer function: attribute value -> colour and opacity, piecewise linear between points.
// Colours in files are sRGB-encoded like every colour picker's; they are held and composited
// in linear RGB.

#include <array>
#include <string>
#include <vector>

namespace linebake {

struct Rgba {
  double r = 0, g = 0, b = 0, a = 0;  // linear RGB, straight (not premultiplied) alpha
};

struct TransferFunction {
  struct ColourPoint {
    double x;                    // position in [0, 1] of the attribute range
    std::array<double, 3> srgb;  // sRGB-encoded, [0, 1]
  };
  struct OpacityPoint {
    double x, opacity;
  };
  std::string name;
  std::vector<ColourPoint> colours;     // sorted by x
  std::vector<OpacityPoint> opacities;  // sorted by x
  // Attribute values mapped to x = 0 and x = 1; both zero: the data's own range is used.
  std::array<double, 2> range{0, 0};

  // Colour and opacity at a normalised position t (clamped to [0, 1]).
  Rgba at(double t) const;
  Rgba evaluate(double value) const {
    const double span = range[1] - range[0];
    return at(span > 0 ? (value - range[0]) / span : 0.5);
  }
};

// The paper's three settings: "opaque" (opacity 1), "semi" (transparent lines whose opacity
// ramps up to opaque features of interest at the top of the range), "transparent" (constant 0.1).
// All use the same cool-to-warm colour map (Moreland 2009).
TransferFunction transfer_function_preset(const std::string& name);
bool is_transfer_function_preset(const std::string& name);

// JSON: {"name": .., "range": [lo, hi], "colours": [[x, r, g, b], ...],
//        "opacities": [[x, a], ...]}. Errors name the file and the entry.
TransferFunction load_transfer_function(const std::string& path);
void save_transfer_function(const TransferFunction& tf, const std::string& path);
// A preset name or a JSON file.
TransferFunction resolve_transfer_function(const std::string& name_or_path);

double srgb_to_linear(double c);
double linear_to_srgb(double c);

}  // namespace linebake
