// Hand-built files in the layouts other tools write, checked against hand-written expectations.

#include <gtest/gtest.h>
#include <hdf5.h>

#include <bit>
#include <cstring>
#include <limits>

#include "core/error.hpp"
#include "formats/registry.hpp"
#include "test_util.hpp"

using namespace linebake;
using linebake::test::TempDir;
using linebake::test::write_bytes;
using linebake::test::write_text;

namespace {

using linebake::test::Bytes;

std::vector<unsigned char> trk_file(bool big) {
  Bytes b(big);
  b.text("TRACK", 6);
  b.put<int16_t>(10).put<int16_t>(20).put<int16_t>(30);
  b.put<float>(1.5f).put<float>(1.5f).put<float>(2.0f);
  b.put<float>(0).put<float>(0).put<float>(0);
  b.put<int16_t>(1);  // n_scalars
  b.text("fa", 20);
  for (int i = 1; i < 10; ++i) b.text("", 20);
  b.put<int16_t>(1);  // n_properties
  b.text("length", 20);
  for (int i = 1; i < 10; ++i) b.text("", 20);
  for (int i = 0; i < 16; ++i) b.put<float>(i % 5 == 0 ? 1.0f : 0.0f);  // identity vox_to_ras
  b.text("", 444).text("LPS", 4).text("", 4);
  for (int i = 0; i < 6; ++i) b.put<float>(0);
  b.text("", 2).text("", 6);
  b.put<int32_t>(2).put<int32_t>(2).put<int32_t>(1000);
  EXPECT_EQ(b.data.size(), 1000u);
  // Streamline 0: 2 points; streamline 1: 3 points.
  b.put<int32_t>(2);
  b.put<float>(1).put<float>(2).put<float>(3).put<float>(0.5f);
  b.put<float>(4).put<float>(5).put<float>(6).put<float>(0.25f);
  b.put<float>(7.5f);
  b.put<int32_t>(3);
  for (float i : {0.0f, 1.0f, 2.0f})
    b.put<float>(-i).put<float>(0).put<float>(1).put<float>(0.1f * i);
  b.put<float>(9.0f);
  return b.data;
}

std::vector<unsigned char> tck_file(bool big, bool doubles, bool finished = true) {
  const std::string type = std::string(doubles ? "Float64" : "Float32") + (big ? "BE" : "LE");
  std::string header = "mrtrix tracks\ndatatype: " + type + "\ncount: 2\nfile: . 64\nEND\n";
  header.resize(64, ' ');
  Bytes b(big);
  b.data.assign(header.begin(), header.end());
  auto put = [&](double x, double y, double z) {
    for (double v : {x, y, z})
      doubles ? (void)b.put<double>(v) : (void)b.put<float>(static_cast<float>(v));
  };
  put(0, 0, 0);
  put(1, 0.5, -2);
  put(NAN, NAN, NAN);
  put(3, 3, 3);
  put(4, 4, 4);
  put(5, 5, 5);
  put(NAN, NAN, NAN);
  if (finished) put(INFINITY, INFINITY, INFINITY);
  return b.data;
}

}  // namespace

TEST(Trk, BothByteOrders) {
  TempDir dir;
  for (bool big : {false, true}) {
    const std::string path = dir.file(big ? "big.trk" : "little.trk");
    write_bytes(path, trk_file(big));
    const LineSet l = read_line_set(path);
    EXPECT_EQ(l.line_offsets, (std::vector<uint64_t>{0, 2, 5}));
    EXPECT_EQ(l.positions, (std::vector<float>{1, 2, 3, 4, 5, 6, 0, 0, 1, -1, 0, 1, -2, 0, 1}));
    ASSERT_EQ(l.attributes.size(), 1u);
    EXPECT_EQ(l.attributes[0].name, "fa");
    EXPECT_EQ(l.attributes[0].values, (std::vector<float>{0.5f, 0.25f, 0.0f, 0.1f, 0.2f}));
    ASSERT_EQ(l.line_attributes.size(), 1u);
    EXPECT_EQ(l.line_attributes[0].name, "length");
    EXPECT_EQ(l.line_attributes[0].values, (std::vector<float>{7.5f, 9.0f}));
    EXPECT_EQ(l.metadata.at("trk.voxel_order"), "LPS");
  }
}

