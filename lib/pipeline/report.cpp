#include "pipeline/report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <set>
#include <sstream>

#include "core/error.hpp"
#include "core/json_file.hpp"
#include "core/memory_budget.hpp"

namespace linebake {

CacheSummary summarize_cache(const CacheReader& cache) {
  CacheSummary s;
  s.path = cache.path();
  s.name = std::filesystem::path(cache.path()).filename().string();
  for (const char* suffix : {".lbc.h5", ".h5"}) {
    const std::string x = suffix;
    if (s.name.size() > x.size() && s.name.compare(s.name.size() - x.size(), x.size(), x) == 0) {
      s.name.resize(s.name.size() - x.size());
      break;
    }
  }
  const auto lines = cache.provenance("/lines");
  if (!lines) throw InputError(cache.path(), "group /lines", "no line set provenance");
  s.lines = *lines;
  for (const std::string& name : cache.assets()) {
    if (auto p = cache.provenance("/assets/" + name)) s.assets.push_back(*p);
  }
  return s;
}

// Asset columns in a stable order: the paper's (tubes = RAS) first, then any others by name.
static std::vector<std::string> asset_columns(const std::vector<CacheSummary>& caches) {
  std::vector<std::string> present;
  for (const CacheSummary& c : caches)
    for (const Provenance& p : c.assets)
      if (std::find(present.begin(), present.end(), p.step) == present.end())
        present.push_back(p.step);
  // The paper's order: tubes (RAS) first, then the rest by name.
  std::sort(present.begin(), present.end(), [](const std::string& a, const std::string& b) {
    return std::make_pair(a != "tubes", a) < std::make_pair(b != "tubes", b);
  });
  return present;
}

static const Provenance* find_asset(const CacheSummary& c, const std::string& step) {
  for (const Provenance& p : c.assets)
    if (p.step == step) return &p;
  return nullptr;
}

std::string format_duration(double seconds) {
  if (!std::isfinite(seconds)) return "-";
  const double ms = seconds * 1e3;
  char text[32];
  if (ms < 1)
    std::snprintf(text, sizeof text, "%.2f ms", ms);
  else if (ms < 9.95)  // below this, %.1f keeps two significant digits
    std::snprintf(text, sizeof text, "%.1f ms", ms);
  else if (ms < 999.5)
    std::snprintf(text, sizeof text, "%.0f ms", ms);
  else if (seconds < 9.995)
    std::snprintf(text, sizeof text, "%.2f s", seconds);
  else if (seconds < 99.95)
    std::snprintf(text, sizeof text, "%.1f s", seconds);
  else
    std::snprintf(text, sizeof text, "%.0f s", seconds);
  return text;
}

static std::string count(uint64_t n) {
  std::string digits = std::to_string(n), out;
  for (size_t i = 0; i < digits.size(); ++i) {
    if (i && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return out;
}

std::vector<std::vector<std::string>> report_table(const std::vector<CacheSummary>& caches,
                                                   std::vector<std::string>& header) {
  const auto columns = asset_columns(caches);
  header = {"data set", "lines", "LS (segments)", "LM"};
  for (const std::string& a : columns) {
    const std::string label = a == "tubes"    ? "tubes (RAS)"
                              : a == "voxels" ? "voxels (VRC)"
                              : a == "embree" ? "embree (OSP)"
                                              : a;
    header.push_back(label + " size");
    header.push_back(a + " build");
    header.push_back(a + " build peak RSS");
    header.push_back(a + " on disk");
    if (a == "voxels") header.push_back("voxel grid, chords, error max/mean (voxels)");
    if (a == "embree") header.push_back("embree rebuild: commit, BVH");
  }
  std::vector<std::vector<std::string>> rows;
  for (const CacheSummary& c : caches) {
    std::vector<std::string> row{c.name, count(c.lines.stats.value("lines", uint64_t{0})),
                                 count(c.lines.stats.value("segments", uint64_t{0})),
                                 format_bytes(c.lines.memory_bytes)};
    for (const std::string& a : columns) {
      const Provenance* p = find_asset(c, a);
      if (!p) {
        row.insert(row.end(), a == "voxels" || a == "embree" ? 5 : 4, "-");
        continue;
      }
      row.push_back(format_bytes(p->memory_bytes));
      // * : built in a pass shared with other steps (report_table_note).
      const std::string shared = p->build.built_with.empty() ? "" : " *";
      row.push_back(format_duration(p->build.wall_s) + shared);
      row.push_back(format_bytes(p->build.peak_rss) + shared);
      row.push_back(format_bytes(p->disk_bytes) + " (" + p->compression + ")");
      if (a == "voxels") {
        const auto r = p->stats.value("resolution", std::array<uint32_t, 3>{});
        char text[128];
        std::snprintf(text, sizeof text, "%ux%ux%u Q%u, %s, %.3f / %.4f", r[0], r[1], r[2],
                      p->stats.value("quantization", 0u),
                      count(p->stats.value("chords", uint64_t{0})).c_str(),
                      p->stats.value("max_error_voxels", 0.0),
                      p->stats.value("mean_error_voxels", 0.0));
        row.push_back(text);
      }
      if (a == "embree")
        row.push_back(format_duration(p->stats.value("commit_s", 0.0)) + ", " +
                      format_bytes(p->stats.value("bvh_bytes", uint64_t{0})));
    }
    rows.push_back(std::move(row));
  }
  return rows;
}

namespace {
template <class Names>
std::string comma_list(const Names& names) {
  std::string list;
  for (const std::string& n : names) list += (list.empty() ? "" : ", ") + n;
  return list;
}
}  // namespace

std::string report_table_note(const std::vector<CacheSummary>& caches) {
  std::set<std::string> shared;
  for (const CacheSummary& c : caches)
    for (const Provenance& p : c.assets)
      if (!p.build.built_with.empty()) shared.insert(p.step);
  if (shared.empty()) return "";
  bool side_by_side = false;  // tubes and voxels, whose batches run in parallel
  for (const CacheSummary& c : caches)
    for (const Provenance& p : c.assets)
      if (p.step == "tubes" &&
          std::count(p.build.built_with.begin(), p.build.built_with.end(), std::string("voxels")))
        side_by_side = true;
  return "* " + comma_list(shared) +
         ": built from the same batches in one pass over the data (a bake reads its input once "
         "for every asset; linebake-mpi's figures are the job's), so the peak RSS is the pass's, "
         "the process included" +
         (side_by_side ? std::string(", and tubes and voxels, built side by side, overlap in "
                                     "wall and CPU time")
                       : std::string()) +
         ". `linebake bench tubes`, `bench voxels` and `bench embree` measure each alone.";
}

std::string report_markdown(const std::vector<CacheSummary>& caches) {
  std::vector<std::string> header;
  const auto rows = report_table(caches, header);
  std::ostringstream out;
  out << "|";
  for (const auto& h : header) out << " " << h << " |";
  out << "\n|";
  for (size_t i = 0; i < header.size(); ++i) out << (i ? " ---: |" : " --- |");
  out << "\n";
  for (const auto& row : rows) {
    out << "|";
    for (const auto& cell : row) out << " " << cell << " |";
    out << "\n";
  }
  // "\*": a line that starts with "* " is a list item in Markdown, and the mark it explains would
  // go.
  if (const std::string note = report_table_note(caches); !note.empty())
    out << "\n\\" << note << "\n";
  return out.str();
}

std::string report_text(const std::vector<CacheSummary>& caches) {
  std::ostringstream out;
  for (const CacheSummary& c : caches) {
    out << c.name << " (" << c.path << ")\n";
    out << "  lines           " << count(c.lines.stats.value("lines", uint64_t{0})) << "\n"
        << "  LS (segments)   " << count(c.lines.stats.value("segments", uint64_t{0})) << "\n"
        << "  LM (line model) " << format_bytes(c.lines.memory_bytes) << " in memory, "
        << format_bytes(c.lines.disk_bytes) << " on disk (" << c.lines.compression << ")\n";
    for (const Provenance& p : c.assets) {
      out << "  " << p.step << "\n"
          << "    size          " << format_bytes(p.memory_bytes) << " in memory, "
          << format_bytes(p.disk_bytes) << " on disk (" << p.compression
          << (p.estimated_disk_bytes ? ", estimated " + format_bytes(p.estimated_disk_bytes)
                                     : std::string())
          << ")\n"
          << "    build         " << format_duration(p.build.wall_s) << " wall, "
          << format_duration(p.build.cpu_s) << " CPU, " << p.threads << " threads\n"
          << "    peak RSS      " << format_bytes(p.build.peak_rss) << " (process held "
          << format_bytes(p.build.rss_before) << " before"
          << (p.build.peak_is_step_local ? "" : "; peak since process start")
          << (p.build.built_with.empty()
                  ? ""
                  : "; the peak of a pass shared with " + comma_list(p.build.built_with))
          << "; budget "
          << (p.memory_budget ? format_bytes(p.memory_budget) : std::string("unlimited")) << ")\n";
      if (p.spill_bytes)
        out << "    spilled       " << format_bytes(p.spill_bytes) << " to a temporary file\n";
      for (const auto& [key, value] : p.stats.items())
        out << "    " << key << std::string(key.size() < 14 ? 14 - key.size() : 1, ' ')
            << json_text(value) << "\n";
      out << "    built         " << p.created << " by linebake " << p.linebake_version << "\n";
    }
  }
  return out.str();
}

nlohmann::json report_json(const std::vector<CacheSummary>& caches) {
  nlohmann::json out = nlohmann::json::array();
  for (const CacheSummary& c : caches) {
    nlohmann::json assets = nlohmann::json::object();
    for (const Provenance& p : c.assets) assets[p.step] = to_json(p);
    out.push_back(
        {{"name", c.name}, {"path", c.path}, {"lines", to_json(c.lines)}, {"assets", assets}});
  }
  return out;
}

}  // namespace linebake
