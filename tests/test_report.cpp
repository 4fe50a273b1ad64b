// The report's building blocks: base64 (RFC 4648 vectors), PNG encoding in memory (round trip
// through the file reader), SVG line plots (geometry checked against hand-computed values); and
// what report.md and report.html say: durations, PSNR of identical images, skipped techniques,
// the error images' gain, Embree's BVH built at render time.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>

#include "cli_contract.hpp"
#include "core/base64.hpp"
#include "metrics/image_metrics.hpp"
#include "pipeline/evaluation_report.hpp"
#include "pipeline/html_report.hpp"
#include "pipeline/pipeline.hpp"
#include "pipeline/report.hpp"
#include "pipeline/svg_plot.hpp"
#include "render/image.hpp"
#include "test_util.hpp"

namespace linebake {
namespace {

TEST(Base64, Rfc4648TestVectors) {
  EXPECT_EQ(base64_encode(""), "");
  EXPECT_EQ(base64_encode("f"), "Zg==");
  EXPECT_EQ(base64_encode("fo"), "Zm8=");
  EXPECT_EQ(base64_encode("foo"), "Zm9v");
  EXPECT_EQ(base64_encode("foob"), "Zm9vYg==");
  EXPECT_EQ(base64_encode("fooba"), "Zm9vYmE=");
  EXPECT_EQ(base64_encode("foobar"), "Zm9vYmFy");
  EXPECT_EQ(base64_encode(std::string("\xff\xfe\x00", 3)), "//4A");
}

TEST(EncodePng, MatchesTheFileWriterAndReadsBack) {
  Image image(5, 3, 3);
  image.srgb_encoded = true;
  for (size_t i = 0; i < image.pixels.size(); ++i) image.pixels[i] = float(i % 7) / 6.0f;
  const test::TempDir dir;
  const std::filesystem::path path = dir.file("encode.png");
  write_png(image, path.string());
  std::ifstream in(path, std::ios::binary);
  const std::string file((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(encode_png(image), file);
  const Image back = read_png(path.string());
  ASSERT_EQ(back.width, 5);
  for (size_t i = 0; i < image.pixels.size(); ++i)
    EXPECT_NEAR(back.pixels[i], image.pixels[i], 0.5 / 255 + 1e-6) << i;  // 8-bit rounding
  std::filesystem::remove(path);
}

std::vector<std::string> polylines(const std::string& svg) {
  std::vector<std::string> out;
  const std::regex points("<polyline[^>]*points=\"([^\"]*)\"");
  for (auto it = std::sregex_iterator(svg.begin(), svg.end(), points); it != std::sregex_iterator();
       ++it)
    out.push_back((*it)[1]);
  return out;
}

TEST(SvgPlot, PlacesPointsOnTheAxes) {
  // 3 frames, y 0..10: the axis runs 0..10 (step 2), so y = 5 sits halfway down the plot area.
  LinePlot plot{"t", "frame", "ms", false, {{"a & b", "#000", {0, 5, 10}}}};
  const std::string svg = svg_line_plot(plot, 520, 300);
  // Plot area: x 62..370 (520 - 62 - 150 wide), y 28..258 (300 - 28 - 42 high).
  const auto lines = polylines(svg);
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_EQ(lines[0], "62.0,258.0 216.0,143.0 370.0,28.0 ");
  EXPECT_NE(svg.find("a &amp; b"), std::string::npos);  // legend escaped
  EXPECT_EQ(svg.find("a & b"), std::string::npos);
}

TEST(SvgPlot, GapsAtMissingValuesAndLogAxes) {
  LinePlot plot{"t", "frame", "ms", true, {{"a", "#000", {1, 10, NAN, 100, 1000}}}};
  const std::string svg = svg_line_plot(plot, 520, 300);
  const auto lines = polylines(svg);
  ASSERT_EQ(lines.size(), 2u);  // broken at the NaN
  // Decades 1..1000: 10 is a third of the way up, 100 two thirds.
  EXPECT_EQ(lines[0], "62.0,258.0 139.0,181.3 ");
  EXPECT_EQ(lines[1], "293.0,104.7 370.0,28.0 ");
  // A series of one usable point is a dot, not an invisible one-point line.
  LinePlot single{"t", "frame", "dB", false, {{"a", "#000", {NAN, 3}}}};
  EXPECT_NE(svg_line_plot(single).find("<circle"), std::string::npos);
  LinePlot empty{"t", "frame", "dB", false, {}};
  EXPECT_NE(svg_line_plot(empty).find("no data"), std::string::npos);
}

// Eleven techniques in a plot (the quickstart's): the eleventh took the first's colour and, where
// its line coincided with another's (tiles and embree), could not be told apart.
TEST(SvgPlot, SeriesPastTheTenthColourAreDashed) {
  LinePlot plot{"t", "frame", "ms", false, {}};
  for (size_t i = 0; i < 12; ++i)
    plot.series.push_back({"s" + std::to_string(i), plot_colour(i), {1, 2}, plot_dash(i)});
  const std::string svg = svg_line_plot(plot, 520, 300);
  EXPECT_EQ(plot_colour(10), plot_colour(0));
  EXPECT_NE(plot_dash(10), plot_dash(0));
  // Two polylines and two legend lines dashed: series 10 and 11.
  size_t dashed = 0;
  for (size_t at = svg.find("stroke-dasharray=\"7,4\""); at != std::string::npos;
       at = svg.find("stroke-dasharray=\"7,4\"", at + 1))
    ++dashed;
  EXPECT_EQ(dashed, 4u);
  EXPECT_EQ(svg.find("stroke-dasharray=\"\""), std::string::npos);
}

// The close-up is the window where the images differ most, at any position: differences that
// fill exactly the 80x45 window at (121, 72) of a 320x180 frame (off the w / 64 grid the search
// had taken, which found (125, 75)).
TEST(CloseupWindow, FindsTheWindowWhereTheImagesDifferMostAtAnyPosition) {
  Image reference(320, 180, 3), image(320, 180, 3);
  for (int y = 72; y < 72 + 45; ++y)
    for (int x = 121; x < 121 + 80; ++x)
      for (int c = 0; c < 3; ++c) image.at(x, y, c) = 1.0f;
  const ImageWindow w = closeup_window(reference, {image});
  EXPECT_EQ(w.width, 80);
  EXPECT_EQ(w.height, 45);
  EXPECT_EQ(w.x, 121);
  EXPECT_EQ(w.y, 72);
  // Nothing differs: the centre.
  const ImageWindow centre = closeup_window(reference, {reference});
  EXPECT_EQ(centre.x, 120);
  EXPECT_EQ(centre.y, 67);  // (180 - 45) / 2, rounded down
}

// Every command's median: the middle two's mean of an even count (render and bench took the
// upper one).
TEST(Median, IsTheMiddleValueOrTheMeanOfTheMiddleTwo) {
  EXPECT_EQ(cli::median({}), 0.0);
  EXPECT_EQ(cli::median({3, 1, 2}), 2.0);
  EXPECT_EQ(cli::median({0.4, 0.1, 0.3, 0.2}), 0.25);
  EXPECT_EQ(cli::median({5}), 5.0);
}

TEST(FormatDuration, KeepsTwoOrThreeSignificantDigits) {
  EXPECT_EQ(format_duration(0.0045), "4.5 ms");  // printed "0.00 s" before
  EXPECT_EQ(format_duration(0.00045), "0.45 ms");
  EXPECT_EQ(format_duration(0.0), "0.00 ms");
  EXPECT_EQ(format_duration(0.017), "17 ms");
  EXPECT_EQ(format_duration(0.2304), "230 ms");
  EXPECT_EQ(format_duration(0.9996), "1.00 s");  // not "1000 ms"
  EXPECT_EQ(format_duration(1.254), "1.25 s");
  EXPECT_EQ(format_duration(12.34), "12.3 s");
  EXPECT_EQ(format_duration(154.2), "154 s");
  EXPECT_EQ(format_duration(NAN), "-");
}

std::string fixed(double value, int digits) {
  char text[32];
  std::snprintf(text, sizeof text, "%.*f", digits, value);
  return text;
}

size_t count_of(const std::string& text, const std::string& part) {
  size_t n = 0;
  for (size_t at = text.find(part); at != std::string::npos; at = text.find(part, at + 1)) ++n;
  return n;
}

// A one-frame run of three techniques on the paper's "aneurysm": the reference, ll (an image
// identical to the reference, 4.5 ms a frame), embree (slow, its BVH built at render time) and
// rtx (skipped), with the frames the image grid reads written under a temporary output (one per
// test and process: ctest runs these tests side by side, and a shared directory raced).
struct SmallRun {
  test::TempDir dir;
  Pipeline pipeline;
  nlohmann::json evaluation;
  Image frame{16, 12, 3};

  SmallRun() {
    pipeline.name = "t";
    pipeline.file = "t.json";
    pipeline.output = dir.file("report");
    pipeline.datasets = {{"aneurysm", "synth:aneurysm?scale=0.01"}};
    pipeline.frame_count = 1;
    pipeline.techniques = {{"reference", {}, "reference", {}, {}},
                           {"ll", {}, "ll", {}, {}},
                           {"embree", {}, "embree", {}, {}},
                           {"rtx", {}, "rtx", {}, {}}};
    frame.srgb_encoded = true;
    for (size_t i = 0; i < frame.pixels.size(); ++i) frame.pixels[i] = float(i % 5) / 4.0f;
    std::filesystem::create_directories(pipeline.output + "/aneurysm");
    for (const char* label : {"reference", "ll", "embree"}) {
      const std::string stem = render_stem(pipeline, "aneurysm", label, "semi");
      write_png(frame, frame_output(pipeline, stem, 0, ".png"));
      if (std::string(label) != "reference")
        write_png(error_image(frame, frame, kErrorImageGain),
                  frame_output(pipeline, stem + "-error", 0, ".png"));
    }
    // What compare writes for an identical image: psnr(), capped by lib/metrics.
    const double identical = psnr(frame, frame);
    const auto result = [&](const char* label, double seconds, bool compared) {
      nlohmann::json frame_stats = {{"frame", 0}, {"seconds", seconds}, {"frame_bytes", 1024}};
      if (compared) frame_stats.update({{"psnr_db", identical}, {"ssim", 1.0}});
      nlohmann::json r = {{"dataset", "aneurysm"},   {"transfer_function", "semi"},
                          {"technique", label},      {"render", label},
                          {"frames", {frame_stats}}, {"mean_seconds", seconds}};
      if (compared) r.update({{"mean_psnr_db", identical}, {"mean_ssim", 1.0}, {"min_ssim", 1.0}});
      return r;
    };
    nlohmann::json embree = result("embree", 4.0, true);
    embree["bvh"] = {{"buffer_bytes", 1000000},
                     {"bvh_bytes", 2000000},
                     {"prepare_s", 0.001},
                     {"commit_s", 0.0035}};
    evaluation = {
        {"machine", {{"cpu", "test CPU"}, {"cores", 2}, {"vulkan", "llvmpipe (LLVM 15)"}}},
        {"caches",
         {{{"name", "aneurysm"},
           {"lines", {{"memory_bytes", 1000000}, {"stats", {{"segments", 115000}}}}},
           {"assets",
            {{"tubes", {{"memory_bytes", 16000000}, {"build", {{"wall_s", 0.0045}}}}},
             {"voxels", {{"memory_bytes", 29148}, {"build", {{"wall_s", 0.002}}}}}}}}}},
        {"results",
         {result("reference", 0.01, false),
          result("ll", 0.0045, true),
          embree,
          {{"dataset", "aneurysm"},
           {"transfer_function", "semi"},
           {"technique", "rtx"},
           {"render", "rtx"},
           {"skipped", "no Vulkan device with ray tracing"}}}}};
  }
};

TEST(EvaluationReport, MarkdownStatesThePsnrCapAndKeepsSkipReasonsOutOfTheTable) {
  const SmallRun run;
  const std::string md = evaluation_markdown(run.pipeline, {}, run.evaluation);
  const std::string cap = fixed(psnr(run.frame, run.frame), 0) + " dB";
  EXPECT_NE(md.find("capped at " + cap), std::string::npos) << md;
  EXPECT_EQ(md.find("100 dB"), std::string::npos) << md;
  // The columns and digits the HTML report has (the Markdown had no speed-up or memory).
  EXPECT_NE(md.find("| ll | 4.5 ms | 2.22x | " + fixed(psnr(run.frame, run.frame), 2) + " |"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("| technique | time / frame | speed-up vs reference | PSNR (dB) | SSIM | min "
                    "SSIM | peak per-frame memory |"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("| rtx | skipped [1] | | | | | |"), std::string::npos) << md;
  EXPECT_NE(md.find("not the scene the technique holds"), std::string::npos) << md;
  EXPECT_NE(md.find("[1] rtx: no Vulkan device with ray tracing"), std::string::npos) << md;
  // An identical image's PSNR, written as null by older runs, counts as what psnr() returns.
  EXPECT_EQ(report_psnr(nlohmann::json()), psnr(run.frame, run.frame));
  EXPECT_EQ(report_psnr(nlohmann::json(42.5)), 42.5);
}

TEST(EvaluationReport, HtmlStatesTheGainNotesSkipsAndReportsTheRenderTimeBvh) {
  const SmallRun run;
  const std::string html = evaluation_html(run.pipeline, {}, run.evaluation, {});
  // The error images' gain, as the compare steps apply it.
  EXPECT_NE(html.find("gain of " + fixed(kErrorImageGain, 0)), std::string::npos);
  EXPECT_NE(html.find(error_image_caption()), std::string::npos);
  // The skip reason: a tooltip and a numbered note, not the cell's text.
  EXPECT_NE(html.find("title=\"no Vulkan device with ray tracing\">skipped<sup>1</sup>"),
            std::string::npos);
  EXPECT_NE(html.find("<li value=\"1\">rtx: no Vulkan device with ray tracing</li>"),
            std::string::npos);
  EXPECT_EQ(count_of(html, "no Vulkan device with ray tracing"), 2u);
  // Speed-ups: the reference's time / the technique's, with the reason they are below 1 here.
  EXPECT_NE(html.find(">2.22x<"), std::string::npos);                             // 10 ms / 4.5 ms
  EXPECT_NE(html.find(">4.5 ms</td><td class=\"n\">2.22x<"), std::string::npos);  // as in the .md
  // Beside the paper, GB to three decimals, and a small voxel grid to two significant digits
  // without an exponent (it read "0.000", then "2.9e-05").
  EXPECT_NE(html.find(">0.016<"), std::string::npos);
  EXPECT_NE(html.find(">0.000029<"), std::string::npos);
  EXPECT_NE(html.find(">3.6 s<"), std::string::npos);  // the paper's aneurysm VRC build
  EXPECT_NE(html.find("time per frame of <code>reference</code> divided"), std::string::npos);
  EXPECT_NE(html.find(">0.0025x<"), std::string::npos);  // 10 ms / 4 s, not "0.00x"
  EXPECT_NE(html.find("below 1 = slower"), std::string::npos);
  EXPECT_NE(html.find("a software renderer on the same CPU"), std::string::npos);
  // Beside the paper: the tubes' 4.5 ms build, and the BVH embree built at render time
  // (buffers 1 MB + BVH 2 MB; prepare 1 ms + commit 3.5 ms), marked as such.
  EXPECT_NE(html.find(">4.5 ms<"), std::string::npos);
  EXPECT_NE(html.find(">0.003 *<"), std::string::npos);
  EXPECT_NE(html.find(">4.5 ms *<"), std::string::npos);
  EXPECT_NE(html.find("the BVH the embree technique built when it rendered"), std::string::npos);
  // The identical image's PSNR in the grid is what lib/metrics returns.
  EXPECT_NE(html.find("PSNR " + fixed(psnr(run.frame, run.frame), 2) + " dB"), std::string::npos);
  EXPECT_EQ(html.find("100.00 dB"), std::string::npos);
}

// Beside the paper, the build times of a pass shared with other steps are marked as Table 1
// marks them (they had no mark there).
TEST(EvaluationReport, SharedPassBuildTimesAreMarkedBesideThePaper) {
  SmallRun run;
  const std::string plain = evaluation_html(run.pipeline, {}, run.evaluation, {});
  EXPECT_EQ(plain.find("\u2020"), std::string::npos);
  nlohmann::json& assets = run.evaluation["caches"][0]["assets"];
  assets["tubes"]["build"]["built_with"] = {"voxels"};
  assets["voxels"]["build"]["built_with"] = {"tubes"};
  const std::string html = evaluation_html(run.pipeline, {}, run.evaluation, {});
  EXPECT_NE(html.find(">4.5 ms \u2020<"), std::string::npos);
  EXPECT_EQ(count_of(html, " \u2020<"), 2u);  // tubes and voxels, not the paper's row
  EXPECT_NE(html.find("\u2020 = built in one pass over the data with other assets"),
            std::string::npos);
}

TEST(EvaluationReport, NoRenderTimeBvhMarkWithoutAnEmbreeRender) {
  SmallRun run;
  run.evaluation["results"][2].erase("bvh");
  const std::string html = evaluation_html(run.pipeline, {}, run.evaluation, {});
  EXPECT_EQ(html.find(" *<"), std::string::npos);
  EXPECT_EQ(html.find("the BVH the embree technique built"), std::string::npos);
}

TEST(EvaluationReport, TheSpeedUpNoteSaysWhatTheReferenceIs) {
  // A pipeline whose reference is ll had been told that its reference ray traces the tube mesh
  // with Embree on the CPU.
  const nlohmann::json machine = {{"vulkan", "llvmpipe (LLVM 15.0.6, 256 bits)"}};
  const std::string cpu = summary_note(machine, "reference", false);
  EXPECT_NE(cpu.find("The reference ray traces the exact tube mesh with Embree"),
            std::string::npos);
  EXPECT_NE(cpu.find("; the Vulkan techniques run on llvmpipe"), std::string::npos);
  const std::string ll = summary_note(machine, "ll", false);
  EXPECT_EQ(ll.find("Embree"), std::string::npos) << ll;
  EXPECT_NE(ll.find("time per frame of `ll` divided"), std::string::npos);
  EXPECT_NE(ll.find("The reference is `ll` (the pipeline's reference)"), std::string::npos);
  const std::string html = summary_note({{"vulkan", "NVIDIA H100"}}, "rtx", true);
  EXPECT_NE(html.find("The reference is <code>rtx</code>"), std::string::npos);
  EXPECT_EQ(html.find("software renderer"), std::string::npos);
}

}  // namespace
}  // namespace linebake
