#include "pipeline/html_report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>

#include "cache/cache.hpp"
#include "core/base64.hpp"
#include "metrics/image_metrics.hpp"
#include "pipeline/evaluation_report.hpp"
#include "pipeline/paper_table1.hpp"
#include "pipeline/report.hpp"
#include "pipeline/svg_plot.hpp"
#include "render/image.hpp"

namespace linebake {
namespace {

constexpr int kThumbnailWidth = 320;

std::string png_uri(const Image& image) {
  return "data:image/png;base64," + base64_encode(encode_png(image));
}

// Box-filtered to at most kThumbnailWidth pixels across (an integer factor).
Image thumbnail(const Image& image) {
  const int factor = std::max(1, (image.width + kThumbnailWidth - 1) / kThumbnailWidth);
  if (factor == 1) return image;
  Image out(image.width / factor, image.height / factor, image.channels);
  out.srgb_encoded = image.srgb_encoded;
  for (int y = 0; y < out.height; ++y)
    for (int x = 0; x < out.width; ++x)
      for (int c = 0; c < image.channels; ++c) {
        float sum = 0;
        for (int dy = 0; dy < factor; ++dy)
          for (int dx = 0; dx < factor; ++dx) sum += image.at(x * factor + dx, y * factor + dy, c);
        out.at(x, y, c) = sum / float(factor * factor);
      }
  return out;
}

Image crop(const Image& image, const ImageWindow& w) {
  Image out(w.width, w.height, image.channels);
  out.srgb_encoded = image.srgb_encoded;
  for (int y = 0; y < w.height; ++y)
    for (int x = 0; x < w.width; ++x)
      for (int c = 0; c < image.channels; ++c) out.at(x, y, c) = image.at(w.x + x, w.y + y, c);
  return out;
}

double luminance(const Image& image, int x, int y) {
  if (image.channels == 1) return image.at(x, y, 0);
  return 0.2126 * image.at(x, y, 0) + 0.7152 * image.at(x, y, 1) + 0.0722 * image.at(x, y, 2);
}

// A depth-complexity image (16-bit counts) in a perceptual blue-to-yellow ramp, 0 = black.
Image colour_counts(const Image& counts, double& max_count) {
  max_count = 0;
  for (float v : counts.pixels) max_count = std::max(max_count, double(v) * 65535.0);
  static const float ramp[5][3] = {{0.27f, 0.00f, 0.33f},
                                   {0.23f, 0.32f, 0.55f},
                                   {0.13f, 0.57f, 0.55f},
                                   {0.37f, 0.79f, 0.38f},
                                   {0.99f, 0.91f, 0.14f}};
  Image out(counts.width, counts.height, 3);
  out.srgb_encoded = true;
  for (int y = 0; y < counts.height; ++y)
    for (int x = 0; x < counts.width; ++x) {
      const double n = double(counts.at(x, y, 0)) * 65535.0;
      if (n < 0.5) continue;
      const double t = max_count > 1 ? std::clamp((n - 1) / (max_count - 1), 0.0, 1.0) * 4 : 4;
      const int i = std::min(3, int(t));
      const float f = float(t - i);
      for (int c = 0; c < 3; ++c) out.at(x, y, c) = ramp[i][c] * (1 - f) + ramp[i + 1][c] * f;
    }
  return out;
}

std::string relative(const Pipeline& p, const std::string& path) {
  return std::filesystem::path(path).lexically_relative(p.output).generic_string();
}

double number_or(const nlohmann::json& j, const char* key, double fallback) {
  return j.contains(key) && j[key].is_number() ? j[key].get<double>() : fallback;
}

std::string plot_name(const std::string& ds, const std::string& tf, const char* what) {
  return ds + "-" + tf + "-" + what + ".svg";
}

// Cells are HTML already (a skipped technique's cell carries its note mark).
std::string html_table(const std::vector<std::string>& header,
                       const std::vector<std::vector<std::string>>& rows) {
  std::string html = "<table><tr>";
  for (const std::string& h : header) html += "<th>" + xml_escape(h) + "</th>";
  html += "</tr>\n";
  for (const auto& row : rows) {
    html += "<tr>";
    for (size_t i = 0; i < row.size(); ++i)
      html += std::string(i ? "<td class=\"n\">" : "<td>") + row[i] + "</td>";
    html += "</tr>\n";
  }
  return html + "</table>\n";
}

std::string table(const std::vector<std::string>& header,
                  std::vector<std::vector<std::string>> rows) {
  for (auto& row : rows)
    for (std::string& cell : row) cell = xml_escape(cell);
  return html_table(header, rows);
}

// Embree's BVH as the embree technique built it when it rendered `dataset`, for a cache without
// an embree asset: {buffers + BVH bytes, prepare + commit seconds}; null when none rendered.
nlohmann::json render_time_embree_bvh(const nlohmann::json& evaluation,
                                      const std::string& dataset) {
  for (const auto& r : evaluation["results"])
    if (r["dataset"] == dataset && r["render"] == "embree" && r.contains("bvh")) {
      const nlohmann::json& bvh = r["bvh"];
      return {{"memory_bytes",
               bvh.value("buffer_bytes", uint64_t{0}) + bvh.value("bvh_bytes", uint64_t{0})},
              {"seconds", bvh.value("prepare_s", 0.0) + bvh.value("commit_s", 0.0)}};
    }
  return nullptr;
}

constexpr const char* kBuiltAtRender =
    " * = not in the cache: the BVH the embree technique built when it rendered (its input "
    "buffers and rtcCommitScene; memory: the buffers and the BVH).";

constexpr const char* kSharedPass =
    " \u2020 = built in one pass over the data with other assets (Table 1's *): its time overlaps "
    "theirs.";

// Ours beside the paper's Table 1, for the data sets the paper has. Where the cache holds no
// embree asset but the embree technique rendered, its OSP/Embree cells are the BVH that render
// built (marked), not "not built".
std::string paper_comparison(const nlohmann::json& evaluation) {
  std::vector<std::vector<std::string>> rows;
  // Three decimals, as the paper's Table 1 has two; a size too small for them (a small data
  // set's voxel grid read "0.000") with two significant digits.
  const auto gb_text = [](double bytes) {
    const double gb = bytes / 1e9;
    if (gb == 0 || gb >= 0.0005) return fixed(gb, 3);
    // Two significant digits as decimals (0.000029), never an exponent.
    return fixed(gb, std::min(12, 1 - int(std::floor(std::log10(gb)))));
  };
  const auto gb = [&](const nlohmann::json& asset) {
    return asset.is_object() ? gb_text(asset.value("memory_bytes", 0.0)) : "-";
  };
  // The paper's build times as it gives them, to a tenth of a second.
  const auto paper_s = [](double seconds) { return fixed(seconds, 1) + " s"; };
  // Times of a pass shared with other steps marked as Table 1 marks them (its note).
  bool shared_pass = false;
  const auto secs = [&](const nlohmann::json& asset) -> std::string {
    if (!asset.is_object()) return "-";
    const nlohmann::json& build = asset["build"];
    const bool shared = build.contains("built_with") && !build["built_with"].empty();
    shared_pass = shared_pass || shared;
    return format_duration(build.value("wall_s", 0.0)) + (shared ? " \u2020" : "");
  };
  bool built_at_render = false;
  for (const auto& c : evaluation["caches"]) {
    const PaperTable1Row* paper = find_paper_table1(c.value("name", std::string()));
    if (!paper) continue;
    const nlohmann::json& a = c["assets"];
    const auto asset = [&](const char* name) {
      return a.contains(name) ? a[name] : nlohmann::json();
    };
    const double segments = c["lines"]["stats"].value("segments", 0.0);
    std::string embree_gb = gb(asset("embree")), embree_s = secs(asset("embree"));
    const nlohmann::json at_render = render_time_embree_bvh(evaluation, c.value("name", ""));
    if (!a.contains("embree") && at_render.is_object()) {
      embree_gb = gb_text(at_render["memory_bytes"].get<double>()) + " *";
      embree_s = format_duration(at_render["seconds"].get<double>()) + " *";
      built_at_render = true;
    }
    rows.push_back({c["name"].get<std::string>() + " (linebake)", fixed(segments / 1e6, 3),
                    fixed(c["lines"].value("memory_bytes", 0.0) / 1e6, 1), gb(asset("tubes")),
                    embree_gb, gb(asset("rtx")), gb(asset("voxels")), secs(asset("tubes")),
                    embree_s, secs(asset("rtx")), secs(asset("voxels"))});
    rows.push_back({paper->dataset + " (paper)", fixed(paper->segments_millions, 1),
                    fixed(paper->line_model_mb, 0), fixed(paper->raster_gb, 2),
                    fixed(paper->osp_gb, 2), fixed(paper->rtx_gb, 2), fixed(paper->vrc_gb, 2),
                    paper_s(paper->raster_s), paper_s(paper->osp_s), paper_s(paper->rtx_s),
                    paper_s(paper->vrc_s)});
  }
  if (rows.empty()) return "";
  return "<p>Beside the paper's Table 1 (its machine, its data at full size; linebake's synthetic "
         "stand-ins at the pipeline's scale, so compare ratios, not absolute values). "
         "'-' = not built by this pipeline." +
         std::string(built_at_render ? kBuiltAtRender : "") +
         std::string(shared_pass ? kSharedPass : "") + "</p>\n" +
         table({"data set", "LS (M)", "LM (MB)", "raster (GB)", "OSP/Embree (GB)", "RTX (GB)",
                "VRC (GB)", "raster build", "OSP build", "RTX build", "VRC build"},
               rows);
}

const char* kStyle = R"(<style>
body{font-family:sans-serif;margin:1.5em;max-width:1500px;color:#222}
table{border-collapse:collapse;margin:0.5em 0 1em}th,td{border:1px solid #ccc;padding:2px 6px}
td.n{text-align:right;font-variant-numeric:tabular-nums}th{background:#f3f3f3}
.plots{display:flex;flex-wrap:wrap;gap:8px}.grid td{vertical-align:top;text-align:center}
img.closeup{image-rendering:pixelated}.skip{color:#888}.notes{font-size:90%;color:#555}
</style>
)";

// Reports, once the page has loaded, how many images decoded: "<loaded>/<total>" in
// <html data-images>, for the headless browser check and anyone debugging a page.
const char* kImageCheck = R"(<script>
window.addEventListener('load', function () {
  var images = Array.prototype.slice.call(document.images);
  var loaded = images.filter(function (i) { return i.complete && i.naturalWidth > 0; }).length;
  document.documentElement.setAttribute('data-images', loaded + '/' + images.length);
});
</script>
)";

// Two decimals, and two significant digits below 0.1, where two decimals would read "0.00x".
// The summary of one data set and transfer function: a row per technique; a skipped one has a
// short cell with a numbered note under the table (its reason would stretch the column) and the
// reason as the cell's tooltip.
std::string summary_table(const Pipeline& p, const std::vector<const nlohmann::json*>& results,
                          const nlohmann::json& machine) {
  double reference_seconds = 0;
  for (const nlohmann::json* r : results)
    if ((*r)["technique"] == p.reference && r->contains("mean_seconds"))
      reference_seconds = (*r)["mean_seconds"].get<double>();
  std::vector<std::vector<std::string>> rows;
  std::string notes;
  int note = 0;
  for (const nlohmann::json* r : results) {
    const std::string name = xml_escape((*r)["technique"].get<std::string>());
    if (r->contains("skipped")) {
      const std::string reason = xml_escape((*r)["skipped"].get<std::string>());
      const std::string mark = std::to_string(++note);
      rows.push_back(
          {name,
           "<span class=\"skip\" title=\"" + reason + "\">skipped<sup>" + mark + "</sup></span>",
           "", "", "", "", ""});
      notes += "<li value=\"" + mark + "\">" + name + ": " + reason + "</li>";
      continue;
    }
    std::vector<std::string> cells =
        summary_cells(*r, reference_seconds, (*r)["technique"] == p.reference);
    for (std::string& cell : cells) cell = xml_escape(cell);
    if (r->contains("not_compared")) {
      const std::string reason = xml_escape((*r)["not_compared"].get<std::string>());
      const std::string mark = std::to_string(++note);
      cells[kPsnrColumn] = "<span class=\"skip\" title=\"" + reason + "\">" + cells[kPsnrColumn] +
                           "<sup>" + mark + "</sup></span>";
      notes += "<li value=\"" + mark + "\">" + name + ": " + reason + "</li>";
    }
    rows.push_back(std::move(cells));
  }
  std::string html = html_table(summary_columns(), rows);
  if (!notes.empty()) html += "<ol class=\"notes\">" + notes + "</ol>\n";
  return html + "<p>" + summary_note(machine, p.reference, true) + " " + psnr_cap_note() +
         ".</p>\n";
}

}  // namespace

ImageWindow closeup_window(const Image& reference, const std::vector<Image>& images) {
  const int w = reference.width, h = reference.height;
  ImageWindow best{(w - w / 4) / 2, (h - h / 4) / 2, std::max(1, w / 4), std::max(1, h / 4)};
  std::vector<double> table(size_t(w + 1) * size_t(h + 1), 0.0);
  const auto at = [&](int x, int y) -> double& { return table[size_t(y) * size_t(w + 1) + x]; };
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      double diff = 0;
      for (const Image& image : images)
        if (image.width == w && image.height == h)
          diff += std::fabs(luminance(image, x, y) - luminance(reference, x, y));
      at(x + 1, y + 1) = diff + at(x, y + 1) + at(x + 1, y) - at(x, y);
    }
  // Every position: the table makes each window four lookups (2 million at 1920x1080); a search
  // on a grid of w / 64 had missed the best window by up to a grid step.
  double best_sum = 0;
  for (int y = 0; y + best.height <= h; ++y)
    for (int x = 0; x + best.width <= w; ++x) {
      const double sum = at(x + best.width, y + best.height) - at(x, y + best.height) -
                         at(x + best.width, y) + at(x, y);
      if (sum > best_sum * (1 + 1e-12) + 1e-12) {
        best_sum = sum;
        best.x = x;
        best.y = y;
      }
    }
  return best;
}

std::string error_image_caption() {
  return "Error images: the absolute difference from the reference (mean over the colour "
         "channels) times a gain of " +
         fixed(kErrorImageGain, 0) + ", inverted (white = equal, black = a difference of " +
         fixed(100 / kErrorImageGain, 0) + " % of full scale or more).";
}

int grid_frame(const Pipeline& p) {
  return p.frame_count / 2;
}

std::map<std::string, std::string> evaluation_plots(const Pipeline& p, const nlohmann::json& e) {
  std::map<std::string, std::string> plots;
  for (const PipelineDataset& d : p.datasets)
    for (const std::string& tf : p.transfer_functions) {
      LinePlot time{d.name + ", " + tf + ": frame time", "frame", "ms (log)", true, {}};
      LinePlot psnr{d.name + ", " + tf + ": PSNR", "frame", "dB", false, {}};
      LinePlot ssim{d.name + ", " + tf + ": SSIM", "frame", "SSIM", false, {}};
      LinePlot memory{d.name + ", " + tf + ": per-frame memory", "frame", "MiB", false, {}};
      size_t index = 0;
      for (const auto& r : e["results"]) {
        if (r["dataset"] != d.name || r["transfer_function"] != tf) continue;
        const std::string colour = plot_colour(index), dash = plot_dash(index);
        ++index;
        if (r.contains("skipped")) continue;
        PlotSeries t{r["technique"], colour, {}, dash}, q{t.name, colour, {}, dash},
            s{t.name, colour, {}, dash}, m{t.name, colour, {}, dash};
        for (const auto& f : r["frames"]) {
          t.y.push_back(number_or(f, "seconds", NAN) * 1e3);
          m.y.push_back(number_or(f, "frame_bytes", NAN) / 1048576.0);
          if (f.contains("ssim")) {
            q.y.push_back(report_psnr(f["psnr_db"]));
            s.y.push_back(number_or(f, "ssim", NAN));
          }
        }
        time.series.push_back(t);
        memory.series.push_back(m);
        if (!q.y.empty()) {
          psnr.series.push_back(q);
          ssim.series.push_back(s);
        }
      }
      plots[plot_name(d.name, tf, "time")] = svg_line_plot(time);
      plots[plot_name(d.name, tf, "psnr")] = svg_line_plot(psnr);
      plots[plot_name(d.name, tf, "ssim")] = svg_line_plot(ssim);
      plots[plot_name(d.name, tf, "memory")] = svg_line_plot(memory);
    }
  return plots;
}

std::string evaluation_html(const Pipeline& p, const std::vector<CacheSummary>& summaries,
                            const nlohmann::json& e,
                            const std::map<std::string, std::string>& plots) {
  const nlohmann::json& m = e["machine"];
  std::string html =
      "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>" +
      xml_escape(p.name) + ": linebake evaluation</title>\n" + kStyle + kImageCheck +
      "</head>\n<body>\n";
  html += "<h1>" + xml_escape(p.name) + ": evaluation report</h1>\n";
  html += "<p>Pipeline <code>" + xml_escape(p.file) +
          "</code>: " + std::to_string(p.datasets.size()) + " data set(s), " +
          std::to_string(p.frame_count) + " frame(s) of the <code>" + xml_escape(p.flight) +
          "</code> flight at " + xml_escape(p.size) + ", every technique compared with <code>" +
          xml_escape(p.reference) + "</code>; " + xml_escape(warm_up_note(p)) + ".</p>\n";
  html += "<p>Machine: " + xml_escape(m.value("cpu", std::string("?"))) + ", " +
          std::to_string(m.value("cores", 0)) +
          " cores; Vulkan devices: " + xml_escape(m.value("vulkan", std::string("none"))) +
          ".</p>\n";
  html += "<p>All numbers: <code>report.json</code>. Contents: ";
  for (const PipelineDataset& d : p.datasets)
    html += "<a href=\"#" + xml_escape(d.name) + "\">" + xml_escape(d.name) + "</a> ";
  html += "</p>\n<h2>Table 1: data and representations</h2>\n";
  std::vector<std::string> header;
  const auto rows = report_table(summaries, header);
  html += table(header, rows);
  if (std::string note = report_table_note(summaries); !note.empty()) {
    note.erase(std::remove(note.begin(), note.end(), '`'), note.end());
    html += "<p>" + xml_escape(note) + "</p>\n";
  }
  html += paper_comparison(e);

  const int frame = grid_frame(p);
  for (const PipelineDataset& d : p.datasets) {
    html += "<h2 id=\"" + xml_escape(d.name) + "\">" + xml_escape(d.name) + "</h2>\n<p><code>" +
            xml_escape(d.source) + "</code></p>\n";
    for (const std::string& tf : p.transfer_functions) {
      html += "<h3>" + xml_escape(d.name) + ", transfer function <code>" + xml_escape(tf) +
              "</code></h3>\n";
      std::vector<const nlohmann::json*> results;
      for (const auto& r : e["results"])
        if (r["dataset"] == d.name && r["transfer_function"] == tf) results.push_back(&r);
      html += summary_table(p, results, m);
      html += "<div class=\"plots\">\n";
      for (const char* what : {"time", "psnr", "ssim", "memory"}) {
        const auto plot = plots.find(plot_name(d.name, tf, what));
        if (plot != plots.end()) html += plot->second;
      }
      html += "</div>\n";
      // Image grid of the middle frame.
      const std::string ref_stem = render_stem(p, d.name, p.reference, tf);
      const std::string ref_png = frame_output(p, ref_stem, frame, ".png");
      bool reference_ran = false;
      for (const nlohmann::json* r : results)
        reference_ran |= (*r)["technique"] == p.reference && !r->contains("skipped");
      if (!reference_ran) continue;
      const Image reference = read_png(ref_png);
      std::vector<Image> images;
      std::vector<const nlohmann::json*> shown;
      for (const nlohmann::json* r : results)
        if ((*r)["technique"] != p.reference && !r->contains("skipped")) {
          images.push_back(read_png(frame_output(
              p, render_stem(p, d.name, (*r)["technique"].get<std::string>(), tf), frame, ".png")));
          shown.push_back(r);
        }
      const ImageWindow w = closeup_window(reference, images);
      html += "<p>Frame " + std::to_string(frame) + ". Close-ups: the " + std::to_string(w.width) +
              "x" + std::to_string(w.height) + " window at (" + std::to_string(w.x) + ", " +
              std::to_string(w.y) + ") where the techniques differ most from the reference, 2x. " +
              error_image_caption() + " Images link to the full-size files.</p>\n";
      html +=
          "<table class=\"grid\"><tr><th>technique</th><th>frame</th><th>close-up</th>"
          "<th>error</th></tr>\n";
      const auto row = [&](const std::string& name, const std::string& caption,
                           const std::string& png, const Image& image, const std::string& error) {
        html += "<tr><td>" + xml_escape(name) + "<br>" + caption + "</td><td><a href=\"" +
                xml_escape(relative(p, png)) + "\"><img alt=\"" + xml_escape(name) + "\" src=\"" +
                png_uri(thumbnail(image)) + "\"></a></td><td><img class=\"closeup\" width=\"" +
                std::to_string(2 * w.width) + "\" alt=\"" + xml_escape(name) +
                " close-up\" src=\"" + png_uri(crop(image, w)) + "\"></td><td>";
        if (!error.empty())
          html += "<a href=\"" + xml_escape(relative(p, error)) + "\"><img alt=\"" +
                  xml_escape(name) + " error\" src=\"" + png_uri(thumbnail(read_png(error))) +
                  "\"></a>";
        html += "</td></tr>\n";
      };
      row(p.reference, "ground truth", ref_png, reference, "");
      for (size_t i = 0; i < shown.size(); ++i) {
        const nlohmann::json& r = *shown[i];
        const std::string name = r["technique"];
        const nlohmann::json& f = r["frames"].at(size_t(frame));
        const std::string stem = render_stem(p, d.name, name, tf);
        row(name,
            "PSNR " + fixed(report_psnr(f["psnr_db"]), 2) + " dB<br>SSIM " +
                fixed(number_or(f, "ssim", NAN), 4) + "<br>" +
                fixed(number_or(f, "seconds", NAN) * 1e3, 1) + " ms",
            frame_output(p, stem, frame, ".png"), images[i],
            frame_output(p, stem + "-error", frame, ".png"));
      }
      html += "</table>\n";
      const std::string dc = frame_output(p, ref_stem + "-dc", frame, ".png");
      if (std::filesystem::exists(dc)) {
        double max_count = 0;
        const Image counts = colour_counts(read_png(dc), max_count);
        html += "<p>Depth complexity of frame " + std::to_string(frame) +
                " (front-facing hits per pixel, black = none, yellow = " + fixed(max_count, 0) +
                "):</p>\n<p><a href=\"" + xml_escape(relative(p, dc)) +
                "\"><img alt=\"depth complexity\" src=\"" + png_uri(thumbnail(counts)) +
                "\"></a></p>\n";
      }
    }
  }
  html += "</body>\n</html>\n";
  return html;
}

}  // namespace linebake
