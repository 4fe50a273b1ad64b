#include "pipeline/evaluation_report.hpp"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>

#include "cache/cache.hpp"
#include "core/error.hpp"
#include "pipeline/report.hpp"

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

std::string fixed(double value, int digits) {
  char text[32];
  std::snprintf(text, sizeof text, "%.*f", digits, value);
  return text;
}

}  // namespace

std::vector<CacheSummary> pipeline_caches(const Pipeline& p) {
  std::vector<CacheSummary> summaries;
  for (const PipelineDataset& d : p.datasets)
    summaries.push_back(summarize_cache(CacheReader(cache_path(p, d.name), false)));
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
        nlohmann::json frames = nlohmann::json::array();
        for (int f = 0; f < p.frame_count; ++f) {
          const nlohmann::json& fs = stats.at("frames").at(size_t(f));
          nlohmann::json frame = {{"frame", f}, {"seconds", fs.value("seconds", 0.0)}};
          if (fs.contains("gpu_ms")) frame["gpu_ms"] = fs["gpu_ms"];
          if (fs.contains("frame_bytes")) frame["frame_bytes"] = fs["frame_bytes"];
          if (t.label != p.reference) {
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
            // An identical image has infinite PSNR; JSON writes it as null.
            psnr += f["psnr_db"].is_number() ? f["psnr_db"].get<double>() : 100.0;
            ssim += f["ssim"].get<double>();
            min_ssim = std::min(min_ssim, f["ssim"].get<double>());
          }
        }
        const double n = double(frames.size());
        r["frames"] = frames;
        r["mean_seconds"] = seconds / n;
        if (t.label != p.reference) {
          r["mean_psnr_db"] = psnr / n;
          r["mean_ssim"] = ssim / n;
          r["min_ssim"] = min_ssim;
        }
        out["results"].push_back(r);
      }
  return out;
}

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
  md += "## Frame time and quality\n\nMeans over the flight; PSNR and SSIM against `" +
        p.reference +
        "` (an identical image counts as 100 dB). report.html has the image grids; report.json "
        "every frame's numbers.\n\n";
  std::string current;
  for (const auto& r : e["results"]) {
    const std::string group =
        r["dataset"].get<std::string>() + ", `" + r["transfer_function"].get<std::string>() + "`";
    if (group != current) {
      current = group;
      const std::string plot = "plots/" + r["dataset"].get<std::string>() + "-" +
                               r["transfer_function"].get<std::string>() + "-";
      md += "\n### " + group + "\n\n![frame time](" + plot + "time.svg) ![PSNR](" + plot +
            "psnr.svg) ![SSIM](" + plot + "ssim.svg) ![per-frame memory](" + plot +
            "memory.svg)\n" +
            "\n\n| technique | s / frame | PSNR (dB) | SSIM | min SSIM |\n"
            "|---|---:|---:|---:|---:|\n";
    }
    const std::string name = r["technique"].get<std::string>();
    if (r.contains("skipped")) {
      md += "| " + name + " | skipped: " + r["skipped"].get<std::string>() + " | | | |\n";
      continue;
    }
    md += "| " + name + " | " + fixed(r["mean_seconds"].get<double>(), 3) + " | ";
    if (r.contains("mean_ssim"))
      md += fixed(r["mean_psnr_db"].get<double>(), 1) + " | " +
            fixed(r["mean_ssim"].get<double>(), 4) + " | " + fixed(r["min_ssim"].get<double>(), 4) +
            " |\n";
    else
      md += "reference | | |\n";
  }
  return md;
}

}  // namespace linebake
