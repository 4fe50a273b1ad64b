// Lines far from 0 kept relative to a local origin (lines/origin.hpp): read in double and moved
// before float32, held so by every format that can, and put back where a file holds world
// coordinates.

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <functional>
#include <initializer_list>
#include <optional>
#include <utility>

#include "core/error.hpp"
#include "formats/registry.hpp"
#include "lines/origin.hpp"
#include "test_util.hpp"

using namespace linebake;
using linebake::test::TempDir;

namespace {

// UTM-like coordinates (easting ~5e5 m, northing ~5.4e6 m) whose millimetres matter: float32
// steps by 0.5 m at 5.4e6, so read as they are they lose them.
constexpr double kEast = 500000, kNorth = 5400000;
const Origin kOrigin{kEast, kNorth, 0};

struct WorldPoint {
  double x, y, z;
};
std::vector<std::vector<WorldPoint>> world_lines() {
  std::vector<std::vector<WorldPoint>> lines(3);
  for (int l = 0; l < 3; ++l)
    for (int i = 0; i < 5 + l; ++i)
      lines[size_t(l)].push_back(
          {kEast + 10.0 * l + 0.001 * i, kNorth + 3.0 * i + 0.123, 100.0 + 0.25 * i});
  return lines;
}

std::string world_csv() {
  std::string text = "line_id,x,y,z,t\n";
  int id = 0;
  for (const auto& line : world_lines()) {
    for (const WorldPoint& p : line) {
      char row[160];
      std::snprintf(row, sizeof row, "%d,%.17g,%.17g,%.17g,%d\n", id, p.x, p.y, p.z, id);
      text += row;
    }
    ++id;
  }
  return text;
}

// The positions expected relative to `origin`: each coordinate's difference, in double, rounded
// to float32 once.
std::vector<float> expected_local(const Origin& origin) {
  std::vector<float> out;
  for (const auto& line : world_lines())
    for (const WorldPoint& p : line)
      for (int k = 0; k < 3; ++k)
        out.push_back(static_cast<float>((k == 0 ? p.x : k == 1 ? p.y : p.z) - origin[k]));
  return out;
}

// One line through `points`.
LineSet one_line(std::initializer_list<std::array<float, 3>> points) {
  LineSet lines;
  for (const auto& p : points) lines.append_point(p[0], p[1], p[2]);
  lines.end_line();
  return lines;
}

ReadOptions at(const Origin& origin) {
  ReadOptions o;
  o.origin = origin;
  return o;
}

}  // namespace

TEST(Origin, TextRoundTripsAndRefusesWhatIsNotThreeNumbers) {
  const Origin o{500000, 5400000.125, -0.1};
  EXPECT_EQ(origin_text(o), "500000 5400000.125 -0.1");
  EXPECT_EQ(parse_origin(origin_text(o)), o);
  EXPECT_EQ(parse_origin("500000,5400000.125,-0.1"), o);
  EXPECT_EQ(parse_origin(" 500000 , 5400000.125 ,-0.1 "), o);
  EXPECT_EQ(parse_origin("+1e300,2,3"), (Origin{1e300, 2, 3}));
  EXPECT_EQ(parse_origin(origin_text({1e300, 2e-9, 0})), (Origin{1e300, 2e-9, 0}));
  for (const char* bad : {"", "1,2", "1,2,3,4", "1,,2,3", "1-2 3", "nan,0,0", "inf 0 0", "a,b,c",
                          "1e999,0,0", "+-5,0,0", "++5,0,0", "+,0,0"})
    EXPECT_FALSE(parse_origin(bad)) << bad;
  // -0 is 0: one text, so one /lines key.
  const std::optional<Origin> zero = parse_origin("-0,0,-0.0");
  ASSERT_TRUE(zero);
  EXPECT_FALSE(std::signbit((*zero)[0]) || std::signbit((*zero)[2]));
  EXPECT_EQ(origin_text(*zero), "0 0 0");
  LineSet lines;
  EXPECT_FALSE(has_origin(lines));
  EXPECT_EQ(origin_of(lines), (Origin{0, 0, 0}));
  lines.metadata[kOriginKey] = "1 2";
  EXPECT_THROW(origin_of(lines, "f.h5"), InputError);
}

