#pragma once
// The build report: the paper's Table 1 for one or more caches (segments, line model size,
// each representation's size and build time), plus build memory peaks and on-disk sizes.

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cache/cache.hpp"
#include "core/memory_budget.hpp"  // format_bytes

namespace linebake {

struct CacheSummary {
  std::string path;
  std::string name;  // the data set: cache file name without .lbc.h5
  Provenance lines;
  std::vector<Provenance> assets;
};

CacheSummary summarize_cache(const CacheReader& cache);

// Table 1's cells, one row per cache, with the column names in `header`.
std::vector<std::vector<std::string>> report_table(const std::vector<CacheSummary>& caches,
                                                   std::vector<std::string>& header);

nlohmann::json report_json(const std::vector<CacheSummary>& caches);
std::string report_markdown(const std::vector<CacheSummary>& caches);
std::string report_text(const std::vector<CacheSummary>& caches);

}  // namespace linebake
