// Bad input: a clear error naming the file and the place, never a crash.

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <limits>

#include "core/base64.hpp"
#include "core/error.hpp"
#include "core/json_file.hpp"
#include "formats/registry.hpp"
#include "pipeline/pipeline.hpp"
#include "render/camera.hpp"
#include "render/transfer_function.hpp"
#include "test_util.hpp"

using namespace linebake;
using linebake::test::TempDir;
using linebake::test::write_bytes;
using linebake::test::write_text;

namespace {

// Reads `path` expecting an InputError whose message names the file and contains `place`.
void expect_error(const std::string& path, const std::string& place) {
  try {
    read_line_set(path);
    ADD_FAILURE() << path << ": expected an error mentioning '" << place << "'";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(path), std::string::npos) << what;
    EXPECT_NE(what.find(place), std::string::npos) << "expected '" << place << "' in: " << what;
  }
}

std::vector<unsigned char> file_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), {}};
}

// Writes a valid file in `extension`, then truncated copies at several lengths: each must fail
// cleanly (or, where a prefix happens to be valid, read without crashing).
void truncations_fail(const std::string& extension, const WriteOptions& options = {}) {
  TempDir dir;
  const std::string good = dir.file("good" + extension);
  write_line_set(linebake::test::awkward_lines(false), good, options);
  const auto bytes = file_bytes(good);
  int failures = 0;
  for (size_t keep : {size_t{0}, size_t{3}, bytes.size() / 3, bytes.size() / 2, bytes.size() - 3}) {
    const std::string cut = dir.file("cut" + std::to_string(keep) + extension);
    write_bytes(cut,
                std::vector<unsigned char>(bytes.begin(), bytes.begin() + static_cast<long>(keep)));
    try {
      read_line_set(cut);
    } catch (const InputError& e) {
      ++failures;
      EXPECT_NE(std::string(e.what()).find(cut), std::string::npos) << e.what();
    }
  }
  EXPECT_GE(failures, 4) << extension;
}

}  // namespace

TEST(Malformed, MissingFile) {
  expect_error("/nonexistent/lines.obj", "cannot open");
}

TEST(Malformed, Truncated) {
  truncations_fail(".binlines");
  truncations_fail(".vtk");
  truncations_fail(".h5");
  truncations_fail(".vtp");
  WriteOptions base64;
  base64.vtp_encoding = "base64";
  truncations_fail(".vtp", base64);
}

TEST(Malformed, Obj) {
  TempDir dir;
  write_text(dir.file("a.obj"), "v 0 0 0\nv 1 1 1\nl 1 3\n");
  expect_error(dir.file("a.obj"), "line 3: vertex index 3 out of range");
  write_text(dir.file("b.obj"), "v 0 0\n");
  expect_error(dir.file("b.obj"), "line 1: vertex needs 3 coordinates");
  write_text(dir.file("c.obj"), "v 0 0 zero\n");
  expect_error(dir.file("c.obj"), "line 1: bad coordinate 'zero'");
  write_text(dir.file("d.obj"), "v 0 0 0\nvt 1 2\nv 1 0 0\nvt 1\nl 1 2\n");
  expect_error(dir.file("d.obj"), "line 4: vt has 1 values");
  write_text(dir.file("e.obj"), "v 0 0 0\nvt 1\nv 1 0 0\nl 1 2\n");
  expect_error(dir.file("e.obj"), "1 vt lines for 2 vertices");
  write_text(dir.file("f.obj"), "v 0 0 0\nv 1 0 0\nl 1 0\n");
  expect_error(dir.file("f.obj"), "line 3: bad vertex index '0'");
}

TEST(Malformed, ObjNegativeIndicesAndNaNReadThenValidate) {
  TempDir dir;
  write_text(dir.file("a.obj"), "v 0 0 0\nv 1 0 0\nv nan 0 0\nl -3 -2 -1\n");
  const LineSet l = read_line_set(dir.file("a.obj"));
  EXPECT_EQ(l.line_offsets, (std::vector<uint64_t>{0, 3}));
  EXPECT_TRUE(std::isnan(l.positions[6]));
}