TEST(Origin, CsvFarFromZeroKeepsItsDigitsOnlyWithAnOrigin) {
  TempDir dir;
  test::write_text(dir.file("utm.csv"), world_csv());
  const LineSet plain = read_line_set(dir.file("utm.csv"));
  const LineSet local = read_line_set(dir.file("utm.csv"), at(kOrigin));
  EXPECT_FALSE(has_origin(plain));
  EXPECT_EQ(local.metadata.at("origin"), "500000 5400000 0");
  EXPECT_EQ(local.positions, expected_local(kOrigin));
  // Without the origin the northing's 0.123 m is gone (float32 steps by 0.5 m there), and the
  // easting's millimetres with it (0.03125 m steps).
  const std::vector<float> plain_expected = expected_local({0, 0, 0});
  EXPECT_EQ(plain.positions, plain_expected);
  EXPECT_GT(std::fabs(double(plain.positions[1]) - (kNorth + 0.123)), 0.1);
  EXPECT_LT(std::fabs(double(local.positions[1]) + kNorth - (kNorth + 0.123)), 1e-6);
}

TEST(Origin, EveryWritableFormatGivesTheSameLocalPositionsBack) {
  TempDir dir;
  test::write_text(dir.file("utm.csv"), world_csv());
  const LineSet local = read_line_set(dir.file("utm.csv"), at(kOrigin));
  WriteOptions ascii;
  ascii.ascii = true;
  WriteOptions vtp_ascii;
  vtp_ascii.vtp_encoding = "ascii";
  const std::pair<const char*, WriteOptions> outputs[] = {
      {"a.csv", {}}, {"a.obj", {}},        {"a.vtk", {}}, {"b.vtk", ascii},
      {"a.vtp", {}}, {"b.vtp", vtp_ascii}, {"a.h5", {}}};
  for (const auto& [name, options] : outputs) {
    SCOPED_TRACE(name);
    write_line_set(local, dir.file(name), options);
    // World coordinates in float64 (CSV, OBJ, VTK, VTP) or the origin beside the float32
    // points (HDF5): read at the same origin, the positions come back to the bit.
    const LineSet back = read_line_set(dir.file(name), at(kOrigin));
    EXPECT_EQ(back.positions, local.positions);
    EXPECT_EQ(back.metadata.at("origin"), "500000 5400000 0");
  }
  // The HDF5 file keeps its origin when read without one; the others hold world coordinates,
  // with no "origin" left in their metadata to move them twice.
  const LineSet h5 = read_line_set(dir.file("a.h5"));
  EXPECT_EQ(h5.positions, local.positions);
  EXPECT_EQ(h5.metadata.at("origin"), "500000 5400000 0");
  for (const char* name : {"a.vtk", "a.vtp", "a.csv"}) {
    const LineSet world = read_line_set(dir.file(name));
    EXPECT_FALSE(has_origin(world)) << name;
    EXPECT_EQ(world.positions, expected_local({0, 0, 0})) << name;
  }
  EXPECT_NE(test::read_text(dir.file("a.vtk")).find("POINTS 18 double"), std::string::npos);
  EXPECT_NE(test::read_text(dir.file("b.vtp")).find("type=\"Float64\" Name=\"Points\""),
            std::string::npos);
  // The HDF5 file read at another origin: its float32 points moved in double from its origin to
  // the other, then rounded once.
  const Origin other{kEast + 7, kNorth - 2, 50};
  const LineSet moved = read_line_set(dir.file("a.h5"), at(other));
  ASSERT_EQ(moved.positions.size(), local.positions.size());
  for (size_t i = 0; i < moved.positions.size(); ++i)
    EXPECT_EQ(moved.positions[i],
              float(double(local.positions[i]) + kOrigin[i % 3] - other[i % 3]));
  EXPECT_NE(moved.positions, local.positions);
}