TEST(Trk, Malformed) {
  TempDir dir;
  auto bytes = trk_file(false);
  bytes[996] = 7;  // hdr_size no longer 1000 in either order
  write_bytes(dir.file("a.trk"), bytes);
  EXPECT_THROW(
      {
        try {
          read_line_set(dir.file("a.trk"));
        } catch (const InputError& e) {
          EXPECT_NE(std::string(e.what()).find("byte offset 996"), std::string::npos) << e.what();
          throw;
        }
      },
      InputError);
  bytes = trk_file(false);
  bytes.resize(bytes.size() - 6);
  write_bytes(dir.file("b.trk"), bytes);
  EXPECT_THROW(read_line_set(dir.file("b.trk")), InputError);
  write_bytes(dir.file("c.trk"), std::vector<unsigned char>(100, 0));
  EXPECT_THROW(read_line_set(dir.file("c.trk")), InputError);
}

TEST(Tck, AllDatatypes) {
  TempDir dir;
  for (bool big : {false, true})
    for (bool doubles : {false, true}) {
      const std::string path = dir.file(std::to_string(big) + std::to_string(doubles) + ".tck");
      write_bytes(path, tck_file(big, doubles));
      const LineSet l = read_line_set(path);
      EXPECT_EQ(l.line_offsets, (std::vector<uint64_t>{0, 2, 5}));
      EXPECT_EQ(l.positions, (std::vector<float>{0, 0, 0, 1, 0.5f, -2, 3, 3, 3, 4, 4, 4, 5, 5, 5}));
      EXPECT_EQ(l.metadata.at("tck.count"), "2");
    }
}

TEST(Tck, Malformed) {
  TempDir dir;
  write_bytes(dir.file("a.tck"), tck_file(false, false, /*finished=*/false));
  EXPECT_THROW(read_line_set(dir.file("a.tck")), InputError);
  write_text(dir.file("b.tck"), "mrtrix tracks\ndatatype: Int16LE\nfile: . 40\nEND\n");
  EXPECT_THROW(read_line_set(dir.file("b.tck")), InputError);
  write_text(dir.file("c.tck"), "mrtrix image\n");
  EXPECT_THROW(read_line_set(dir.file("c.tck")), InputError);
  auto bytes = tck_file(false, false);
  const std::string count = "count: 2";
  const auto at = std::search(bytes.begin(), bytes.end(), count.begin(), count.end());
  ASSERT_NE(at, bytes.end());
  *(at + 7) = '7';  // the header now disagrees with the data
  write_bytes(dir.file("d.tck"), bytes);
  EXPECT_THROW(read_line_set(dir.file("d.tck")), InputError);
}

TEST(VtkLegacy, Ascii51LayoutFieldVectorsAndCellData) {
  TempDir dir;
  // Lines index shared points out of order; one VERTICES cell shifts the cell data.
  write_text(dir.file("a.vtk"),
             "# vtk DataFile Version 5.1\nstreamlines\nASCII\nDATASET POLYDATA\n"
             "POINTS 4 double\n0 0 0  1 0 0  2 0 0  3 1 0\n"
             "VERTICES 2 1\nOFFSETS vtktypeint64\n0 1\nCONNECTIVITY vtktypeint64\n0\n"
             "LINES 3 5\nOFFSETS vtktypeint64\n0 3 5\nCONNECTIVITY vtktypeint64\n3 2 1 0 1\n"
             "POINT_DATA 4\nSCALARS speed%20m/s float 1\nLOOKUP_TABLE default\n0.5 1.5 2.5 3.5\n"
             "VECTORS v float\n1 2 3 4 5 6 7 8 9 10 11 12\n"
             "FIELD FieldData 1\nid 1 4 int\n10 11 12 13\n"
             "CELL_DATA 3\nSCALARS group int 1\nLOOKUP_TABLE default\n99 7 8\n");
  const LineSet l = read_line_set(dir.file("a.vtk"));
  EXPECT_EQ(l.line_offsets, (std::vector<uint64_t>{0, 3, 5}));
  EXPECT_EQ(l.positions, (std::vector<float>{3, 1, 0, 2, 0, 0, 1, 0, 0, 0, 0, 0, 1, 0, 0}));
  ASSERT_EQ(l.attributes.size(), 5u);
  EXPECT_EQ(l.attributes[0].name, "speed m/s");
  EXPECT_EQ(l.attributes[0].values, (std::vector<float>{3.5f, 2.5f, 1.5f, 0.5f, 1.5f}));
  EXPECT_EQ(l.attributes[1].name, "v_x");
  EXPECT_EQ(l.attributes[3].values, (std::vector<float>{12, 9, 6, 3, 6}));
  EXPECT_EQ(l.attributes[4].name, "id");
  EXPECT_EQ(l.attributes[4].values, (std::vector<float>{13, 12, 11, 10, 11}));
  ASSERT_EQ(l.line_attributes.size(), 1u);
  EXPECT_EQ(l.line_attributes[0].values, (std::vector<float>{7, 8}));
}