TEST(Malformed, Binlines) {
  TempDir dir;
  write_bytes(dir.file("a.binlines"), {});
  expect_error(dir.file("a.binlines"), "empty file");
  write_bytes(dir.file("b.binlines"), {7, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0});
  expect_error(dir.file("b.binlines"), "byte offset 0: unsupported .binlines version 7");
  // One line claiming 1000 points in a 20-byte file.
  write_bytes(dir.file("c.binlines"),
              {1, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0xE8, 3, 0, 0, 0, 0, 0, 0});
  expect_error(dir.file("c.binlines"), "byte offset 12: line 0 claims 1000 points");
  // Two lines announced, one present.
  write_bytes(dir.file("d.binlines"), {1, 0, 0, 0, 200, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0});
  expect_error(dir.file("d.binlines"), "line count 200 does not fit");
  // Version 2 names its attributes: 3585 of them need 14,340 bytes of name lengths before a
  // 32-byte file's end (a fuzzer's input; each used to make an Attribute first).
  std::vector<uint8_t> names = {2, 0, 0, 0, 2, 0, 0, 0, 0x01, 0x0e, 0, 0};
  names.resize(32, 0);
  write_bytes(dir.file("e.binlines"), names);
  expect_error(dir.file("e.binlines"),
               "byte offset 8: attribute count 3585 needs 14340 bytes of names, the file has 20 "
               "left");
  // Version 1 with no lines may declare attributes without data: a valid, empty file.
  write_bytes(dir.file("f.binlines"), {1, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0});
  EXPECT_EQ(read_line_set(dir.file("f.binlines")).attributes.size(), 256u);
}

TEST(Malformed, VtkLegacy) {
  TempDir dir;
  write_text(dir.file("a.vtk"), "not vtk\n");
  expect_error(dir.file("a.vtk"), "line 1: not a VTK legacy file");
  write_text(dir.file("b.vtk"),
             "# vtk DataFile Version 3.0\nt\nASCII\nDATASET POLYDATA\nPOINTS 2 float\n0 0 0 1 1 1\n"
             "LINES 1 3\n2 0 5\n");
  expect_error(dir.file("b.vtk"), "point index 5 out of range");
  write_text(dir.file("c.vtk"),
             "# vtk DataFile Version 3.0\nt\nASCII\nDATASET POLYDATA\nPOINTS 2 float\n0 0 0 1 1\n");
  expect_error(dir.file("c.vtk"), "file ends after 5 of 6 values");
  write_text(dir.file("d.vtk"),
             "# vtk DataFile Version 3.0\nt\nASCII\nDATASET POLYDATA\nPOINTS 2 float\n0 0 0 1 1 1\n"
             "LINES 1 4\n2 0 1\n");
  expect_error(dir.file("d.vtk"), "cell list size 4 does not match");
  write_text(dir.file("e.vtk"),
             "# vtk DataFile Version 3.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\n");
  expect_error(dir.file("e.vtk"), "expected DATASET POLYDATA");
}

TEST(Malformed, Vtp) {
  TempDir dir;
  write_text(dir.file("a.vtp"), "<VTKFile type=\"PolyData\"><PolyData><Piece");
  expect_error(dir.file("a.vtp"), "XML error");
  write_text(dir.file("b.vtp"), "<VTKFile type=\"ImageData\"></VTKFile>");
  expect_error(dir.file("b.vtp"), "not a VTK XML PolyData file");
  write_text(
      dir.file("c.vtp"),
      "<VTKFile type=\"PolyData\"><PolyData><Piece NumberOfPoints=\"2\" NumberOfLines=\"1\">"
      "<Points><DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"ascii\">0 0 0 1 1"
      "</DataArray></Points></Piece></PolyData></VTKFile>");
  expect_error(dir.file("c.vtp"), "DataArray '': 5 values, expected 6");
}

TEST(Malformed, Hdf5) {
  TempDir dir;
  write_text(dir.file("a.h5"), "plain text");
  expect_error(dir.file("a.h5"), "not an HDF5 file");
}

TEST(Malformed, Csv) {
  TempDir dir;
  write_text(dir.file("a.csv"), "");
  expect_error(dir.file("a.csv"), "line 1: empty file");
  write_text(dir.file("b.csv"), "id,x,y,z\n");
  expect_error(dir.file("b.csv"), "line 1: header column 1 is 'id'");
  write_text(dir.file("c.csv"), "line_id,x,y,z,a\n0,0,0,0,1\n0,1,1\n");
  expect_error(dir.file("c.csv"), "line 3: 3 columns");
  write_text(dir.file("d.csv"), "line_id,x,y,z\n0,0,0,0\n1,0,0,0\n0,1,1,1\n");
  expect_error(dir.file("d.csv"), "line 4: rows of line 0 are not consecutive");
  write_text(dir.file("e.csv"), "line_id,x,y,z\n0,0,0,abc\n");
  expect_error(dir.file("e.csv"), "line 2: bad coordinate 'abc'");
}

