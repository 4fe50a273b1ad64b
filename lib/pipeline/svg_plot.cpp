#include "pipeline/svg_plot.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace linebake {
namespace {

std::string number(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.1f", v);
  return text;
}

// Tick label: as few digits as the step needs.
std::string tick_label(double v, double step) {
  char text[32];
  const int digits = step >= 1 ? 0 : int(std::ceil(-std::log10(step) - 1e-9));
  if (std::fabs(v) >= 1e5 || (v != 0 && std::fabs(v) < 1e-4))
    std::snprintf(text, sizeof text, "%.0e", v);
  else
    std::snprintf(text, sizeof text, "%.*f", std::min(digits, 6), v);
  return text;
}

// A 1, 2 or 5 x 10^k step giving about `count` intervals over [lo, hi].
double nice_step(double lo, double hi, int count) {
  const double raw = (hi - lo) / count;
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  const double m = raw / magnitude;
  return (m < 1.5 ? 1 : m < 3.5 ? 2 : m < 7.5 ? 5 : 10) * magnitude;
}

}  // namespace

std::string xml_escape(const std::string& text) {
  std::string out;
  for (char c : text) switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
    }
  return out;
}

std::string plot_colour(size_t i) {
  static const char* colours[] = {"#4e79a7", "#f28e2b", "#e15759", "#76b7b2", "#59a14f",
                                  "#edc948", "#b07aa1", "#ff9da7", "#9c755f", "#bab0ac"};
  return colours[i % 10];
}

std::string plot_dash(size_t i) {
  static const char* dashes[] = {"", "7,4", "2,3"};
  return dashes[(i / 10) % 3];
}

std::string svg_line_plot(const LinePlot& plot, int width, int height) {
  const double left = 62, right = 150, top = 28, bottom = 42;  // margins; legend on the right
  const double plot_w = width - left - right, plot_h = height - top - bottom;
  const auto usable = [&](double v) { return std::isfinite(v) && (!plot.log_y || v > 0); };
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  size_t points = 0;
  for (const PlotSeries& s : plot.series) {
    points = std::max(points, s.y.size());
    for (double v : s.y)
      if (usable(v)) {
        const double t = plot.log_y ? std::log10(v) : v;
        lo = std::min(lo, t);
        hi = std::max(hi, t);
      }
  }
  std::string svg = "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + std::to_string(width) +
                    "\" height=\"" + std::to_string(height) + "\" viewBox=\"0 0 " +
                    std::to_string(width) + " " + std::to_string(height) +
                    "\" font-family=\"sans-serif\" font-size=\"11\">\n";
  svg += "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  svg += "<text x=\"" + number(left) + "\" y=\"16\" font-size=\"13\" font-weight=\"bold\">" +
         xml_escape(plot.title) + "</text>\n";
  if (!(lo <= hi)) {
    svg += "<text x=\"" + number(left) + "\" y=\"" + number(top + plot_h / 2) +
           "\">no data</text>\n</svg>\n";
    return svg;
  }
  // Axis range: whole decades for log plots, nice steps with a little headroom otherwise.
  double step;
  if (plot.log_y) {
    lo = std::floor(lo);
    hi = std::max(std::ceil(hi), lo + 1);
    step = 1;
  } else {
    if (hi - lo < 1e-12 * std::max(1.0, std::fabs(hi))) {
      lo -= std::max(1e-3, std::fabs(lo) * 0.05);
      hi += std::max(1e-3, std::fabs(hi) * 0.05);
    }
    step = nice_step(lo, hi, 5);
    lo = std::floor(lo / step) * step;
    hi = std::ceil(hi / step) * step;
  }
  const double x_span = points > 1 ? double(points - 1) : 1.0;
  const auto px = [&](double x) { return left + plot_w * x / x_span; };
  const auto py = [&](double t) { return top + plot_h * (1 - (t - lo) / (hi - lo)); };
  // Grid and y ticks.
  for (double t = lo; t <= hi + step * 1e-6; t += step) {
    const double y = py(t);
    svg += "<line x1=\"" + number(left) + "\" x2=\"" + number(left + plot_w) + "\" y1=\"" +
           number(y) + "\" y2=\"" + number(y) + "\" stroke=\"#ddd\"/>\n";
    const std::string label =
        plot.log_y ? tick_label(std::pow(10.0, t), std::pow(10.0, t)) : tick_label(t, step);
    svg += "<text x=\"" + number(left - 4) + "\" y=\"" + number(y + 4) + "\" text-anchor=\"end\">" +
           label + "</text>\n";
  }
  // X ticks: about 8 frame numbers.
  const size_t x_step = std::max<size_t>(1, size_t(nice_step(0, std::max(1.0, x_span), 8)));
  for (size_t x = 0; x < std::max<size_t>(points, 1); x += x_step)
    svg += "<text x=\"" + number(px(double(x))) + "\" y=\"" + number(top + plot_h + 14) +
           "\" text-anchor=\"middle\">" + std::to_string(x) + "</text>\n";
  svg += "<rect x=\"" + number(left) + "\" y=\"" + number(top) + "\" width=\"" + number(plot_w) +
         "\" height=\"" + number(plot_h) + "\" fill=\"none\" stroke=\"#888\"/>\n";
  svg += "<text x=\"" + number(left + plot_w / 2) + "\" y=\"" + number(height - 8) +
         "\" text-anchor=\"middle\">" + xml_escape(plot.x_label) + "</text>\n";
  svg += "<text transform=\"translate(14," + number(top + plot_h / 2) +
         ") rotate(-90)\" text-anchor=\"middle\">" + xml_escape(plot.y_label) + "</text>\n";
  // Series: polylines broken at unusable values; single points as dots.
  for (size_t i = 0; i < plot.series.size(); ++i) {
    const PlotSeries& s = plot.series[i];
    std::vector<std::string> runs(1);
    for (size_t x = 0; x < s.y.size(); ++x) {
      if (!usable(s.y[x])) {
        if (!runs.back().empty()) runs.emplace_back();
        continue;
      }
      const double t = plot.log_y ? std::log10(s.y[x]) : s.y[x];
      runs.back() += number(px(double(x))) + "," + number(py(t)) + " ";
    }
    const std::string dash =
        s.dash.empty() ? "" : " stroke-dasharray=\"" + xml_escape(s.dash) + "\"";
    for (const std::string& run : runs) {
      if (run.empty()) continue;
      if (std::count(run.begin(), run.end(), ' ') == 1) {
        const size_t comma = run.find(',');
        svg += "<circle cx=\"" + run.substr(0, comma) + "\" cy=\"" +
               run.substr(comma + 1, run.size() - comma - 2) + "\" r=\"2.5\" fill=\"" + s.colour +
               "\"/>\n";
      } else {
        svg += "<polyline fill=\"none\" stroke-width=\"1.6\" stroke=\"" + s.colour + "\"" + dash +
               " points=\"" + run + "\"/>\n";
      }
    }
    const double ly = top + 6 + 16 * double(i);
    svg += "<line x1=\"" + number(left + plot_w + 10) + "\" x2=\"" + number(left + plot_w + 28) +
           "\" y1=\"" + number(ly) + "\" y2=\"" + number(ly) + "\" stroke-width=\"2\" stroke=\"" +
           s.colour + "\"" + dash + "/>\n";
    svg += "<text x=\"" + number(left + plot_w + 32) + "\" y=\"" + number(ly + 4) + "\">" +
           xml_escape(s.name) + "</text>\n";
  }
  svg += "</svg>\n";
  return svg;
}

}  // namespace linebake