TEST(Origin, Float32SourcesAreMovedOnceAndWrittenAsWorldFloat32) {
  TempDir dir;
  test::write_text(dir.file("utm.csv"), world_csv());
  const LineSet local = read_line_set(dir.file("utm.csv"), at(kOrigin));
  write_line_set(local, dir.file("a.binlines"));
  // binlines holds float32 world coordinates: the origin added back, rounded to float32.
  const LineSet world = read_line_set(dir.file("a.binlines"));
  ASSERT_EQ(world.positions.size(), local.positions.size());
  for (size_t i = 0; i < world.positions.size(); ++i)
    EXPECT_EQ(world.positions[i], float(double(local.positions[i]) + kOrigin[i % 3]));
  // Read at an origin, a float32 coordinate moves by it exactly once.
  const LineSet moved = read_line_set(dir.file("a.binlines"), at(kOrigin));
  for (size_t i = 0; i < moved.positions.size(); ++i)
    EXPECT_EQ(moved.positions[i], float(double(world.positions[i]) - kOrigin[i % 3]));
  // convert warns of it: the formats that keep the digits are named.
  const std::vector<std::string> lost = lost_in_format(local, Format::binlines, {});
  ASSERT_EQ(lost.size(), 1u);
  EXPECT_NE(lost[0].find("float32"), std::string::npos);
  EXPECT_TRUE(lost_in_format(local, Format::vtk, {}).empty());
}

TEST(Origin, AutoIsTheFirstValidPointRounded) {
  TempDir dir;
  test::write_text(dir.file("a.csv"),
                   "line_id,x,y,z\n0,nan,1,2\n0,500123.5,5400000.25,-12.7\n0,500124,5400001,-12\n");
  EXPECT_EQ(auto_origin({dir.file("a.csv")}), (Origin{500124, 5400000, -13}));
  // A file without a valid point: no move (its own origin, here none).
  test::write_text(dir.file("b.csv"), "line_id,x,y,z\n0,nan,1,2\n");
  EXPECT_EQ(auto_origin({dir.file("b.csv")}), (Origin{0, 0, 0}));
  EXPECT_EQ(resolve_origin("", {dir.file("a.csv")}), std::nullopt);
  EXPECT_EQ(resolve_origin("1,2,3", {dir.file("a.csv")}), (Origin{1, 2, 3}));
  EXPECT_THROW(resolve_origin("1,2", {dir.file("a.csv")}), UsageError);
}

TEST(Origin, SeveralFilesAreReadInTheFirstFilesFrame) {
  TempDir dir;
  test::write_text(dir.file("utm.csv"), world_csv());
  write_line_set(read_line_set(dir.file("utm.csv"), at(kOrigin)), dir.file("a.h5"));
  // A second file in another frame (world coordinates, and an HDF5 file at another origin).
  write_line_set(read_line_set(dir.file("utm.csv")), dir.file("b.vtp"));
  write_line_set(read_line_set(dir.file("utm.csv"), at({kEast - 100, kNorth + 100, 1})),
                 dir.file("c.h5"));
  const std::unique_ptr<LineReader> reader = open_line_reader(
      std::vector<std::string>{dir.file("a.h5"), dir.file("b.vtp"), dir.file("c.h5")});
  EXPECT_EQ(reader->header().metadata.at("origin"), "500000 5400000 0");
  LineSet all = header_of(reader->header());
  LineSet batch;
  while (reader->next(batch, 1000)) append_lines(all, batch);
  const std::vector<float> a = expected_local(kOrigin);
  ASSERT_EQ(all.positions.size(), 3 * a.size());
  // The first file's points as written; the VTP's float32 world points moved by the origin; the
  // second HDF5 file's moved from its origin to the first's.
  EXPECT_TRUE(std::equal(a.begin(), a.end(), all.positions.begin()));
  const LineSet world = read_line_set(dir.file("b.vtp"));
  for (size_t i = 0; i < a.size(); ++i)
    EXPECT_EQ(all.positions[a.size() + i], to_local(world.positions[i], kOrigin[i % 3]));
  const LineSet c = read_line_set(dir.file("c.h5"));
  const Origin c_origin = origin_of(c);
  for (size_t i = 0; i < a.size(); ++i)
    EXPECT_EQ(all.positions[2 * a.size() + i],
              to_local(to_world(c.positions[i], c_origin[i % 3]), kOrigin[i % 3]));
}