// A file of no bytes lacks the header of every format but OBJ, which has none: there it is a
// valid file with no lines, as is one of vertices and comments only.
TEST(Malformed, EmptyFileOfEveryFormat) {
  TempDir dir;
  for (const FormatInfo& f : format_table()) {
    const std::string path = dir.file(std::string("empty") + f.extensions[0]);
    write_text(path, "");
    if (f.format == Format::obj)
      EXPECT_EQ(read_line_set(path).line_count(), 0u);
    else
      EXPECT_THROW(read_line_set(path), InputError) << f.name;
  }
  write_text(dir.file("comments.obj"), "# only a comment\nv 1 2 3\n");
  EXPECT_EQ(read_line_set(dir.file("comments.obj")).line_count(), 0u);
}

TEST(Malformed, UnknownExtension) {
  EXPECT_THROW(read_line_set("/tmp/lines.xyz"), Error);
}

// ---------------------------------------------------------------------------------------------
// Found by the fuzz targets (tests/fuzz, docs/fuzzing.md); their inputs are in the corpus too.

static std::string vtp_piece(const std::string& piece_attributes, const std::string& body) {
  return "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"1.0\" "
         "byte_order=\"LittleEndian\" header_type=\"UInt64\"><PolyData><Piece " +
         piece_attributes + ">" + body + "</Piece></PolyData></VTKFile>\n";
}

TEST(FuzzFindings, VtpCountsAreCheckedAgainstTheFileBeforeAllocating) {
  TempDir dir;
  // NumberOfPoints of 10^15 in a file of 300 bytes: refused, not a 12 PB allocation.
  write_text(dir.file("huge.vtp"),
             vtp_piece("NumberOfPoints=\"1000000000000000\" NumberOfLines=\"1\"",
                       "<Points><DataArray type=\"Float32\" NumberOfComponents=\"3\" "
                       "format=\"ascii\">0 0 0</DataArray></Points>"));
  expect_error(dir.file("huge.vtp"), "NumberOfPoints 1000000000000000 cannot be in a file");
  // Within the file's bound, a DataArray still has to hold its values: 1000 ASCII values cannot
  // be in 40 characters.
  write_text(dir.file("short.vtp"),
             vtp_piece("NumberOfPoints=\"300\" NumberOfLines=\"0\"",
                       "<Points><DataArray type=\"Float32\" NumberOfComponents=\"3\" "
                       "format=\"ascii\">0 0 0</DataArray></Points>"));
  expect_error(dir.file("short.vtp"), "DataArray");
}

TEST(FuzzFindings, VtpZlibBlocksCannotClaimMoreThanDeflateGives) {
  TempDir dir;
  // One block whose header claims 2^40 bytes from 8 compressed ones (base64 of the UInt64
  // words 1, 2^40, 2^40, 8 and eight data bytes).
  const std::string header = linebake::base64_encode(
      std::string("\x01\0\0\0\0\0\0\0", 8) + std::string("\0\0\0\0\0\x01\0\0", 8) +
      std::string("\0\0\0\0\0\x01\0\0", 8) + std::string("\x08\0\0\0\0\0\0\0", 8));
  const std::string data = linebake::base64_encode(std::string(8, 'x'));
  write_text(dir.file("zlib.vtp"),
             "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"1.0\" "
             "byte_order=\"LittleEndian\" header_type=\"UInt64\" "
             "compressor=\"vtkZLibDataCompressor\"><PolyData><Piece NumberOfPoints=\"1\" "
             "NumberOfLines=\"0\"><Points><DataArray type=\"Float32\" NumberOfComponents=\"3\" "
             "format=\"binary\">" +
                 header + data + "</DataArray></Points></Piece></PolyData></VTKFile>\n");
  expect_error(dir.file("zlib.vtp"), "claims 1099511627776 bytes from 8 compressed");
  // Raw appended data with a compressed size of 2^62 (1032 times it wraps to a small number):
  // past the data, refused before anything is sized from it.
  const std::string raw_header =
      std::string("\x01\0\0\0\0\0\0\0", 8) + std::string("\0\0\0\0\0\x01\0\0", 8) +
      std::string("\0\0\0\0\0\x01\0\0", 8) + std::string("\0\0\0\0\0\0\0\x40", 8);
  write_text(dir.file("wrap.vtp"),
             "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"1.0\" "
             "byte_order=\"LittleEndian\" header_type=\"UInt64\" "
             "compressor=\"vtkZLibDataCompressor\"><PolyData><Piece NumberOfPoints=\"1\" "
             "NumberOfLines=\"0\"><Points><DataArray type=\"Float32\" NumberOfComponents=\"3\" "
             "format=\"appended\" offset=\"0\"/></Points></Piece></PolyData>"
             "<AppendedData encoding=\"raw\">_" +
                 raw_header + std::string(8, 'x') + "</AppendedData></VTKFile>\n");
  expect_error(dir.file("wrap.vtp"), "compressed block past the end of data");
}

