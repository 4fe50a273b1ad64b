// The report's building blocks: base64 (RFC 4648 vectors), PNG encoding in memory (round trip
// through the file reader), and SVG line plots (geometry checked against hand-computed values).

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>

#include "core/base64.hpp"
#include "pipeline/svg_plot.hpp"
#include "render/image.hpp"

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
  const auto path = std::filesystem::temp_directory_path() / "linebake-encode.png";
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

}  // namespace
}  // namespace linebake