TEST(VtkLegacy, BigEndianBinaryClassic) {
  TempDir dir;
  Bytes b(/*big=*/true);
  const std::string head =
      "# vtk DataFile Version 3.0\nx\nBINARY\nDATASET POLYDATA\nPOINTS 3 float\n";
  b.data.assign(head.begin(), head.end());
  for (float v : {0.f, 1.f, 2.f, 3.f, 4.f, 5.f, 6.f, 7.f, 8.f}) b.put(v);
  const std::string lines = "\nLINES 1 4\n";
  b.data.insert(b.data.end(), lines.begin(), lines.end());
  for (int32_t v : {3, 0, 1, 2}) b.put(v);
  const std::string pd = "\nPOINT_DATA 3\nSCALARS s double\nLOOKUP_TABLE default\n";
  b.data.insert(b.data.end(), pd.begin(), pd.end());
  for (double v : {0.25, -1.0, 1e30}) b.put(v);
  b.data.push_back('\n');
  write_bytes(dir.file("a.vtk"), b.data);
  const LineSet l = read_line_set(dir.file("a.vtk"));
  EXPECT_EQ(l.positions, (std::vector<float>{0, 1, 2, 3, 4, 5, 6, 7, 8}));
  EXPECT_EQ(l.line_offsets, (std::vector<uint64_t>{0, 3}));
  EXPECT_EQ(l.attributes[0].values, (std::vector<float>{0.25f, -1.0f, 1e30f}));
}

TEST(Vtp, AsciiAsParaViewWritesIt) {
  TempDir dir;
  write_text(dir.file("a.vtp"), R"(<?xml version="1.0"?>
<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian" header_type="UInt64">
  <PolyData>
    <Piece NumberOfPoints="3" NumberOfVerts="0" NumberOfLines="1" NumberOfStrips="0" NumberOfPolys="0">
      <PointData Scalars="temp">
        <DataArray type="Float64" Name="temp" format="ascii" RangeMin="1" RangeMax="3">1 2 3</DataArray>
      </PointData>
      <CellData>
        <DataArray type="Int32" Name="SeedIds" format="ascii">4</DataArray>
      </CellData>
      <Points>
        <DataArray type="Float32" Name="Points" NumberOfComponents="3" format="ascii">
          0 0 0 1 0 0 1 1 0
        </DataArray>
      </Points>
      <Lines>
        <DataArray type="Int64" Name="connectivity" format="ascii">2 1 0</DataArray>
        <DataArray type="Int64" Name="offsets" format="ascii">3</DataArray>
      </Lines>
    </Piece>
  </PolyData>
</VTKFile>
)");
  const LineSet l = read_line_set(dir.file("a.vtp"));
  EXPECT_EQ(l.positions, (std::vector<float>{1, 1, 0, 1, 0, 0, 0, 0, 0}));
  EXPECT_EQ(l.attributes[0].values, (std::vector<float>{3, 2, 1}));
  EXPECT_EQ(l.line_attributes[0].name, "SeedIds");
  EXPECT_EQ(l.line_attributes[0].values, (std::vector<float>{4}));
}

