// Every writable format, written and read back, gives the same bits.

#include <gtest/gtest.h>

#include <algorithm>

#include "core/error.hpp"
#include "formats/registry.hpp"
#include "test_util.hpp"

using namespace linebake;
using linebake::test::awkward_lines;
using linebake::test::TempDir;

namespace {

struct Case {
  const char* name;
  const char* extension;
  bool keeps_line_attributes;
  WriteOptions options;
  friend void PrintTo(const Case& c, std::ostream* os) { *os << c.name; }
};

WriteOptions vtp(const char* encoding, bool compress, bool uint64_header) {
  WriteOptions o;
  o.vtp_encoding = encoding;
  o.vtp_compress = compress;
  o.vtp_header_uint64 = uint64_header;
  return o;
}
WriteOptions ascii() {
  WriteOptions o;
  o.ascii = true;
  return o;
}

std::vector<Case> cases() {
  return {
      {"obj", ".obj", false, {}},
      {"binlines", ".binlines", false, {}},
      {"vtk_binary", ".vtk", true, {}},
      {"vtk_ascii", ".vtk", true, ascii()},
      {"hdf5", ".h5", true, {}},
      {"csv", ".csv", false, {}},
      {"vtp_appended_zlib", ".vtp", true, vtp("appended", true, true)},
      {"vtp_appended_raw_u32", ".vtp", true, vtp("appended", false, false)},
      {"vtp_appended_base64_zlib_u32", ".vtp", true, vtp("appended-base64", true, false)},
      {"vtp_appended_base64", ".vtp", true, vtp("appended-base64", false, true)},
      {"vtp_inline_base64_zlib", ".vtp", true, vtp("base64", true, true)},
      {"vtp_inline_base64_u32", ".vtp", true, vtp("base64", false, false)},
      {"vtp_ascii", ".vtp", true, vtp("ascii", false, true)},
  };
}

class RoundTrip : public ::testing::TestWithParam<Case> {};

}  // namespace

TEST_P(RoundTrip, PreservesDataExactly) {
  const Case& c = GetParam();
  TempDir dir;
  const LineSet original = awkward_lines(c.keeps_line_attributes);
  const std::string path = dir.file(std::string("lines") + c.extension);
  write_line_set(original, path, c.options);
  const LineSet back = read_line_set(path);
  EXPECT_TRUE(back.same_data(original)) << c.name;
  ASSERT_EQ(back.attributes.size(), 2u);
  EXPECT_EQ(back.attributes[1].name, "second attr");
  EXPECT_EQ(dir.entries(), std::vector<std::string>{std::string("lines") + c.extension})
      << "temporary files left behind";
}

// An empty line set (no lines; attribute names kept where the format has them) is a valid
// file in every writable format, read back as zero lines and zero points.
TEST_P(RoundTrip, EmptyLineSetIsAValidFile) {
  const Case& c = GetParam();
  TempDir dir;
  LineSet empty;
  empty.attributes = {{"speed", {}}};
  if (c.keeps_line_attributes) empty.line_attributes = {{"line_id", {}}};
  const std::string path = dir.file(std::string("empty") + c.extension);
  write_line_set(empty, path, c.options);
  const LineSet back = read_line_set(path);
  EXPECT_EQ(back.line_count(), 0u);
  EXPECT_EQ(back.point_count(), 0u);
  EXPECT_EQ(back.line_offsets, std::vector<uint64_t>{0});
  for (const Attribute& a : back.attributes) EXPECT_TRUE(a.values.empty()) << a.name;
  for (const Attribute& a : back.line_attributes) EXPECT_TRUE(a.values.empty()) << a.name;
}