TEST(FuzzFindings, VtpLinesWithoutConnectivity) {
  TempDir dir;
  write_text(dir.file("noconn.vtp"),
             vtp_piece("NumberOfPoints=\"2\" NumberOfLines=\"1\"",
                       "<Points><DataArray type=\"Float32\" NumberOfComponents=\"3\" "
                       "format=\"ascii\">0 0 0 1 1 1</DataArray></Points><Lines><DataArray "
                       "type=\"Int64\" Name=\"offsets\" format=\"ascii\">2</DataArray></Lines>"));
  expect_error(dir.file("noconn.vtp"), "missing connectivity array");
}

// The campaign's finding: an index too large for int64 (UBSan: 2e+110 outside the range of
// 'long' in the cast); a float array of indices with a NaN, in VTP binary and legacy VTK alike.
TEST(FuzzFindings, IndicesOutsideTheirIntegerRange) {
  TempDir dir;
  const auto lines = [](const std::string& type, const std::string& format,
                        const std::string& connectivity) {
    return vtp_piece("NumberOfPoints=\"2\" NumberOfLines=\"1\"",
                     "<Points><DataArray type=\"Float32\" NumberOfComponents=\"3\" "
                     "format=\"ascii\">0 0 0 1 1 1</DataArray></Points><Lines><DataArray "
                     "type=\"" +
                         type + "\" Name=\"connectivity\" format=\"" + format + "\">" +
                         connectivity +
                         "</DataArray><DataArray type=\"Int64\" Name=\"offsets\" "
                         "format=\"ascii\">2</DataArray></Lines>");
  };
  write_text(dir.file("huge.vtp"), lines("Int64", "ascii", "0 2e110"));
  expect_error(dir.file("huge.vtp"), "DataArray 'connectivity': value 2e110 is outside");
  // Float32 {0, NaN}, binary: a UInt64 byte count, then the data, in base64.
  write_text(dir.file("nan.vtp"), lines("Float32", "binary", "CAAAAAAAAAAAAAAAAADAfw=="));
  expect_error(dir.file("nan.vtp"),
               "a Float32 value outside the range of the array it is read into");
  write_text(dir.file("huge.vtk"),
             "# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\nPOINTS 2 float\n"
             "0 0 0 1 1 1\nLINES 1 3\n2 0 1e300\n");
  expect_error(dir.file("huge.vtk"), "value 1e300 is outside the array's range");
}

