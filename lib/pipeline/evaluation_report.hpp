#pragma once
// The evaluation report of a pipeline run: Table 1 of every cache (pipeline/report.hpp) and, per
// data set and transfer function, each technique's frame times and its PSNR / SSIM against the
// reference along the flight, from the files the run's steps wrote. Markdown and JSON.

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "pipeline/pipeline.hpp"
#include "pipeline/report.hpp"

namespace linebake {

// `skipped`: step id -> reason for steps that did not run. Missing files of skipped steps are
// reported as skipped; of other steps, as an Error naming the file.
// Every data set's cache summary (Table 1), read once and passed to the report writers.
std::vector<CacheSummary> pipeline_caches(const Pipeline& pipeline);

nlohmann::json evaluation_json(const Pipeline& pipeline, const std::vector<CacheSummary>& caches,
                               const std::vector<PipelineStep>& steps,
                               const nlohmann::json& machine);
// A frame's PSNR as the report counts it: compare's value, which lib/metrics caps at kPsnrCap
// for an identical image.
double report_psnr(const nlohmann::json& psnr_db);
// The sentence both reports say it with.
std::string psnr_cap_note();
// The summary table's columns, and one row's cells for a result that was not skipped (plain
// text: the HTML report escapes them): mean time per frame, speed-up against the reference
// (whose mean time is `reference_seconds`; 0: none), mean PSNR, mean and least SSIM, and the
// largest frame_bytes. Both reports show the same figures to the same digits.
const std::vector<std::string>& summary_columns();
// The place of the PSNR cell among them (a technique not compared carries its note mark there).
constexpr size_t kPsnrColumn = 3;
std::vector<std::string> summary_cells(const nlohmann::json& result, double reference_seconds,
                                       bool is_reference);
// What the speed-up and per-frame memory columns mean: Markdown, or HTML (names escaped and in
// <code>).
std::string summary_note(const nlohmann::json& machine, const std::string& reference, bool html);
// What the frame times count: "each technique's frames timed after its N untimed warm-up
// frame(s)" (or that none was rendered first), for both reports.
std::string warm_up_note(const Pipeline& pipeline);
// `value` with `digits` digits after the point ("%.*f"), as both reports print figures.
std::string fixed(double value, int digits);

std::string evaluation_markdown(const Pipeline& pipeline, const std::vector<CacheSummary>& caches,
                                const nlohmann::json& evaluation);

}  // namespace linebake
