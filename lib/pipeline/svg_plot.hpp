#pragma once
// Line plots as standalone SVG: one series per technique over the frames of a flight, like the
// paper's per-frame time and error figures. No scripts or external resources, so the SVG can be
// inlined in an HTML page or opened on its own.

#include <string>
#include <vector>

namespace linebake {

struct PlotSeries {
  std::string name;
  std::string colour;     // any SVG colour, e.g. "#1f77b4"
  std::vector<double> y;  // y[i] at x = i; NaN or infinity leaves a gap
  std::string dash = "";  // an SVG stroke-dasharray ("7,4"); "" draws it solid
};

struct LinePlot {
  std::string title;
  std::string x_label = "frame";
  std::string y_label;
  bool log_y = false;  // decades on the y axis (values <= 0 leave a gap)
  std::vector<PlotSeries> series;
};

std::string svg_line_plot(const LinePlot& plot, int width = 520, int height = 300);

// A distinct colour for the i-th series (Tableau 10, then repeating) and a dash pattern that
// tells the repeats apart: solid for the first ten, dashed for the next, dotted after. Two
// series that coincide (tiles and embree over capsules) then still show both.
std::string plot_colour(size_t i);
std::string plot_dash(size_t i);

// Escapes &, <, >, " and ' for XML/HTML text and attributes.
std::string xml_escape(const std::string& text);

}  // namespace linebake