// Attributes are found by name (--attribute, HDF5 datasets, JSON): a name given twice (VTK's
// writer calls every unnamed FIELD array "unknown"), or none, is renamed when the file is opened,
// name_2 after name (skipping names the file has), "unnamed" for none, whatever the format, with
// the renames in the metadata (names given twice had been taken and failed only when written to
// HDF5, exit 3 naming a temporary file). The values stay with their arrays.
TEST(MalformedInput, AttributeNamesGivenTwiceOrNotAtAllAreRenamed) {
  TempDir dir;
  const std::string head =
      "# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\nPOINTS 2 float\n0 0 0 1 1 1\n"
      "LINES 1 3\n2 0 1\nPOINT_DATA 2\n";
  write_text(dir.file("twice.vtk"), head +
                                        "SCALARS t float\nLOOKUP_TABLE default\n1 2\n"
                                        "SCALARS t_2 float\nLOOKUP_TABLE default\n5 6\n"
                                        "SCALARS t float\nLOOKUP_TABLE default\n3 4\n"
                                        "CELL_DATA 1\nSCALARS w float\nLOOKUP_TABLE default\n7\n"
                                        "SCALARS w float\nLOOKUP_TABLE default\n8\n");
  const LineSet lines = read_line_set(dir.file("twice.vtk"));
  ASSERT_EQ(lines.attributes.size(), 3u);
  EXPECT_EQ(lines.attributes[0].name, "t");
  EXPECT_EQ(lines.attributes[1].name, "t_2");
  EXPECT_EQ(lines.attributes[2].name, "t_3");  // t_2 is the file's own
  EXPECT_EQ(lines.attributes[2].values, (std::vector<float>{3, 4}));
  ASSERT_EQ(lines.line_attributes.size(), 2u);
  EXPECT_EQ(lines.line_attributes[1].name, "w_2");  // the same name as a vertex one is no clash
  EXPECT_EQ(lines.line_attributes[1].values, (std::vector<float>{8}));
  EXPECT_EQ(lines.metadata.at("linebake.renamed_attributes"),
            "vertex attribute 3 't' as 't_3'; line attribute 2 'w' as 'w_2'");
  // Written on, the names are one each: the note is the first file's, not carried on.
  write_line_set(lines, dir.file("renamed.vtp"));
  const LineSet again = read_line_set(dir.file("renamed.vtp"));
  EXPECT_EQ(again.attributes[2].name, "t_3");
  EXPECT_EQ(again.metadata.count("linebake.renamed_attributes"), 0u);
  // A streamed format, batch by batch: binlines v2, 2 lines of 2 points, attributes "a" and "a".
  const auto u32 = [](std::vector<unsigned char>& out, uint32_t v) {
    for (int b = 0; b < 4; ++b) out.push_back(static_cast<unsigned char>(v >> (8 * b)));
  };
  const auto f32 = [&](std::vector<unsigned char>& out, float v) {
    uint32_t bits;
    std::memcpy(&bits, &v, 4);
    u32(out, bits);
  };
  std::vector<unsigned char> twice;
  for (uint32_t v : {2u, 2u, 2u, 1u}) u32(twice, v);
  twice.push_back('a');
  u32(twice, 1);
  twice.push_back('a');
  for (int line = 0; line < 2; ++line) {
    u32(twice, 2);
    for (int k = 0; k < 6; ++k) f32(twice, float(k));
    for (float v : {1.0f, 2.0f, 10.0f + float(line), 20.0f}) f32(twice, v);  // a's, then a's
  }
  write_bytes(dir.file("twice.binlines"), twice);
  auto reader = open_line_reader(dir.file("twice.binlines"));
  EXPECT_EQ(reader->header().attributes[1].name, "a_2");
  LineSet batch;
  for (int line = 0; line < 2; ++line) {
    ASSERT_TRUE(reader->next(batch, 1));
    ASSERT_EQ(batch.attributes.size(), 2u);
    EXPECT_EQ(batch.attributes[1].name, "a_2");
    EXPECT_EQ(batch.attributes[1].values, (std::vector<float>{10.0f + float(line), 20}));
  }
  EXPECT_EQ(reader->lines_read(), 2u);
  // binlines v2: version 2, 1 line, 1 attribute named by 0 bytes; the line of 2 points.
  std::vector<unsigned char> unnamed = {2, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 2, 0, 0, 0};
  unnamed.resize(unnamed.size() + 8 * 4, 0);  // 6 coordinates and 2 values, all 0.0f
  write_bytes(dir.file("unnamed.binlines"), unnamed);
  const LineSet named = read_line_set(dir.file("unnamed.binlines"));
  ASSERT_EQ(named.attributes.size(), 1u);
  EXPECT_EQ(named.attributes[0].name, "unnamed");
  // A name given thousands of times (a fuzzer's OBJ `a` line): each renamed once, the note
  // naming the first 16.
  std::string many = "a";
  for (int i = 0; i < 5000; ++i) many += " x";
  write_text(dir.file("many.obj"), many + "\n");
  const LineSet crowded = read_line_set(dir.file("many.obj"));
  ASSERT_EQ(crowded.attributes.size(), 5000u);
  EXPECT_EQ(crowded.attributes[4999].name, "x_5000");
  const std::string& note = crowded.metadata.at("linebake.renamed_attributes");
  EXPECT_NE(note.find("vertex attribute 17 'x' as 'x_17'; and 4983 more"), std::string::npos)
      << note.substr(0, 200);
  // Names that were one each: no note.
  write_text(dir.file("once.vtk"), head + "SCALARS t float\nLOOKUP_TABLE default\n1 2\n");
  EXPECT_EQ(read_line_set(dir.file("once.vtk")).metadata.count("linebake.renamed_attributes"), 0u);
}

// A METADATA block (VTK 9) is the keyword alone on its line; a FIELD array may be named
// METADATA too, its counts and type after it on the line: an array, as it was read before the
// blocks were (review finding: it had been taken for a block).
TEST(MalformedInput, VtkFieldArrayNamedMetadataIsAnArray) {
  TempDir dir;
  write_text(dir.file("named.vtk"),
             "# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\nPOINTS 2 float\n0 0 0 1 1 1\n"
             "LINES 1 3\n2 0 1\nPOINT_DATA 2\nFIELD FieldData 3\na 1 2 float\n1 2\nMETADATA\n"
             "INFORMATION 0\n\nmetadata 1 2 float\n3 4\nMETADATA 1 2 float\n5 6\n");
  const LineSet lines = read_line_set(dir.file("named.vtk"));
  ASSERT_EQ(lines.attributes.size(), 3u);
  EXPECT_EQ(lines.attributes[1].name, "metadata");
  EXPECT_EQ(lines.attributes[1].values, (std::vector<float>{3, 4}));
  EXPECT_EQ(lines.attributes[2].name, "METADATA");
  EXPECT_EQ(lines.attributes[2].values, (std::vector<float>{5, 6}));
}

