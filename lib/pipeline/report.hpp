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

// A build or frame time with two or three significant digits in a unit that keeps them:
// "0.45 ms", "4.5 ms", "230 ms", "1.25 s", "12.3 s", "154 s". Fixed decimals of seconds print the
// milliseconds small data sets take as "0.00 s".
std::string format_duration(double seconds);

// Table 1's cells, one row per cache, with the column names in `header`.
std::vector<std::vector<std::string>> report_table(const std::vector<CacheSummary>& caches,
                                                   std::vector<std::string>& header);

// The footnote to Table 1's cells marked "*" (figures of steps built in one pass), or "".
std::string report_table_note(const std::vector<CacheSummary>& caches);

nlohmann::json report_json(const std::vector<CacheSummary>& caches);
std::string report_markdown(const std::vector<CacheSummary>& caches);
std::string report_text(const std::vector<CacheSummary>& caches);

}  // namespace linebake