// Metadata survives every format that can hold it (formats/registry.cpp says which): names and
// values with spaces, quotes, XML specials, an empty value, and values long enough for each of
// VTK's binary string length prefixes (1, 2 and 4 bytes).
TEST_P(RoundTrip, KeepsMetadataWhereTheFormatHoldsIt) {
  const Case& c = GetParam();
  TempDir dir;
  LineSet original = awkward_lines(c.keeps_line_attributes);
  original.metadata = {{"units", "m s^-1"},
                       {"quote \"&<tag>", "a \"b\" <c> & 100%"},
                       {"empty", ""},
                       {"long", std::string(200, 'x')},
                       {"longer", std::string(20000, 'y')}};
  const std::string path = dir.file(std::string("lines") + c.extension);
  write_line_set(original, path, c.options);
  LineSet back = read_line_set(path);
  back.metadata.erase("source");  // added by read_line_set
  const FormatInfo& info = format_info(*format_from_extension(path));
  if (info.metadata)
    EXPECT_EQ(back.metadata, original.metadata) << c.name;
  else
    EXPECT_TRUE(back.metadata.empty()) << c.name;
  const std::vector<std::string> lost = lost_in_format(original, info.format, c.options);
  EXPECT_EQ(std::find(lost.begin(), lost.end(),
                      "metadata (empty, long, longer, quote \"&<tag>, units)") != lost.end(),
            !info.metadata)
      << c.name;
}

INSTANTIATE_TEST_SUITE_P(Formats, RoundTrip, ::testing::ValuesIn(cases()),
                         [](const auto& param_info) { return std::string(param_info.param.name); });

// A CSV header holds any name the reader reads back: one with a comma, a quote or blanks at its
// ends is quoted (RFC 4180), as the reader takes quoted names (the writer had refused them); one
// with a line break, which a quoted field may not hold there, is refused naming the file.
TEST(RoundTripCsv, NamesTheHeaderMustQuote) {
  TempDir dir;
  LineSet original = awkward_lines(false);
  ASSERT_GE(original.attributes.size(), 2u);
  original.attributes[0].name = "speed, \"m/s\"";
  original.attributes[1].name = " padded ";
  write_line_set(original, dir.file("quoted.csv"));
  const LineSet back = read_line_set(dir.file("quoted.csv"));
  ASSERT_EQ(back.attributes.size(), original.attributes.size());
  EXPECT_EQ(back.attributes[0].name, "speed, \"m/s\"");
  EXPECT_EQ(back.attributes[1].name, " padded ");
  EXPECT_EQ(back.attributes[0].values, original.attributes[0].values);
  original.attributes[0].name = "two\nlines";
  try {
    write_line_set(original, dir.file("broken.csv"));
    ADD_FAILURE() << "a name with a line break was written";
  } catch (const OutputError& e) {
    EXPECT_NE(std::string(e.what()).find("broken.csv"), std::string::npos) << e.what();
  }
}

TEST(RoundTripBinlines, Version1DropsNamesOnly) {
  TempDir dir;
  const LineSet original = awkward_lines(false);
  WriteOptions o;
  o.binlines_version = 1;
  write_line_set(original, dir.file("a.binlines"), o);
  LineSet back = read_line_set(dir.file("a.binlines"));
  EXPECT_EQ(back.attributes[0].name, "attribute0");
  back.attributes[0].name = original.attributes[0].name;
  back.attributes[1].name = original.attributes[1].name;
  EXPECT_TRUE(back.same_data(original));
}

TEST(RoundTripFormat, ExtensionOverride) {
  TempDir dir;
  const LineSet original = awkward_lines(true);
  WriteOptions w;
  w.format = Format::hdf5;
  write_line_set(original, dir.file("data.bin"), w);
  ReadOptions r;
  r.format = Format::hdf5;
  EXPECT_TRUE(read_line_set(dir.file("data.bin"), r).same_data(original));
  // No extension to go by: an HDF5 file is recognised by its superblock, anything else is
  // refused.
  EXPECT_TRUE(read_line_set(dir.file("data.bin")).same_data(original));
  WriteOptions binlines;
  binlines.format = Format::binlines;
  write_line_set(original, dir.file("data.bin2"), binlines);
  EXPECT_THROW(read_line_set(dir.file("data.bin2")), Error);
}

TEST(RoundTripFormat, NotWritableFormatsAreRefused) {
  TempDir dir;
  EXPECT_THROW(write_line_set(awkward_lines(false), dir.file("x.trk")), Error);
  EXPECT_TRUE(dir.entries().empty());
}