// VTK writes a METADATA block's COMPONENT_NAMES as one line a component, an empty one for a
// component without a name: the block ends at the empty line after INFORMATION, not at those
// (review finding: a partly named array's block had ended early, the next name read as a
// keyword). Partly named components keep the default names.
TEST(MalformedInput, VtkPartlyNamedComponents) {
  TempDir dir;
  write_text(dir.file("partly.vtk"),
             "# vtk DataFile Version 5.1\nx\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n"
             "0 0 0 1 0 0 2 0 0\nLINES 1 4\n3 0 1 2\nPOINT_DATA 3\nVECTORS vel float\n"
             "0 1 2 3 4 5 6 7 8\nMETADATA\nCOMPONENT_NAMES\nvx\n\nvz\nINFORMATION 0\n\n"
             "SCALARS after float 1\nLOOKUP_TABLE default\n0 1 2\n");
  const LineSet lines = read_line_set(dir.file("partly.vtk"));
  ASSERT_EQ(lines.attributes.size(), 4u);
  EXPECT_EQ(lines.attributes[1].name, "vel_y");
  EXPECT_EQ(lines.attributes[3].name, "after");
  EXPECT_EQ(lines.attributes[3].values, (std::vector<float>{0, 1, 2}));
}

// MRtrix .tck headers: a key given again keeps every value, one a line, as MRtrix's reader does
// (the last one only had been kept); a data offset inside the header or past the file's end is
// said as such (the header's text had been read as points, or a seek failed at "byte offset 0").
TEST(MalformedInput, TckHeaderKeysRepeatedAndDataOffsets) {
  TempDir dir;
  const auto tck = [&](const std::string& name, uint64_t data_offset, bool pad) {
    std::string text =
        "mrtrix tracks\nroi: a.nii\nroi: b.nii\ndatatype: Float32LE\ncount: 1\nfile: . " +
        std::to_string(data_offset) + "\nEND\n";
    if (pad) text.resize(data_offset, '\0');
    std::vector<unsigned char> bytes(text.begin(), text.end());
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const float inf = std::numeric_limits<float>::infinity();
    for (float v : {0.0f, 0.0f, 0.0f, 1.0f, 2.0f, 3.0f, nan, nan, nan, inf, inf, inf}) {
      unsigned char b[4];
      std::memcpy(b, &v, 4);
      bytes.insert(bytes.end(), b, b + 4);
    }
    write_bytes(dir.file(name), bytes);
    return dir.file(name);
  };
  const LineSet lines = read_line_set(tck("ok.tck", 128, true));
  EXPECT_EQ(lines.line_count(), 1u);
  EXPECT_EQ(lines.positions[5], 3.0f);
  EXPECT_EQ(lines.metadata.at("tck.roi"), "a.nii\nb.nii");
  expect_error(tck("inside.tck", 20, false),
               "'file: . 20' points inside the header, which ends at byte");
  expect_error(tck("past.tck", 100000, false), "'file: . 100000' points past the end of the");
}

// OBJ vertex colours (`v x y z r g b`, or `v x y z w r g b`) are the attributes color_r/_g/_b after
// the vt ones, gathered along the `l` indices as vt values are (they had been dropped silently); a
// vertex without one, in a file that colours others, has NaN (no value) there (review finding: such
// files had read before and were refused).
TEST(MalformedInput, ObjVertexColoursAreAttributes) {
  TempDir dir;
  write_text(dir.file("colour.obj"),
             "v 0 0 0 1 0 0\nv 1 0 0 0 0.5 0\nv 2 0 0 0 0 0.25\nvt 5\nvt 6\nvt 7\na temp\n"
             "l 1 2 3\nl 3 1\n");
  const LineSet lines = read_line_set(dir.file("colour.obj"));
  ASSERT_EQ(lines.attributes.size(), 4u);
  EXPECT_EQ(lines.attributes[0].name, "temp");
  EXPECT_EQ(lines.attributes[1].name, "color_r");
  EXPECT_EQ(lines.attributes[3].name, "color_b");
  // The second line walks vertex 3, then 1.
  EXPECT_EQ(lines.attributes[0].values, (std::vector<float>{5, 6, 7, 7, 5}));
  EXPECT_EQ(lines.attributes[1].values, (std::vector<float>{1, 0, 0, 0, 1}));
  EXPECT_EQ(lines.attributes[2].values, (std::vector<float>{0, 0.5f, 0, 0, 0}));
  EXPECT_EQ(lines.attributes[3].values, (std::vector<float>{0, 0, 0.25f, 0.25f, 0}));
  write_text(dir.file("some.obj"), "v 0 0 0\nv 1 0 0 1 0.5 1\nv 2 0 0\nl 1 2 3\n");
  const LineSet some = read_line_set(dir.file("some.obj"));
  ASSERT_EQ(some.attributes.size(), 3u);
  EXPECT_TRUE(std::isnan(some.attributes[1].values[0]));
  EXPECT_EQ(some.attributes[1].values[1], 0.5f);
  EXPECT_TRUE(std::isnan(some.attributes[1].values[2]));
  write_text(dir.file("w.obj"), "v 0 0 0 1\nv 1 0 0 1\nl 1 2\n");
  EXPECT_TRUE(read_line_set(dir.file("w.obj")).attributes.empty());
  // With the weight w, the colour comes after it (it had been left unread).
  write_text(dir.file("wrgb.obj"), "v 0 0 0 1 0.25 0.5 0.75\nv 1 0 0 2 1 0 0\nl 1 2\n");
  const LineSet wrgb = read_line_set(dir.file("wrgb.obj"));
  ASSERT_EQ(wrgb.attributes.size(), 3u);
  EXPECT_EQ(wrgb.positions, (std::vector<float>{0, 0, 0, 1, 0, 0}));
  EXPECT_EQ(wrgb.attributes[0].values, (std::vector<float>{0.25f, 1}));
  EXPECT_EQ(wrgb.attributes[1].values, (std::vector<float>{0.5f, 0}));
  EXPECT_EQ(wrgb.attributes[2].values, (std::vector<float>{0.75f, 0}));
}