// A line file as h5py writes one: float64 points (N x 3) and /line_lengths of `length_type`
// (an HDF5 file type, written from `lengths` in the matching native type).
template <class Length>
void write_points_and_lengths(const std::string& path, const std::vector<double>& points,
                              hid_t length_type, hid_t native, const std::vector<Length>& lengths) {
  hid_t f = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  hsize_t dims[2] = {points.size() / 3, 3};
  hid_t s = H5Screate_simple(2, dims, nullptr);
  hid_t d = H5Dcreate2(f, "points", H5T_IEEE_F64LE, s, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  H5Dwrite(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, points.data());
  H5Dclose(d);
  H5Sclose(s);
  hsize_t n = lengths.size();
  s = H5Screate_simple(1, &n, nullptr);
  d = H5Dcreate2(f, "line_lengths", length_type, s, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  H5Dwrite(d, native, H5S_ALL, H5S_ALL, H5P_DEFAULT, lengths.data());
  H5Dclose(d);
  H5Sclose(s);
  H5Fclose(f);
}

using linebake::test::read_error;

TEST(Hdf5, DoublePointsAndLineLengthsAsH5pyWrites) {
  TempDir dir;
  const std::string path = dir.file("a.h5");
  write_points_and_lengths(path, {0, 0, 0, 1, 1, 1, 2, 2, 2, 3.5, 0, 0}, H5T_STD_I32LE,
                           H5T_NATIVE_INT32, std::vector<int32_t>{3, 1});
  const LineSet l = read_line_set(path);
  EXPECT_EQ(l.line_offsets, (std::vector<uint64_t>{0, 3, 4}));
  EXPECT_EQ(l.positions[9], 3.5f);
}

// Lengths whose running sum wraps past 2^64 had made offsets that go back (a line of 2^64 - 1
// points over a set of 5, which Python's views and the writers then read outside their arrays):
// each length is held to the points left.
TEST(Hdf5, LineLengthsPastThePointsAreRefusedWhereverTheSumWraps) {
  TempDir dir;
  const std::vector<double> points(15, 0.5);
  const uint64_t most = UINT64_MAX;
  write_points_and_lengths(dir.file("a.h5"), points, H5T_STD_U64LE, H5T_NATIVE_UINT64,
                           std::vector<uint64_t>{most, 6});
  EXPECT_NE(read_error(dir.file("a.h5"))
                .find("dataset /line_lengths: lengths up to index 0 sum past the point count 5"),
            std::string::npos)
      << read_error(dir.file("a.h5"));
  // 3 + (2^64 - 2) + 4 wraps to the point count, 5.
  write_points_and_lengths(dir.file("b.h5"), points, H5T_STD_U64LE, H5T_NATIVE_UINT64,
                           std::vector<uint64_t>{3, most - 1, 4});
  EXPECT_NE(read_error(dir.file("b.h5")).find("lengths up to index 1 sum past the point count 5"),
            std::string::npos)
      << read_error(dir.file("b.h5"));
  write_points_and_lengths(dir.file("c.h5"), points, H5T_STD_U64LE, H5T_NATIVE_UINT64,
                           std::vector<uint64_t>{3, 2});
  EXPECT_EQ(read_line_set(dir.file("c.h5")).line_offsets, (std::vector<uint64_t>{0, 3, 5}));
}

// A float64 coordinate past float32's range is refused, as the VTK, VTP and CSV readers refuse
// it (HDF5's own conversion had made it an infinity), and so is one that an origin moves past
// it; the largest float32 itself reads.
TEST(Hdf5, DoublePointsPastFloat32AreRefusedNamingTheRow) {
  TempDir dir;
  write_points_and_lengths(dir.file("a.h5"), {0, 0, 0, 2, 0, 0, 0, -1e39, 0}, H5T_STD_U8LE,
                           H5T_NATIVE_UINT8, std::vector<uint8_t>{3});
  EXPECT_NE(read_error(dir.file("a.h5"))
                .find("dataset /points: row 2: a coordinate outside float32's range (magnitude"),
            std::string::npos)
      << read_error(dir.file("a.h5"));
  const double largest = std::numeric_limits<float>::max();
  write_points_and_lengths(dir.file("b.h5"), {0, 0, 0, largest, 0, -largest}, H5T_STD_U8LE,
                           H5T_NATIVE_UINT8, std::vector<uint8_t>{2});
  const LineSet b = read_line_set(dir.file("b.h5"));
  EXPECT_EQ(b.positions[3], std::numeric_limits<float>::max());
  EXPECT_EQ(b.positions[5], -std::numeric_limits<float>::max());
  ReadOptions far;
  far.origin = Origin{-largest, 0, 0};  // moves x = largest to twice float32's range
  try {
    read_line_set(dir.file("b.h5"), far);
    ADD_FAILURE() << "read";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("row 1: a coordinate outside float32's range from the "
                                         "origin"),
              std::string::npos)
        << e.what();
  }
}

TEST(Hdf5, BadOffsetsNameTheDataset) {
  TempDir dir;
  LineSet l = linebake::test::awkward_lines(false);
  l.line_offsets.back() += 1;  // points past the end
  write_line_set(l, dir.file("a.h5"));
  try {
    read_line_set(dir.file("a.h5"));
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("dataset /line_offsets"), std::string::npos) << e.what();
  }
}