TEST(Origin, AnotherFormatsOriginMetadataIsNotAFrame) {
  TempDir dir;
  // A VTP whose field data happens to carry "origin": its points are what they are.
  const LineSet lines = one_line({{1, 2, 3}, {4, 5, 6}});
  write_line_set(lines, dir.file("a.vtp"));
  std::string text = test::read_text(dir.file("a.vtp"));
  const std::string field =
      "<FieldData>\n<Array type=\"String\" Name=\"origin\" NumberOfTuples=\"1\" "
      "format=\"ascii\">\n49 32 50 32 51 0\n</Array>\n</FieldData>\n";
  text.insert(text.find("<Piece"), field);
  test::write_text(dir.file("b.vtp"), text);
  const LineSet back = read_line_set(dir.file("b.vtp"));
  EXPECT_FALSE(has_origin(back));
  EXPECT_EQ(back.metadata.at("source_origin"), "1 2 3");  // kept, under another name
  EXPECT_EQ(back.positions, lines.positions);
  // Read at an origin: the frame asked for, the file's own "origin" still kept beside it.
  const LineSet moved = read_line_set(dir.file("b.vtp"), at({1, 1, 1}));
  EXPECT_EQ(moved.metadata.at("origin"), "1 1 1");
  EXPECT_EQ(moved.metadata.at("source_origin"), "1 2 3");
  EXPECT_EQ(moved.positions, (std::vector<float>{0, 1, 2, 3, 4, 5}));
}

// Points enough for the VTK reader's blocks of doubles (65,535 values) to cut a file's POINTS in
// three: binary and ASCII read back to the bit at the origin.
TEST(Origin, VtkPointsReadInBlocksAreMovedEach) {
  TempDir dir;
  LineSet local;
  for (int i = 0; i < 50000; ++i)
    // At least 1 in magnitude: float32's steps there (1.2e-7 and up) are far above a float64
    // world coordinate's at 6.4e6 (9.3e-10), so the round trip is exact (nearer 0 it is exact
    // to the world coordinate's float64 step).
    local.append_point(1 + 0.001f * float(i), -1 - 0.5f * float(i % 97), 1 + 1e-3f * float(i % 13));
  local.end_line();
  set_origin(local, {6378137.5, -2.25, 1e5});
  WriteOptions ascii;
  ascii.ascii = true;
  for (const WriteOptions& options : {WriteOptions{}, ascii}) {
    write_line_set(local, dir.file("a.vtk"), options);
    const LineSet back = read_line_set(dir.file("a.vtk"), at({6378137.5, -2.25, 1e5}));
    EXPECT_EQ(back.positions, local.positions) << (options.ascii ? "ascii" : "binary");
  }
}