// OBJ continues a statement on the next line after a trailing backslash: a long `l` split so
// is one polyline (it had been refused as a bad vertex index '\\'); a file ending inside one is
// refused, not read short.
TEST(MalformedInput, ObjStatementsContinuedOverLines) {
  TempDir dir;
  write_text(dir.file("continued.obj"),
             "v 0 0 0\nv 1 0 0\nv 2 0 0\nl 1 \\\n  2 \\\n 3\n# a comment\nl 3 1\n");
  const LineSet lines = read_line_set(dir.file("continued.obj"));
  ASSERT_EQ(lines.line_count(), 2u);
  EXPECT_EQ(lines.line_size(0), 3u);
  EXPECT_EQ(lines.positions[6], 2.0f);  // the first line's third point is vertex 3
  write_text(dir.file("cut.obj"), "v 0 0 0\nv 1 0 0\nl 1 \\\n");
  expect_error(dir.file("cut.obj"), "line 3: the file ends in a statement continued with");
  // A comment runs to its line's end, a backslash there included, and may follow a statement
  // (review finding: the next statement had been joined into the comment, a line lost).
  write_text(dir.file("comments.obj"),
             "v 0 0 0\nv 1 0 0 # first\nv 2 0 0 #a b c\nl 1 2\n# from D:\\lines\\\nl 2 3\n");
  const LineSet commented = read_line_set(dir.file("comments.obj"));
  EXPECT_EQ(commented.line_count(), 2u);
  EXPECT_TRUE(commented.attributes.empty());
  // But not in linebake's own `a` line, where older versions wrote '#' in a name as it was.
  write_text(dir.file("names.obj"), "a n#obs speed\nv 0 0 0\nvt 1 2\nv 1 0 0\nvt 3 4\nl 1 2\n");
  const LineSet named = read_line_set(dir.file("names.obj"));
  ASSERT_EQ(named.attributes.size(), 2u);
  EXPECT_EQ(named.attributes[0].name, "n#obs");
}

