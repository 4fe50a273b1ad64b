// linebake compare <image> <reference>: PSNR and SSIM as the paper reports them.

#include <tbb/task_arena.h>

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <utility>

#include "cli_contract.hpp"
#include "commands.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/json_file.hpp"
#include "core/memory_budget.hpp"
#include "metrics/image_metrics.hpp"
#include "whole_output.hpp"

namespace linebake::cli {

Command add_compare(CLI::App& app) {
  auto* sub = app.add_subcommand(
      "compare", "PSNR and SSIM of an image against a reference (display-encoded values)");
  struct Args {
    std::string image, reference, error_image, memory_budget;
    double error_scale = 1;
    bool json = false;
  };
  auto args = std::make_shared<Args>();
  sub->add_option("image", args->image, "Image (.png or .pfm)")->required();
  sub->add_option("reference", args->reference, "Reference image (.png or .pfm)")->required();
  sub->add_option(
      "--error-image", args->error_image,
      "Per-pixel absolute error, inverted grey (white = equal): .png (8-bit) or .pfm (float)");
  sub->add_option("--error-scale", args->error_scale, "Error image gain (default 1)")
      ->check(positive());
  sub->add_option("--memory-budget", args->memory_budget,
                  "Resident memory at most for the two images and SSIM's rows, e.g. 8G "
                  "(default: half of physical memory, or of the cgroup's or ulimit -v's limit "
                  "when less); unlimited")
      ->check(memory_budget_size());
  sub->add_flag("--json", args->json, "Print JSON");
  return [args] {
    // Linear PFMs are display-encoded first, so a PFM and a PNG of one frame compare equal.
    check_input_file(args->image);
    check_input_file(args->reference);
    check_output_location(args->error_image);
    refuse_input_as_output(args->error_image, {args->image, args->reference});
    const std::string error_format = std::filesystem::path(args->error_image).extension().string();
    if (!args->error_image.empty() && error_format != ".png" && error_format != ".pfm")
      throw OutputError(args->error_image,
                        "an error image is .png (8-bit grey) or .pfm (float grey)");
    // Each image is read within what the budget leaves (its floats and its decoding), checked
    // as read (the display encoding clamps an infinity to 0 or 1; a NaN stays) and encoded in
    // place, so that the command holds two images and SSIM's rows, no more.
    MemoryBudget budget(memory_budget_bytes(args->memory_budget));
    const auto read = [&budget](const std::string& path) {
      Image image = read_image(path, budget);
      if (image.alpha_dropped)
        warn(path +
             ": its alpha channel (or tRNS transparency) is dropped: compared by its "
             "colour channels as stored, not composited over a background");
      if (const std::string place = first_nonfinite_pixel(image); !place.empty())
        throw InputError(path, place,
                         "not a finite value (NaN or infinity): PSNR and SSIM need finite values");
      return display_encoded(std::move(image));
    };
    const Image a = read(args->image), b = read(args->reference);
    if (const std::string problem = comparison_problem(a, b, args->reference); !problem.empty())
      throw InputError(args->image, "", problem);
    budget.reserve(ssim_scratch_bytes(a.width, a.height, tbb::this_task_arena::max_concurrency()),
                   "SSIM's rows");
    if (!args->error_image.empty())  // its floats, and a PFM's bytes or a PNG's samples and file
      budget.reserve(2 * image_bytes(a.width, a.height, 1), "the error image " + args->error_image);
    const double p = psnr(a, b), s = ssim(a, b);
    if (error_format == ".pfm")
      write_pfm(error_image(a, b, args->error_scale), args->error_image);
    else if (!args->error_image.empty())
      write_png(error_image(a, b, args->error_scale), args->error_image, 8);
    if (args->json) {
      std::cout << json_text(nlohmann::json{{"image", args->image},
                                            {"reference", args->reference},
                                            {"psnr_db", p},
                                            {"ssim", s},
                                            {"ssim_mode", "per-channel mean"}},
                             2)
                << "\n";
    } else {
      std::printf("PSNR  %.4f dB%s\nSSIM  %.6f (per-channel mean)\n", p,
                  p >= kPsnrCap ? " (capped)" : "", s);
    }
  };
}

}  // namespace linebake::cli
