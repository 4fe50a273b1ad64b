#include "pipeline/evaluation_report.hpp"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>

#include "cache/cache.hpp"
#include "core/error.hpp"
#include "metrics/image_metrics.hpp"
#include "pipeline/report.hpp"
#include "pipeline/svg_plot.hpp"

namespace linebake {
namespace {

nlohmann::json read_json(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error("report: " + path + " is missing");
  try {
    return nlohmann::json::parse(in);
  } catch (const std::exception& e) {
    throw InputError(path, "", std::string("not JSON: ") + e.what());
  }
}

}  // namespace

const std::vector<std::string>& summary_columns() {
  static const std::vector<std::string> columns = {
      "technique", "time / frame", "speed-up vs reference", "PSNR (dB)",
      "SSIM",      "min SSIM",     "peak per-frame memory"};
  return columns;
}

std::vector<std::string> summary_cells(const nlohmann::json& r, double reference_seconds,
                                       bool is_reference) {
  double peak = 0;
  for (const auto& f : r["frames"])
    if (f.contains("frame_bytes") && f["frame_bytes"].is_number())
      peak = std::max(peak, f["frame_bytes"].get<double>());
  const double seconds = r["mean_seconds"].get<double>();
  std::string speedup;
  if (reference_seconds > 0 && seconds > 0) {
    const double ratio = reference_seconds / seconds;
    char text[32];
    std::snprintf(text, sizeof text, ratio < 0.1 ? "%.2gx" : "%.2fx", ratio);
    speedup = text;
  }
  std::vector<std::string> cells = {r["technique"].get<std::string>(), format_duration(seconds),
                                    speedup};
  if (r.contains("mean_ssim"))
    cells.insert(cells.end(),
                 {fixed(r["mean_psnr_db"].get<double>(), 2), fixed(r["mean_ssim"].get<double>(), 4),
                  fixed(r["min_ssim"].get<double>(), 4)});
  else
    cells.insert(cells.end(), {is_reference                 ? "reference"
                               : r.contains("not_compared") ? "not compared"
                                                            : "",
                               "", ""});
  cells.push_back(format_bytes(uint64_t(peak)));
  return cells;
}

std::string summary_note(const nlohmann::json& machine, const std::string& reference, bool html) {
  // The names are the only parts that need escaping; the rest is plain text either way.
  const auto name = [html](const std::string& s) { return html ? xml_escape(s) : s; };
  const auto code = [&](const std::string& s) {
    return html ? "<code>" + name(s) + "</code>" : "`" + s + "`";
  };
  std::string note = "Speed-up = the time per frame of " + code(reference) +
                     " divided by the technique's; below 1 = slower. ";
  // What the reference is: the pipeline's "reference" may name another technique (the
  // sentence had said the CPU ray tracer of any).
  if (reference == "reference")
    note +=
        "The reference ray traces the exact tube mesh with Embree on every CPU core, its BVH "
        "built before the first frame and not counted";
  else
    note += "The reference is " + code(reference) + " (the pipeline's reference)";
  const std::string vulkan = machine.value("vulkan", std::string("none"));
  for (const char* software : {"llvmpipe", "lavapipe", "SwiftShader"})
    if (vulkan.find(software) != std::string::npos) {
      note += "; the Vulkan techniques run on " + name(vulkan) +
              ", a software renderer on the same CPU";
      break;
    }
  return note +
         ". Per-frame memory is what a frame takes (the image, its outputs and the technique's "
         "per-pixel storage: --stats' frame_bytes), not the scene the technique holds (its BVH, "
         "mesh or voxel grid: Table 1, and --stats' mesh_bytes).";
}

std::string fixed(double value, int digits) {
  char text[32];
  std::snprintf(text, sizeof text, "%.*f", digits, value);
  return text;
}

std::string warm_up_note(const Pipeline& p) {
  return p.warm_up > 0
             ? "frame times count the flight's frames only, each technique having rendered " +
                   std::to_string(p.warm_up) + " untimed warm-up frame" +
                   (p.warm_up > 1 ? "s" : "") +
                   " first, which compiled its shaders and filled its caches"
             : "frame times count every frame, the first with its shaders' compilation "
               "(warm_up: 0)";
}

double report_psnr(const nlohmann::json& psnr_db) {
  // `compare` writes psnr() (lib/metrics), capped at kPsnrCap; a null, what an infinite PSNR of
  // an identical image becomes in JSON, is that cap too.
  return psnr_db.is_number() ? psnr_db.get<double>() : kPsnrCap;
}

std::vector<CacheSummary> pipeline_caches(const Pipeline& p) {
  std::vector<CacheSummary> summaries;
  // The assets this pipeline bakes: a cache keeps those an earlier version of it baked, which
  // its Table 1 had listed too.
  const std::vector<std::string> baked = pipeline_assets(p);
  for (const PipelineDataset& d : p.datasets) {
    CacheSummary summary = summarize_cache(CacheReader(cache_path(p, d.name), false));
    std::erase_if(summary.assets, [&](const Provenance& a) {
      return std::find(baked.begin(), baked.end(), a.step) == baked.end();
    });
    summaries.push_back(std::move(summary));
  }
  return summaries;
}

nlohmann::json evaluation_json(const Pipeline& p, const std::vector<CacheSummary>& summaries,
                               const std::vector<PipelineStep>& steps,
                               const nlohmann::json& machine) {
  std::map<std::string, const PipelineStep*> by_id;
  for (const PipelineStep& s : steps) by_id[s.id] = &s;
  nlohmann::json out = {{"pipeline", p.name},
                        {"file", p.file},
                        {"machine", machine},
                        {"size", p.size},
                        {"flight", p.flight},
                        {"frames", p.frame_count},
                        {"warm_up", p.warm_up},
                        {"reference", p.reference},
                        {"caches", nlohmann::json::array()},
                        {"results", nlohmann::json::array()}};
  out["caches"] = report_json(summaries);
  for (const PipelineDataset& d : p.datasets)
    for (const std::string& tf : p.transfer_functions)
      for (const PipelineTechnique& t : p.techniques) {
        const PipelineStep& render = *by_id.at("render/" + d.name + "/" + t.label + "/" + tf);
        nlohmann::json r = {{"dataset", d.name},
                            {"transfer_function", tf},
                            {"technique", t.label},
                            {"render", t.technique}};
        if (!render.skip_reason.empty()) {
          r["skipped"] = render.skip_reason;
          out["results"].push_back(r);
          continue;
        }
        const std::string stem = render_stem(p, d.name, t.label, tf);
        const nlohmann::json stats = read_json(stem + ".json");
        // The acceleration structure the technique built at render time (Embree's BVH for
        // embree and reference): Table 1's build figures when the cache holds none.
        if (stats.contains("bvh")) r["bvh"] = stats["bvh"];
        // Not compared where the reference did not run (its compare steps skipped).
        const PipelineStep* compare =
            t.label == p.reference
                ? nullptr
                : by_id.at("compare/" + d.name + "/" + t.label + "/" + tf + "/0");
        const bool compared = compare && compare->skip_reason.empty();
        if (compare && !compared) r["not_compared"] = compare->skip_reason;
        nlohmann::json frames = nlohmann::json::array();
        for (int f = 0; f < p.frame_count; ++f) {
          const nlohmann::json& fs = stats.at("frames").at(size_t(f));
          nlohmann::json frame = {{"frame", f}, {"seconds", fs.value("seconds", 0.0)}};
          if (fs.contains("gpu_ms")) frame["gpu_ms"] = fs["gpu_ms"];
          if (fs.contains("frame_bytes")) frame["frame_bytes"] = fs["frame_bytes"];
          if (compared) {
            const nlohmann::json c = read_json(frame_output(p, stem + "-compare", f, ".json"));
            frame["psnr_db"] = c.at("psnr_db");
            frame["ssim"] = c.at("ssim");
          }
          frames.push_back(frame);
        }
        double seconds = 0, psnr = 0, ssim = 0, min_ssim = std::numeric_limits<double>::infinity();
        for (const auto& f : frames) {
          seconds += f["seconds"].get<double>();
          if (f.contains("ssim")) {
            psnr += report_psnr(f["psnr_db"]);
            ssim += f["ssim"].get<double>();
            min_ssim = std::min(min_ssim, f["ssim"].get<double>());
          }
        }
        const double n = double(frames.size());
        r["frames"] = frames;
        r["mean_seconds"] = seconds / n;
        if (compared) {
          r["mean_psnr_db"] = psnr / n;
          r["mean_ssim"] = ssim / n;
          r["min_ssim"] = min_ssim;
        }
        out["results"].push_back(r);
      }
  return out;
}

std::string psnr_cap_note() {
  return "PSNR is capped at " + fixed(kPsnrCap, 0) +
         " dB, what an identical image gets, as linebake compare reports it";
}

namespace {

// evaluation_json()'s results by data set and transfer function, in their order.
std::vector<std::vector<const nlohmann::json*>> result_groups(const nlohmann::json& evaluation) {
  std::vector<std::vector<const nlohmann::json*>> groups;
  for (const auto& r : evaluation["results"]) {
    const bool same = !groups.empty() && (*groups.back().front())["dataset"] == r["dataset"] &&
                      (*groups.back().front())["transfer_function"] == r["transfer_function"];
    if (!same) groups.emplace_back();
    groups.back().push_back(&r);
  }
  return groups;
}

// One data set and transfer function: the plots, the table, and the reasons for skipped
// techniques as numbered notes under it (in the table they would stretch its column).
std::string markdown_group(const Pipeline& p, const std::vector<const nlohmann::json*>& results) {
  const nlohmann::json& first = *results.front();
  const std::string dataset = first["dataset"], tf = first["transfer_function"];
  const std::string plot = "plots/" + dataset + "-" + tf + "-";
  std::string md = "\n### " + dataset + ", `" + tf + "`\n\n![frame time](" + plot +
                   "time.svg) ![PSNR](" + plot + "psnr.svg) ![SSIM](" + plot +
                   "ssim.svg) ![per-frame memory](" + plot + "memory.svg)\n\n\n|";
  for (const std::string& column : summary_columns()) md += " " + column + " |";
  md += "\n|---|";
  for (size_t i = 1; i < summary_columns().size(); ++i) md += "---:|";
  md += "\n";
  double reference_seconds = 0;
  for (const nlohmann::json* r : results)
    if ((*r)["technique"] == p.reference && r->contains("mean_seconds"))
      reference_seconds = (*r)["mean_seconds"].get<double>();
  std::string notes;
  int note = 0;
  for (const nlohmann::json* r : results) {
    const std::string name = (*r)["technique"];
    if (r->contains("skipped")) {
      const std::string mark = "[" + std::to_string(++note) + "]";
      md += "| " + name + " | skipped " + mark + " | | | | | |\n";
      notes += mark + " " + name + ": " + (*r)["skipped"].get<std::string>() + "  \n";
      continue;
    }
    std::vector<std::string> cells = summary_cells(*r, reference_seconds, name == p.reference);
    if (r->contains("not_compared")) {
      const std::string mark = "[" + std::to_string(++note) + "]";
      cells[kPsnrColumn] += " " + mark;
      notes += mark + " " + name + ": " + (*r)["not_compared"].get<std::string>() + "  \n";
    }
    md += "|";
    for (const std::string& cell : cells) md += " " + cell + " |";
    md += "\n";
  }
  return notes.empty() ? md : md + "\n" + notes;
}

}  // namespace

std::string evaluation_markdown(const Pipeline& p, const std::vector<CacheSummary>& summaries,
                                const nlohmann::json& e) {
  std::string md = "# " + p.name + ": evaluation report\n\n";
  md += "Pipeline `" + p.file + "`: " + std::to_string(p.datasets.size()) + " data set(s), " +
        std::to_string(p.frame_count) + " frame(s) of the `" + p.flight + "` flight at " + p.size +
        ", compared with `" + p.reference + "`.\n\n";
  md += "Machine: " + e["machine"].value("cpu", std::string("?")) + ", " +
        std::to_string(e["machine"].value("cores", 0)) +
        " cores; Vulkan devices: " + e["machine"].value("vulkan", std::string("none")) + ".\n\n";
  md += "## Table 1: data and representations\n\n";
  md += report_markdown(summaries) + "\n";
  md += "## Frame time and quality\n\nMeans over the flight (" + warm_up_note(p) +
        "); PSNR and SSIM against `" + p.reference + "` (" + psnr_cap_note() +
        "). report.html has the image grids; report.json every frame's numbers.\n";
  for (const auto& group : result_groups(e)) md += markdown_group(p, group);
  md += "\n" + summary_note(e["machine"], p.reference, false) + "\n";
  return md;
}

}  // namespace linebake