// JSON a user writes by hand: a number past double's range, a value of the wrong type, text that
// is not UTF-8 are the file's errors, with its name, not nlohmann::json's exceptions.
TEST(FuzzFindings, JsonInputsRefuseWhatNlohmannJsonThrows) {
  TempDir dir;
  const auto refused = [&](const std::string& name, const std::function<void(std::string)>& load) {
    try {
      load(dir.file(name));
      ADD_FAILURE() << name << " was accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  };
  write_text(dir.file("tf.json"), "{\"name\": \"x\", \"range\": [0, 1e400]}");
  refused("tf.json", [](const std::string& p) { load_transfer_function(p); });
  // The campaign's finding: a name that is not a string (nlohmann::json's type_error 302).
  write_text(dir.file("tf-name.json"),
             "{\"name\":[0, 1], \"colours\": [[1, 0, 0.1, 0]], \"opacities\": [[0, 0.1], [1, 1]]}");
  refused("tf-name.json", [](const std::string& p) { load_transfer_function(p); });
  write_text(dir.file("keys.json"),
             "{\"keyframes\": [{\"eye\": [0, 0, 1], \"target\": [0, 0, 0], \"fov\": \"wide\"}]}");
  refused("keys.json", [](const std::string& p) {
    FlightOptions f;
    f.kind = FlightKind::Keyframes;
    f.keyframes_file = p;
    Bounds b;
    b.max = {1, 1, 1}, b.empty = false;
    make_flight(b, 1.0, f);
  });
  write_text(dir.file("p.json"), "{\"name\": 1e999}");
  refused("p.json", [](const std::string& p) { load_pipeline(p); });
  write_text(dir.file("p.yaml"), "name: \"\x95\x95\"\ndata: synth:aneurysm\n");
  refused("p.yaml", [](const std::string& p) { load_pipeline(p); });
}

// What linebake writes as JSON holds a file name that is not UTF-8 with U+FFFD (EF BF BD) for each
// bad byte, where nlohmann::json's dump() throws type_error 316; valid text is left as it is.
TEST(FuzzFindings, JsonTextKeepsNamesThatAreNotUtf8) {
  const nlohmann::json value = {{"file",
                                 "a\x95"
                                 "b.binlines"},
                                {"lines", 2}};
  EXPECT_THROW((void)value.dump(), nlohmann::json::type_error);
  EXPECT_EQ(json_text(value),
            "{\"file\":\"a\xEF\xBF\xBD"
            "b.binlines\",\"lines\":2}");
  EXPECT_EQ(json_text(value, 1),
            "{\n \"file\": \"a\xEF\xBF\xBD"
            "b.binlines\",\n \"lines\": 2\n}");
  EXPECT_EQ(json_text(nlohmann::json{{"name", "\xC3\xA9t\xC3\xA9"}}),
            "{\"name\":\"\xC3\xA9t\xC3\xA9\"}");
}

// The campaign's pipeline_yaml finding: a transfer function named by 300 characters, which the
// parser looked for as a file beside the pipeline with the throwing std::filesystem overload:
// "File name too long" escaped as std::filesystem_error. Such a name is no file (and no preset):
// the pipeline loads and keeps it as written. A pipeline path that long is a missing file.
TEST(FuzzFindings, ANameTooLongForTheFileSystemIsNoFile) {
  TempDir dir;
  const std::string long_name(300, 'f');
  write_text(dir.file("p.yaml"),
             "name: t\n"
             "datasets:\n  - {name: a, source: \"synth:aneurysm?scale=0.01\"}\n"
             "techniques: [reference, ll]\n"
             "transfer_functions: [semi, " +
                 long_name + "]\n");
  const Pipeline p = load_pipeline(dir.file("p.yaml"));
  ASSERT_EQ(p.transfer_functions.size(), 2u);
  EXPECT_EQ(p.transfer_functions[1], long_name);
  EXPECT_EQ(p.transfer_function_files.count(long_name), 0u);
  EXPECT_THROW(load_pipeline(dir.file(long_name)), InputError);
}

// Counts in a VTK legacy header are checked against what is left of the file before anything is
// sized from them (docs/fuzzing.md, guarded allocation): a 100-byte file claiming 10^15 points,
// cells, cell sizes, tuples or lookup-table entries is an error naming the count.
TEST(GuardedAllocation, VtkLegacyCountsAreCheckedAgainstTheFile) {
  TempDir dir;
  const std::string head = "# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\n";
  const std::pair<const char*, std::string> cases[] = {
      {"POINTS count 1000000000000000", "POINTS 1000000000000000 float\n0 0 0\n"},
      {"cell count 1000000000000000", "POINTS 2 float\n0 0 0 1 1 1\nLINES 1000000000000000 3\n"},
      {"cell list size 1000000000000000",
       "POINTS 2 float\n0 0 0 1 1 1\nLINES 1 1000000000000000\n"},
      {"cell size 1000000000000000", "POINTS 2 float\n0 0 0 1 1 1\nLINES 1 3\n1000000000000000\n"},
      {"POINT_DATA or CELL_DATA count",
       "POINTS 2 float\n0 0 0 1 1 1\nLINES 1 3\n2 0 1\nPOINT_DATA 1000000000000000\n"
       "SCALARS s float\nLOOKUP_TABLE default\n0 0\n"},
      {"LOOKUP_TABLE size 1000000000000000",
       "POINTS 2 float\n0 0 0 1 1 1\nLINES 1 3\n2 0 1\nLOOKUP_TABLE t 1000000000000000\n0\n"},
  };
  int k = 0;
  for (const auto& [expected, body] : cases) {
    const std::string path = dir.file("c" + std::to_string(k++) + ".vtk");
    write_text(path, head + body);
    expect_error(path, expected);
  }
}
