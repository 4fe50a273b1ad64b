#pragma once
// The evaluation report as one self-contained HTML page: Table 1 beside the paper's, per data set
// and transfer function the summary table, SVG plots of frame time, PSNR, SSIM and per-frame
// memory along the flight, and an image grid of one frame (ground truth, each technique, its
// error image and a close-up where the techniques differ most, plus the depth complexity).
// Every image is a PNG data: URI and every plot inline SVG, so the page needs no other file.

#include <map>
#include <nlohmann/json.hpp>
#include <string>

#include "pipeline/pipeline.hpp"
#include "pipeline/report.hpp"
#include "render/image.hpp"

namespace linebake {

// The plots of one run, by file name ("aneurysm-semi-time.svg"): the Markdown report links them
// from <output>/plots/, the HTML page inlines them.
std::map<std::string, std::string> evaluation_plots(const Pipeline& pipeline,
                                                    const nlohmann::json& evaluation);

// `evaluation` is evaluation_json()'s; images are read from the run's output files.
std::string evaluation_html(const Pipeline& pipeline, const std::vector<CacheSummary>& caches,
                            const nlohmann::json& evaluation,
                            const std::map<std::string, std::string>& plots);

// The image grids' caption of the error images, with the gain the compare steps apply.
std::string error_image_caption();

// The frame shown in the image grids: the middle of the flight.
int grid_frame(const Pipeline& pipeline);

// The close-up of the image grids: the window a quarter of each side where `images` differ most
// from `reference` (summed absolute luminance difference, over every position through a
// summed-area table; the first such, row by row); the centre when nothing differs.
struct ImageWindow {
  int x = 0, y = 0, width = 0, height = 0;
};
ImageWindow closeup_window(const Image& reference, const std::vector<Image>& images);

}  // namespace linebake
