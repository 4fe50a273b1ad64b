// Lines far from 0 kept relative to a local origin (lines/origin.hpp): read in double and moved
// before float32, held so by every format that can, and put back where a file holds world
// coordinates.

#include <gtest/gtest.h>

#include <cmath>

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
  for (const char* bad :
       {"", "1,2", "1,2,3,4", "1,,2,3", "1-2 3", "nan,0,0", "inf 0 0", "a,b,c", "1e999,0,0"})
    EXPECT_FALSE(parse_origin(bad)) << bad;
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
  LineSet lines;
  lines.append_point(1, 2, 3);
  lines.append_point(4, 5, 6);
  lines.end_line();
  write_line_set(lines, dir.file("a.vtp"));
  std::string text = test::read_text(dir.file("a.vtp"));
  const std::string field =
      "<FieldData>\n<Array type=\"String\" Name=\"origin\" NumberOfTuples=\"1\" "
      "format=\"ascii\">\n49 32 50 32 51 0\n</Array>\n</FieldData>\n";
  text.insert(text.find("<Piece"), field);
  test::write_text(dir.file("b.vtp"), text);
  const LineSet back = read_line_set(dir.file("b.vtp"));
  EXPECT_FALSE(has_origin(back));
  EXPECT_EQ(back.positions, lines.positions);
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

// An HDF5 line file from another tool with float64 points (h5py's default for Python floats):
// read at an origin, its coordinates are moved in double, not rounded to float32 first.
TEST(Origin, Float64HdfPointsAreMovedBeforeFloat32) {
  TempDir dir;
  const std::string path = dir.file("f64.h5");
  const double points[] = {6378137.01, 1.5, -20.25, 6378137.02, 2.5, -20.5, 6378137.03, 3.5, -21};
  const uint64_t offsets[] = {0, 3};
  const hid_t file = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  const hsize_t dims[2] = {3, 3}, two = 2;
  const hid_t space = H5Screate_simple(2, dims, nullptr),
              line_space = H5Screate_simple(1, &two, nullptr);
  const hid_t p =
      H5Dcreate2(file, "points", H5T_IEEE_F64LE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  const hid_t o = H5Dcreate2(file, "line_offsets", H5T_STD_U64LE, line_space, H5P_DEFAULT,
                             H5P_DEFAULT, H5P_DEFAULT);
  ASSERT_GE(H5Dwrite(p, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, points), 0);
  ASSERT_GE(H5Dwrite(o, H5T_NATIVE_UINT64, H5S_ALL, H5S_ALL, H5P_DEFAULT, offsets), 0);
  H5Dclose(p), H5Dclose(o), H5Sclose(space), H5Sclose(line_space), H5Fclose(file);
  const Origin origin{6378137, 0, -20};
  const LineSet local = read_line_set(path, at(origin));
  ASSERT_EQ(local.positions.size(), 9u);
  for (size_t i = 0; i < 9; ++i) EXPECT_EQ(local.positions[i], float(points[i] - origin[i % 3]));
  // Without it the three x (1 cm apart at 6.4e6) are one float32 value.
  const LineSet plain = read_line_set(path);
  EXPECT_EQ(plain.positions[0], plain.positions[6]);
  EXPECT_NE(local.positions[0], local.positions[6]);
}