namespace {

// An HDF5 line file as another tool (h5py) writes one: `n` points of `file_type`, given in
// `memory_type`, one line; `attributes` adds root attributes.
void write_foreign_h5(const std::string& path, hid_t file_type, hid_t memory_type,
                      const void* points, hsize_t n,
                      const std::function<void(hid_t)>& attributes = {}) {
  const uint64_t offsets[] = {0, n};
  const hid_t file = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  const hsize_t dims[2] = {n, 3}, two = 2;
  const hid_t space = H5Screate_simple(2, dims, nullptr),
              line_space = H5Screate_simple(1, &two, nullptr);
  const hid_t p =
      H5Dcreate2(file, "points", file_type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  const hid_t o = H5Dcreate2(file, "line_offsets", H5T_STD_U64LE, line_space, H5P_DEFAULT,
                             H5P_DEFAULT, H5P_DEFAULT);
  ASSERT_GE(H5Dwrite(p, memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, points), 0);
  ASSERT_GE(H5Dwrite(o, H5T_NATIVE_UINT64, H5S_ALL, H5S_ALL, H5P_DEFAULT, offsets), 0);
  if (attributes) attributes(file);
  H5Dclose(p), H5Dclose(o), H5Sclose(space), H5Sclose(line_space), H5Fclose(file);
}

// A root attribute of `count` values of `file_type` (given in `memory_type`).
void numeric_attribute(hid_t file, const char* name, hid_t file_type, hid_t memory_type,
                       const void* values, hsize_t count) {
  const hid_t space = H5Screate_simple(1, &count, nullptr);
  const hid_t a = H5Acreate2(file, name, file_type, space, H5P_DEFAULT, H5P_DEFAULT);
  ASSERT_GE(H5Awrite(a, memory_type, values), 0);
  H5Aclose(a), H5Sclose(space);
}

}  // namespace

// An HDF5 line file from another tool with float64 points (h5py's default for Python floats), or
// integers (millimetres in int64): read at an origin, its coordinates are moved in double, not
// rounded to float32 first.
TEST(Origin, WideHdfPointsAreMovedBeforeFloat32) {
  TempDir dir;
  const double points[] = {6378137.01, 1.5, -20.25, 6378137.02, 2.5, -20.5, 6378137.03, 3.5, -21};
  write_foreign_h5(dir.file("f64.h5"), H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, points, 3);
  const Origin origin{6378137, 0, -20};
  const LineSet local = read_line_set(dir.file("f64.h5"), at(origin));
  ASSERT_EQ(local.positions.size(), 9u);
  for (size_t i = 0; i < 9; ++i) EXPECT_EQ(local.positions[i], float(points[i] - origin[i % 3]));
  // Without it the three x (1 cm apart at 6.4e6) are one float32 value.
  const LineSet plain = read_line_set(dir.file("f64.h5"));
  EXPECT_EQ(plain.positions[0], plain.positions[6]);
  EXPECT_NE(local.positions[0], local.positions[6]);

  // Millimetres: 500,000,123 mm and its neighbours, one float32 value (steps of 32 there).
  const int64_t mm[] = {500000123, 5400000123, 7,          500000124, 5400000125,
                        8,         500000127,  5400000126, 9};
  write_foreign_h5(dir.file("mm.h5"), H5T_STD_I64LE, H5T_NATIVE_INT64, mm, 3);
  const Origin mm_origin{500000000, 5400000000, 0};
  const LineSet mm_local = read_line_set(dir.file("mm.h5"), at(mm_origin));
  ASSERT_EQ(mm_local.positions.size(), 9u);
  for (size_t i = 0; i < 9; ++i)
    EXPECT_EQ(mm_local.positions[i], float(double(mm[i]) - mm_origin[i % 3])) << i;
  const LineSet mm_plain = read_line_set(dir.file("mm.h5"));
  EXPECT_EQ(mm_plain.positions[0], mm_plain.positions[6]);
}

// A root attribute `origin` is the points' frame only as linebake writes one (three floating-point
// numbers); another tool's (text, integers, another count) is kept as "source_origin" and moves
// nothing.
TEST(Origin, AnHdfRootOriginIsAFrameOnlyAsThreeFloats) {
  TempDir dir;
  const float points[] = {1, 2, 3, 4, 5, 6};
  const double frame[] = {10.5, 20, 30};
  write_foreign_h5(dir.file("frame.h5"), H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, points, 2,
                   [&](hid_t file) {
                     numeric_attribute(file, "origin", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, frame, 3);
                   });
  const LineSet framed = read_line_set(dir.file("frame.h5"));
  EXPECT_EQ(framed.metadata.at("origin"), "10.5 20 30");
  EXPECT_FALSE(framed.metadata.contains("source_origin"));
  const int64_t corner[] = {10, 20, 30};
  const double two[] = {1, 2};
  const std::vector<std::pair<std::string, std::function<void(hid_t)>>> foreign = {
      {"10 20 30",
       [&](hid_t file) {
         numeric_attribute(file, "origin", H5T_STD_I64LE, H5T_NATIVE_INT64, corner, 3);
       }},
      {"1 2",
       [&](hid_t file) {
         numeric_attribute(file, "origin", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, two, 2);
       }},
      {"lower-left", [&](hid_t file) {
         const hid_t type = H5Tcopy(H5T_C_S1);
         H5Tset_size(type, 10);
         const hid_t space = H5Screate(H5S_SCALAR);
         const hid_t a = H5Acreate2(file, "origin", type, space, H5P_DEFAULT, H5P_DEFAULT);
         ASSERT_GE(H5Awrite(a, type, "lower-left"), 0);
         H5Aclose(a), H5Sclose(space), H5Tclose(type);
       }}};
  for (const auto& [text, add] : foreign) {
    write_foreign_h5(dir.file("foreign.h5"), H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, points, 2, add);
    const LineSet back = read_line_set(dir.file("foreign.h5"));
    EXPECT_FALSE(has_origin(back)) << text;
    EXPECT_EQ(back.metadata.at("source_origin"), text);
    EXPECT_EQ(back.positions, std::vector<float>(points, points + 6)) << text;
    // Written again, it is metadata like any other: no frame either.
    write_line_set(back, dir.file("again.h5"));
    EXPECT_FALSE(has_origin(read_line_set(dir.file("again.h5")))) << text;
  }
}

// MRtrix's Float64 data is read in double: at an origin it keeps what float32 would round away.
TEST(Origin, Float64TckPointsAreMovedBeforeFloat32) {
  TempDir dir;
  const double points[] = {500000.125, 5400000.125, 10.5, 500000.375, 5400000.625, 11.25};
  const double nan = std::nan(""), inf = HUGE_VAL;
  std::string header = "mrtrix tracks\ndatatype: Float64LE\ncount: 1\nfile: . 64\nEND\n";
  header.resize(64, '\0');
  std::string data = header;
  const auto put = [&](double v) { data.append(reinterpret_cast<const char*>(&v), 8); };
  for (double v : points) put(v);
  for (double v : {nan, nan, nan, inf, inf, inf}) put(v);
  test::write_text(dir.file("f64.tck"), data);
  const LineSet local = read_line_set(dir.file("f64.tck"), at(kOrigin));
  ASSERT_EQ(local.positions.size(), 6u);
  for (size_t i = 0; i < 6; ++i) EXPECT_EQ(local.positions[i], float(points[i] - kOrigin[i % 3]));
  EXPECT_EQ(local.metadata.at("origin"), "500000 5400000 0");
  // Without it both northings round to float32's steps of 0.5 there.
  const LineSet plain = read_line_set(dir.file("f64.tck"));
  EXPECT_EQ(plain.positions[1], 5400000.0f);
  EXPECT_EQ(plain.positions[4], 5400000.5f);
}

// A coordinate beyond float32's range from the origin is refused as it is without one (the text
// and VTK readers), not read as an infinite, invalid point.
TEST(Origin, CoordinatesBeyondFloat32FromTheOriginAreRefused) {
  TempDir dir;
  // x of 1e38 and 2e38 locally, at 1.1e39 and 1.2e39 in the world (past float32's 3.4e38): read
  // back at that origin, exact (float32's steps there are 1e31, double's error 1e23).
  LineSet lines = one_line({{1e38f, 2, 3}, {2e38f, 5, 6}});
  set_origin(lines, {1e39, 0, 0});
  WriteOptions ascii;
  ascii.ascii = true;
  WriteOptions vtp_ascii;
  vtp_ascii.vtp_encoding = "ascii";
  const std::vector<std::pair<std::string, WriteOptions>> files = {
      {"a.csv", {}},    {"a.obj", {}}, {"a.vtk", {}},
      {"b.vtk", ascii}, {"a.vtp", {}}, {"b.vtp", vtp_ascii}};
  for (const auto& [name, options] : files) {
    write_line_set(lines, dir.file(name), options);
    EXPECT_THROW(read_line_set(dir.file(name)), InputError) << name;
    EXPECT_THROW(read_line_set(dir.file(name), at({0, 0, 0})), InputError) << name;
    EXPECT_EQ(read_line_set(dir.file(name), at({1e39, 0, 0})).positions, lines.positions) << name;
  }
}

TEST(Origin, SameDataComparesTheFrame) {
  LineSet a = one_line({{1, 2, 3}, {4, 5, 6}});
  LineSet b = a;
  EXPECT_TRUE(a.same_data(b));
  set_origin(b, {0, 0, 0});
  EXPECT_TRUE(a.same_data(b));  // none is (0, 0, 0)
  set_origin(b, {500000, 0, 0});
  EXPECT_FALSE(a.same_data(b));
  set_origin(a, {500000, 0, 0});
  EXPECT_TRUE(a.same_data(b));
}
