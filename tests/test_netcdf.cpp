// NetCDF trajectories in the three layouts, written with the netCDF C library.

#include <gtest/gtest.h>
#include <netcdf.h>

#include <cmath>
#include <optional>

#include "core/error.hpp"
#include "formats/registry.hpp"
#include "pipeline/bake.hpp"
#include "test_util.hpp"

using namespace linebake;
using linebake::test::TempDir;

namespace {
void ok(int status) {
  ASSERT_EQ(status, NC_NOERR) << nc_strerror(status);
}
}  // namespace

TEST(NetCdf, LagrantoStyleInvalidValuesEndLines) {
  TempDir dir;
  const std::string path = dir.file("lagranto.nc");
  int nc, d[3], lon, lat, p, t;
  ok(nc_create(path.c_str(), NC_CLOBBER, &nc));
  ok(nc_def_dim(nc, "ensemble", 1, &d[0]));
  ok(nc_def_dim(nc, "trajectory", 2, &d[1]));
  ok(nc_def_dim(nc, "time", 3, &d[2]));
  ok(nc_def_var(nc, "lon", NC_FLOAT, 3, d, &lon));
  ok(nc_def_var(nc, "lat", NC_FLOAT, 3, d, &lat));
  ok(nc_def_var(nc, "pressure", NC_FLOAT, 3, d, &p));
  ok(nc_def_var(nc, "T", NC_FLOAT, 3, d, &t));
  const float fill = -999.0f;
  ok(nc_put_att_float(nc, lon, "_FillValue", NC_FLOAT, 1, &fill));
  ok(nc_enddef(nc));
  const float lons[] = {10, 11, 12, 20, -999, 22};  // a gap: line 1 is two lines of a point
  const float lats[] = {45, 46, 47, 50, 51, 52};
  const float ps[] = {900, 850, 800, 700, 650, 600};
  const float ts[] = {280, 279, 278, 260, 259, 258};
  ok(nc_put_var_float(nc, lon, lons));
  ok(nc_put_var_float(nc, lat, lats));
  ok(nc_put_var_float(nc, p, ps));
  ok(nc_put_var_float(nc, t, ts));
  ok(nc_close(nc));

  const LineSet l = read_line_set(path);
  EXPECT_EQ(l.line_offsets, (std::vector<uint64_t>{0, 3, 4, 5}));
  EXPECT_EQ(l.positions,
            (std::vector<float>{10, 45, 900, 11, 46, 850, 12, 47, 800, 20, 50, 700, 22, 52, 600}));
  ASSERT_EQ(l.attributes.size(), 1u);
  EXPECT_EQ(l.attributes[0].name, "T");
  EXPECT_EQ(l.attributes[0].values, (std::vector<float>{280, 279, 278, 260, 258}));
  EXPECT_EQ(l.metadata.at("netcdf.layout"), "lagranto");
  // What the split is, counted: one observation missing, one trajectory split into one line more.
  EXPECT_EQ(l.metadata.at("netcdf.missing_observations"), "1");
  EXPECT_EQ(l.metadata.at("netcdf.split_trajectories"), "1");
  EXPECT_EQ(l.metadata.at("netcdf.lines_from_splits"), "1");
  EXPECT_EQ(l.metadata.count("netcdf.trajectories_without_position"), 0u);
}

namespace {
// A Lagranto-style file of `trajectories` rows of `times` longitudes (latitude 1 where the
// longitude is given; -999 is the fill value).
std::string lagranto_file(const TempDir& dir, const std::string& name, int trajectories, int times,
                          const std::vector<float>& lons) {
  const std::string path = dir.file(name);
  int nc, d[2], lon, lat;
  EXPECT_EQ(nc_create(path.c_str(), NC_CLOBBER, &nc), NC_NOERR);
  nc_def_dim(nc, "trajectory", size_t(trajectories), &d[0]);
  nc_def_dim(nc, "time", size_t(times), &d[1]);
  nc_def_var(nc, "lon", NC_FLOAT, 2, d, &lon);
  nc_def_var(nc, "lat", NC_FLOAT, 2, d, &lat);
  const float fill = -999.0f;
  nc_put_att_float(nc, lon, "_FillValue", NC_FLOAT, 1, &fill);
  nc_enddef(nc);
  const std::vector<float> lats(lons.size(), 1.0f);
  nc_put_var_float(nc, lon, lons.data());
  nc_put_var_float(nc, lat, lats.data());
  EXPECT_EQ(nc_close(nc), NC_NOERR);
  return path;
}
}  // namespace

// Counted by hand: trajectory 0 has two gaps (three lines: two more), 1 none, 2 no position; the
// second file's trajectory 0 one gap at its end (no split), 1 one gap (one line more). The counts
// add up over files, in read_line_set, in the streamed reader and in a bake's cache and notes.
TEST(NetCdf, SplitsAtGapsAreCountedInTheMetadata) {
  TempDir dir;
  const float x = -999.0f;
  const std::string a =
      lagranto_file(dir, "a.nc", 3, 5, {1, x, 2, x, 3, 1, 2, 3, 4, 5, x, x, x, x, x});
  const std::string b = lagranto_file(dir, "b.nc", 2, 3, {1, 2, x, 1, x, 2});
  const LineSet one = read_line_set(a);
  EXPECT_EQ(one.line_count(), 4u);
  EXPECT_EQ(one.metadata.at("netcdf.missing_observations"), "7");
  EXPECT_EQ(one.metadata.at("netcdf.split_trajectories"), "1");
  EXPECT_EQ(one.metadata.at("netcdf.lines_from_splits"), "2");
  EXPECT_EQ(one.metadata.at("netcdf.trajectories_without_position"), "1");

  const std::unique_ptr<LineReader> both = open_line_reader(std::vector<std::string>{a, b});
  const LineSet read = read_all(*both);
  EXPECT_EQ(read.line_count(), 4u + 3u);
  EXPECT_EQ(read.metadata.at("netcdf.missing_observations"), "9");
  EXPECT_EQ(read.metadata.at("netcdf.split_trajectories"), "2");
  EXPECT_EQ(read.metadata.at("netcdf.lines_from_splits"), "3");
  EXPECT_EQ(read.metadata.at("netcdf.trajectories_without_position"), "1");
  EXPECT_EQ(counts_read_note(both->counts_read()),
            "2 trajectories split at missing positions (netcdf.split_trajectories), 3 lines more "
            "from those splits (netcdf.lines_from_splits), 1 trajectories without a position (no "
            "line) (netcdf.trajectories_without_position)");

  BakeOptions o = test::quiet_bake(dir, a, "a.lbc.h5");
  const BakeResult result = bake(o);
  const LineSet cached = read_line_set(dir.file("a.lbc.h5"));
  EXPECT_EQ(cached.metadata.at("netcdf.lines_from_splits"), "2");
  EXPECT_EQ(cached.metadata.at("netcdf.trajectories_without_position"), "1");
  bool noted = false;
  for (const std::string& note : result.notes)
    noted = noted || note.find("1 trajectories split at missing positions") != std::string::npos;
  EXPECT_TRUE(noted);
}

namespace {
// A double variable over `dims` that its `axis` attribute ("X", "Y", "Z") names a coordinate.
int axis_variable(int nc, const char* name, const int* dims, const char* axis) {
  int id = -1;
  ok(nc_def_var(nc, name, NC_DOUBLE, 2, dims, &id));
  ok(nc_put_att_text(nc, id, "axis", 1, axis));
  return id;
}
}  // namespace

TEST(NetCdf, CfMultidimensionalWithAxisAttributes) {
  TempDir dir;
  const std::string path = dir.file("cf.nc");
  int nc, d[2];
  ok(nc_create(path.c_str(), NC_CLOBBER | NC_NETCDF4, &nc));
  ok(nc_put_att_text(nc, NC_GLOBAL, "featureType", 10, "trajectory"));
  ok(nc_def_dim(nc, "trajectory", 2, &d[0]));
  ok(nc_def_dim(nc, "obs", 2, &d[1]));
  // Names that say nothing: the axis attributes decide (and the order in the file is z, x, y).
  const int c = axis_variable(nc, "c", d, "Z");
  const int a = axis_variable(nc, "a", d, "X");
  const int b = axis_variable(nc, "b", d, "Y");
  ok(nc_enddef(nc));
  const double xs[] = {1, 2, 3, NAN}, ys[] = {4, 5, 6, 7}, zs[] = {7, 8, 9, 10};
  ok(nc_put_var_double(nc, a, xs));
  ok(nc_put_var_double(nc, b, ys));
  ok(nc_put_var_double(nc, c, zs));
  ok(nc_close(nc));
  const LineSet l = read_line_set(path);
  EXPECT_EQ(l.line_offsets, (std::vector<uint64_t>{0, 2, 3}));
  EXPECT_EQ(l.positions, (std::vector<float>{1, 4, 7, 2, 5, 8, 3, 6, 9}));
  EXPECT_EQ(l.metadata.at("netcdf.layout"), "cf-multidimensional");
}

// fuzz_netcdf (CI's 10 s step, 2026-12-01): a classic header claiming 738,197,514 characters for
// featureType in a 612-byte file; libnetcdf opens it, and the reader copied the claim and trimmed
// it a character at a time (42 s under the sanitizers). An attribute longer than the file is
// refused, naming it.
TEST(NetCdf, ATextAttributeLongerThanTheFileIsRefused) {
  TempDir dir;
  const std::string path = dir.file("classic.nc");
  int nc, d[2];
  ok(nc_create(path.c_str(), NC_CLOBBER, &nc));
  ok(nc_put_att_text(nc, NC_GLOBAL, "featureType", 10, "trajectory"));
  ok(nc_def_dim(nc, "trajectory", 2, &d[0]));
  ok(nc_def_dim(nc, "obs", 2, &d[1]));
  const int x = axis_variable(nc, "x", d, "X");
  const int y = axis_variable(nc, "y", d, "Y");
  const int z = axis_variable(nc, "z", d, "Z");
  ok(nc_enddef(nc));
  const double xs[] = {1, 2, 3, 4}, ys[] = {4, 5, 6, 7}, zs[] = {7, 8, 9, 10};
  ok(nc_put_var_double(nc, x, xs));
  ok(nc_put_var_double(nc, y, ys));
  ok(nc_put_var_double(nc, z, zs));
  ok(nc_close(nc));
  ASSERT_EQ(read_line_set(path).point_count(), 4u);
  // The classic header (NetCDF's file format spec): the name, its padding, the type NC_CHAR (2),
  // the length (10), big-endian, then the characters. Say 100,000.
  std::string bytes = linebake::test::read_text(path);
  const std::string attribute =
      std::string("featureType\0", 12) + std::string("\0\0\0\x02\0\0\0\x0a", 8) + "trajectory";
  const size_t at = bytes.find(attribute);
  ASSERT_NE(at, std::string::npos);
  bytes.replace(at + 16, 4, std::string("\0\x01\x86\xa0", 4));
  linebake::test::write_text(path, bytes);
  for (const char* isolation : {"on", "off"}) {
    SCOPED_TRACE(isolation);
    setenv("LINEBAKE_ISOLATION", isolation, 1);
    try {
      (void)read_line_set(path);
      ADD_FAILURE() << "no error";
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), path);
      EXPECT_NE(std::string(e.what()).find("attribute featureType: 100000 characters claimed, "
                                           "more than the file's"),
                std::string::npos)
          << e.what();
    }
  }
  unsetenv("LINEBAKE_ISOLATION");
}

// Earth-centred coordinates (6.4e6 m) read at an origin: unpacked and moved in double, rounded
// once, so the centimetres float32 cannot hold at 6.4e6 (steps of 0.5 m) are kept.
TEST(NetCdf, PositionsAreMovedToTheOriginBeforeFloat32) {
  TempDir dir;
  const std::string path = dir.file("ecef.nc");
  int nc, d[2];
  ok(nc_create(path.c_str(), NC_CLOBBER | NC_NETCDF4, &nc));
  ok(nc_put_att_text(nc, NC_GLOBAL, "featureType", 10, "trajectory"));
  ok(nc_def_dim(nc, "trajectory", 1, &d[0]));
  ok(nc_def_dim(nc, "obs", 3, &d[1]));
  const int x = axis_variable(nc, "x", d, "X");
  const int y = axis_variable(nc, "y", d, "Y");
  const int z = axis_variable(nc, "z", d, "Z");
  ok(nc_enddef(nc));
  const double xs[] = {4198944.61, 4198944.62, 4198944.63}, ys[] = {174747.25, 174747.5, 174748},
               zs[] = {4781886.07, 4781886.08, 4781886.09};
  ok(nc_put_var_double(nc, x, xs));
  ok(nc_put_var_double(nc, y, ys));
  ok(nc_put_var_double(nc, z, zs));
  ok(nc_close(nc));
  ReadOptions options;
  options.origin = Origin{4198944, 174747, 4781886};
  const LineSet l = read_line_set(path, options);
  ASSERT_EQ(l.positions.size(), 9u);
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(l.positions[3 * i], float(xs[i] - 4198944));
    EXPECT_EQ(l.positions[3 * i + 1], float(ys[i] - 174747));
    EXPECT_EQ(l.positions[3 * i + 2], float(zs[i] - 4781886));
  }
  // Without it the three x differ by 1 cm and read as one float32 value.
  const LineSet plain = read_line_set(path);
  EXPECT_EQ(plain.positions[0], plain.positions[3]);
  EXPECT_NE(l.positions[0], l.positions[3]);
}

TEST(NetCdf, CfContiguousRagged) {
  TempDir dir;
  const std::string path = dir.file("ragged.nc");
  int nc, traj, obs, count, lon, lat, alt, speed;
  ok(nc_create(path.c_str(), NC_CLOBBER, &nc));
  ok(nc_put_att_text(nc, NC_GLOBAL, "featureType", 10, "trajectory"));
  ok(nc_def_dim(nc, "trajectory", 3, &traj));
  ok(nc_def_dim(nc, "obs", 6, &obs));
  ok(nc_def_var(nc, "rowSize", NC_INT, 1, &traj, &count));
  ok(nc_put_att_text(nc, count, "sample_dimension", 3, "obs"));
  ok(nc_def_var(nc, "lon", NC_FLOAT, 1, &obs, &lon));
  ok(nc_put_att_text(nc, lon, "standard_name", 9, "longitude"));
  ok(nc_def_var(nc, "lat", NC_FLOAT, 1, &obs, &lat));
  ok(nc_def_var(nc, "z", NC_FLOAT, 1, &obs, &alt));
  ok(nc_def_var(nc, "speed", NC_FLOAT, 1, &obs, &speed));
  ok(nc_enddef(nc));
  const int counts[] = {2, 3, 1};
  const float x[] = {0, 1, 2, 3, 4, 5}, y[] = {6, 7, 8, 9, 10, 11}, z[] = {0, 0, 1, 1, 1, 2},
              s[] = {.5f, .6f, .7f, .8f, .9f, 1};
  ok(nc_put_var_int(nc, count, counts));
  ok(nc_put_var_float(nc, lon, x));
  ok(nc_put_var_float(nc, lat, y));
  ok(nc_put_var_float(nc, alt, z));
  ok(nc_put_var_float(nc, speed, s));
  ok(nc_close(nc));
  const LineSet l = read_line_set(path);
  EXPECT_EQ(l.line_offsets, (std::vector<uint64_t>{0, 2, 5, 6}));
  EXPECT_EQ(l.positions[3 * 5], 5.0f);
  EXPECT_EQ(l.attributes[0].name, "speed");
  EXPECT_EQ(l.attributes[0].values, (std::vector<float>{.5f, .6f, .7f, .8f, .9f, 1}));
  EXPECT_EQ(l.metadata.at("netcdf.layout"), "cf-contiguous-ragged");
}

TEST(NetCdf, RaggedCountsPastTheDataAreAnError) {
  TempDir dir;
  const std::string path = dir.file("bad.nc");
  int nc, traj, obs, count, lon, lat;
  ok(nc_create(path.c_str(), NC_CLOBBER, &nc));
  ok(nc_def_dim(nc, "trajectory", 1, &traj));
  ok(nc_def_dim(nc, "obs", 2, &obs));
  ok(nc_def_var(nc, "n", NC_INT, 1, &traj, &count));
  ok(nc_put_att_text(nc, count, "sample_dimension", 3, "obs"));
  ok(nc_def_var(nc, "lon", NC_FLOAT, 1, &obs, &lon));
  ok(nc_def_var(nc, "lat", NC_FLOAT, 1, &obs, &lat));
  ok(nc_enddef(nc));
  const int counts[] = {5};
  ok(nc_put_var_int(nc, count, counts));
  ok(nc_close(nc));
  try {
    read_line_set(path);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("variable n, index 0"), std::string::npos) << e.what();
  }
  linebake::test::write_text(dir.file("text.nc"), "not netcdf");
  EXPECT_THROW(read_line_set(dir.file("text.nc")), InputError);
}

using linebake::test::read_error;

TEST(NetCdf, PackedVariablesAreUnpacked) {
  // CF 8.1: unpacked = packed * scale_factor + add_offset; _FillValue is in packed units.
  TempDir dir;
  const std::string path = dir.file("packed.nc");
  int nc, d[2], lon, lat, alt, t, id;
  ok(nc_create(path.c_str(), NC_CLOBBER, &nc));
  ok(nc_put_att_text(nc, NC_GLOBAL, "featureType", 10, "trajectory"));
  ok(nc_def_dim(nc, "trajectory", 2, &d[0]));
  ok(nc_def_dim(nc, "obs", 3, &d[1]));
  ok(nc_def_var(nc, "lon", NC_SHORT, 2, d, &lon));
  ok(nc_def_var(nc, "lat", NC_SHORT, 2, d, &lat));
  ok(nc_def_var(nc, "alt", NC_SHORT, 2, d, &alt));
  ok(nc_def_var(nc, "T", NC_SHORT, 2, d, &t));
  ok(nc_def_var(nc, "id", NC_INT, 2, d, &id));
  const float lon_scale = 0.5f;
  const double lat_scale = 0.25, lat_offset = 40, alt_offset = 1000, t_scale = 0.1, t_offset = 273;
  const short lon_fill = -2, t_fill = -1;
  ok(nc_put_att_float(nc, lon, "scale_factor", NC_FLOAT, 1, &lon_scale));
  // -2 is a valid longitude once unpacked (-1): the fill test must compare the packed value.
  ok(nc_put_att_short(nc, lon, "_FillValue", NC_SHORT, 1, &lon_fill));
  ok(nc_put_att_double(nc, lat, "scale_factor", NC_DOUBLE, 1, &lat_scale));
  ok(nc_put_att_double(nc, lat, "add_offset", NC_DOUBLE, 1, &lat_offset));
  ok(nc_put_att_double(nc, alt, "add_offset", NC_DOUBLE, 1, &alt_offset));  // no scale_factor
  ok(nc_put_att_double(nc, t, "scale_factor", NC_DOUBLE, 1, &t_scale));
  ok(nc_put_att_double(nc, t, "add_offset", NC_DOUBLE, 1, &t_offset));
  ok(nc_put_att_short(nc, t, "missing_value", NC_SHORT, 1, &t_fill));
  ok(nc_enddef(nc));
  const short lons[] = {20, 22, 24, 30, -2, 34};
  const short lats[] = {4, 8, 12, -4, -8, -12};
  const short alts[] = {0, 10, 20, 30, 40, 50};
  const short ts[] = {100, -1, 300, 400, 500, 600};
  const int ids[] = {7, 7, 7, 8, 8, 8};  // not packed: as stored
  ok(nc_put_var_short(nc, lon, lons));
  ok(nc_put_var_short(nc, lat, lats));
  ok(nc_put_var_short(nc, alt, alts));
  ok(nc_put_var_short(nc, t, ts));
  ok(nc_put_var_int(nc, id, ids));
  ok(nc_close(nc));

  const LineSet l = read_line_set(path);
  // The packed fill at trajectory 1's second point is a gap: its last point is a line of its own.
  EXPECT_EQ(l.line_offsets, (std::vector<uint64_t>{0, 3, 4, 5}));
  EXPECT_EQ(l.positions, (std::vector<float>{10, 41, 1000, 11, 42, 1010, 12, 43, 1020, 15, 39, 1030,
                                             17, 37, 1050}));
  ASSERT_EQ(l.attributes.size(), 2u);
  EXPECT_EQ(l.attributes[0].name, "T");
  ASSERT_EQ(l.attributes[0].values.size(), 5u);
  EXPECT_FLOAT_EQ(l.attributes[0].values[0], 283.0f);
  EXPECT_TRUE(std::isnan(l.attributes[0].values[1]));  // missing_value, compared packed
  EXPECT_FLOAT_EQ(l.attributes[0].values[2], 303.0f);
  EXPECT_FLOAT_EQ(l.attributes[0].values[3], 313.0f);
  EXPECT_FLOAT_EQ(l.attributes[0].values[4], 333.0f);
  EXPECT_EQ(l.attributes[1].name, "id");
  EXPECT_EQ(l.attributes[1].values, (std::vector<float>{7, 7, 7, 8, 8}));
}

// CF 2.5.1: a value is missing when it is _FillValue, any of missing_value's values, or outside
// valid_range (or valid_min / valid_max); only the first of _FillValue and missing_value had
// counted, and the valid range not at all.
TEST(NetCdf, EveryMissingValueConventionCounts) {
  TempDir dir;
  const std::string path = dir.file("missing.nc");
  int nc, d[2], lon, lat, t, q;
  ok(nc_create(path.c_str(), NC_CLOBBER, &nc));
  ok(nc_put_att_text(nc, NC_GLOBAL, "featureType", 10, "trajectory"));
  ok(nc_def_dim(nc, "trajectory", 1, &d[0]));
  ok(nc_def_dim(nc, "obs", 8, &d[1]));
  ok(nc_def_var(nc, "lon", NC_FLOAT, 2, d, &lon));
  ok(nc_def_var(nc, "lat", NC_FLOAT, 2, d, &lat));
  ok(nc_def_var(nc, "T", NC_FLOAT, 2, d, &t));
  ok(nc_def_var(nc, "q", NC_FLOAT, 2, d, &q));  // not "p": a z name
  const float fill = -999, missing[] = {-888, -777}, range[] = {0, 100}, low = 10;
  ok(nc_put_att_float(nc, t, "_FillValue", NC_FLOAT, 1, &fill));
  ok(nc_put_att_float(nc, t, "missing_value", NC_FLOAT, 2, missing));
  ok(nc_put_att_float(nc, q, "valid_min", NC_FLOAT, 1, &low));
  ok(nc_put_att_float(nc, lon, "valid_range", NC_FLOAT, 2, range));
  ok(nc_enddef(nc));
  // The longitude leaves its valid range at obs 7: the line ends there.
  const float lons[] = {1, 2, 3, 4, 5, 6, 7, 101};
  const float lats[] = {0, 0, 0, 0, 0, 0, 0, 0};
  const float ts[] = {1, -999, -888, -777, 5, 6, 7, 8};
  const float qs[] = {50, 9, 50, 50, 50, 50, 50, 50};
  ok(nc_put_var_float(nc, lon, lons));
  ok(nc_put_var_float(nc, lat, lats));
  ok(nc_put_var_float(nc, t, ts));
  ok(nc_put_var_float(nc, q, qs));
  ok(nc_close(nc));

  const LineSet l = read_line_set(path);
  EXPECT_EQ(l.line_offsets, (std::vector<uint64_t>{0, 7}));
  ASSERT_EQ(l.attributes.size(), 2u);
  const std::vector<float>& temperature = l.attributes[0].values;
  ASSERT_EQ(temperature.size(), 7u);
  EXPECT_EQ(temperature[0], 1.0f);
  for (int i = 1; i <= 3; ++i) EXPECT_TRUE(std::isnan(temperature[i])) << i;
  EXPECT_EQ(temperature[4], 5.0f);
  EXPECT_TRUE(std::isnan(l.attributes[1].values[1]));  // below valid_min
  EXPECT_EQ(l.attributes[1].values[2], 50.0f);
}

// A count variable without a _FillValue has no missing value: a ubyte count of 255 is 255
// points (review finding: the type's default fill, 255, had been taken for "not written").
TEST(NetCdf, RaggedCountsOfTheTypesDefaultFillAreCounts) {
  TempDir dir;
  const std::string path = dir.file("ubyte.nc");
  int nc, traj, obs, row, lon, lat;
  ok(nc_create(path.c_str(), NC_CLOBBER | NC_NETCDF4, &nc));
  ok(nc_put_att_text(nc, NC_GLOBAL, "featureType", 10, "trajectory"));
  ok(nc_def_dim(nc, "trajectory", 2, &traj));
  ok(nc_def_dim(nc, "obs", 258, &obs));
  ok(nc_def_var(nc, "rowSize", NC_UBYTE, 1, &traj, &row));
  ok(nc_put_att_text(nc, row, "sample_dimension", 3, "obs"));
  ok(nc_def_var(nc, "lon", NC_FLOAT, 1, &obs, &lon));
  ok(nc_def_var(nc, "lat", NC_FLOAT, 1, &obs, &lat));
  ok(nc_enddef(nc));
  const unsigned char counts[] = {3, 255};
  std::vector<float> values(258);
  for (size_t i = 0; i < values.size(); ++i) values[i] = float(i);
  ok(nc_put_var_uchar(nc, row, counts));
  ok(nc_put_var_float(nc, lon, values.data()));
  ok(nc_put_var_float(nc, lat, values.data()));
  ok(nc_close(nc));
  const LineSet l = read_line_set(path);
  EXPECT_EQ(l.line_offsets, (std::vector<uint64_t>{0, 3, 258}));

  // An int count never written holds the int default fill, which cannot be a count: 0, as
  // netCDF4-python masks it (review finding: the fix above had refused such files).
  const std::string unwritten = dir.file("unwritten.nc");
  int nc2, traj2, obs2, row2, lon2, lat2;
  ok(nc_create(unwritten.c_str(), NC_CLOBBER, &nc2));
  ok(nc_put_att_text(nc2, NC_GLOBAL, "featureType", 10, "trajectory"));
  ok(nc_def_dim(nc2, "trajectory", 3, &traj2));
  ok(nc_def_dim(nc2, "obs", 6, &obs2));
  ok(nc_def_var(nc2, "rowSize", NC_INT, 1, &traj2, &row2));
  ok(nc_put_att_text(nc2, row2, "sample_dimension", 3, "obs"));
  ok(nc_def_var(nc2, "lon", NC_FLOAT, 1, &obs2, &lon2));
  ok(nc_def_var(nc2, "lat", NC_FLOAT, 1, &obs2, &lat2));
  ok(nc_enddef(nc2));
  const size_t first = 0, two = 2, three = 3;
  const int written[] = {2, 1};
  ok(nc_put_vara_int(nc2, row2, &first, &two, written));  // the third count never written
  const float xs[] = {0, 1, 2};
  ok(nc_put_vara_float(nc2, lon2, &first, &three, xs));
  ok(nc_put_vara_float(nc2, lat2, &first, &three, xs));
  ok(nc_close(nc2));
  const LineSet u = read_line_set(unwritten);
  EXPECT_EQ(u.line_offsets, (std::vector<uint64_t>{0, 2, 3}));  // the empty feature: no line
}

TEST(NetCdf, BadPackingAttributesAreAnError) {
  TempDir dir;
  auto write = [&](const std::string& name, auto&& add_attribute) {
    const std::string path = dir.file(name);
    int nc, d[2], lon, lat;
    ok(nc_create(path.c_str(), NC_CLOBBER, &nc));
    ok(nc_def_dim(nc, "trajectory", 1, &d[0]));
    ok(nc_def_dim(nc, "time", 2, &d[1]));
    ok(nc_def_var(nc, "lon", NC_SHORT, 2, d, &lon));
    ok(nc_def_var(nc, "lat", NC_SHORT, 2, d, &lat));
    add_attribute(nc, lat);
    ok(nc_enddef(nc));
    const short v[] = {1, 2};
    ok(nc_put_var_short(nc, lon, v));
    ok(nc_put_var_short(nc, lat, v));
    ok(nc_close(nc));
    return path;
  };
  const std::string text = write(
      "text.nc", [](int nc, int var) { ok(nc_put_att_text(nc, var, "scale_factor", 4, "0.01")); });
  // The error names the variable, the attribute and what is wrong with it.
  const auto expect_error = [](const std::string& path, std::initializer_list<const char*> parts) {
    const std::string error = read_error(path);
    for (const char* part : parts) EXPECT_NE(error.find(part), std::string::npos) << error;
  };
  expect_error(text, {"variable lat", "scale_factor", "not a number"});

  const std::string nan = write("nan.nc", [](int nc, int var) {
    const double offset = NAN;
    ok(nc_put_att_double(nc, var, "add_offset", NC_DOUBLE, 1, &offset));
  });
  expect_error(nan, {"variable lat", "add_offset", "finite"});

  const std::string infinite = write("inf.nc", [](int nc, int var) {
    const float scale = INFINITY;
    ok(nc_put_att_float(nc, var, "scale_factor", NC_FLOAT, 1, &scale));
  });
  expect_error(infinite, {"variable lat", "scale_factor", "finite"});
}

TEST(NetCdf, StringTypedAttributesInMultidimensionalFiles) {
  // h5netcdf/xarray write text attributes as NC_STRING; names that say nothing, so the
  // standard_name and featureType attributes have to be read.
  TempDir dir;
  const std::string path = dir.file("strings.nc");
  int nc, d[2], a, b, c;
  ok(nc_create(path.c_str(), NC_CLOBBER | NC_NETCDF4, &nc));
  const char* trajectory = "trajectory";
  ok(nc_put_att_string(nc, NC_GLOBAL, "featureType", 1, &trajectory));
  ok(nc_def_dim(nc, "trajectory", 1, &d[0]));
  ok(nc_def_dim(nc, "obs", 2, &d[1]));
  ok(nc_def_var(nc, "a", NC_FLOAT, 2, d, &a));
  ok(nc_def_var(nc, "b", NC_FLOAT, 2, d, &b));
  ok(nc_def_var(nc, "c", NC_FLOAT, 2, d, &c));
  const char* latitude = "latitude";
  const char* longitude = "longitude";
  const char* height = "height";
  ok(nc_put_att_string(nc, a, "standard_name", 1, &latitude));
  ok(nc_put_att_string(nc, b, "standard_name", 1, &height));
  ok(nc_put_att_string(nc, c, "standard_name", 1, &longitude));
  ok(nc_enddef(nc));
  const float as[] = {40, 41}, bs[] = {100, 200}, cs[] = {5, 6};
  ok(nc_put_var_float(nc, a, as));
  ok(nc_put_var_float(nc, b, bs));
  ok(nc_put_var_float(nc, c, cs));
  ok(nc_close(nc));
  const LineSet l = read_line_set(path);
  EXPECT_EQ(l.positions, (std::vector<float>{5, 40, 100, 6, 41, 200}));
  EXPECT_EQ(l.metadata.at("netcdf.layout"), "cf-multidimensional");
  EXPECT_EQ(l.metadata.at("netcdf.x"), "c");
  EXPECT_EQ(l.metadata.at("netcdf.z"), "b");
}

TEST(NetCdf, StringTypedAttributesInRaggedFiles) {
  TempDir dir;
  const std::string path = dir.file("strings.nc");
  int nc, traj, obs, count, p, q, r;
  ok(nc_create(path.c_str(), NC_CLOBBER | NC_NETCDF4, &nc));
  const char* trajectory = "trajectory";
  ok(nc_put_att_string(nc, NC_GLOBAL, "featureType", 1, &trajectory));
  ok(nc_def_dim(nc, "trajectory", 2, &traj));
  ok(nc_def_dim(nc, "obs", 3, &obs));
  ok(nc_def_var(nc, "rowSize", NC_INT, 1, &traj, &count));
  const char* sample = "obs";
  ok(nc_put_att_string(nc, count, "sample_dimension", 1, &sample));
  ok(nc_def_var(nc, "p", NC_DOUBLE, 1, &obs, &p));
  ok(nc_def_var(nc, "q", NC_DOUBLE, 1, &obs, &q));
  ok(nc_def_var(nc, "r", NC_DOUBLE, 1, &obs, &r));
  const char *x = "X", *y = "Y", *z = "Z";
  ok(nc_put_att_string(nc, p, "axis", 1, &y));
  ok(nc_put_att_string(nc, q, "axis", 1, &z));
  ok(nc_put_att_string(nc, r, "axis", 1, &x));
  ok(nc_enddef(nc));
  const int counts[] = {1, 2};
  const double ps[] = {1, 2, 3}, qs[] = {4, 5, 6}, rs[] = {7, 8, 9};
  ok(nc_put_var_int(nc, count, counts));
  ok(nc_put_var_double(nc, p, ps));
  ok(nc_put_var_double(nc, q, qs));
  ok(nc_put_var_double(nc, r, rs));
  ok(nc_close(nc));
  const LineSet l = read_line_set(path);
  EXPECT_EQ(l.line_offsets, (std::vector<uint64_t>{0, 1, 3}));
  EXPECT_EQ(l.positions, (std::vector<float>{7, 1, 4, 8, 2, 5, 9, 3, 6}));
  EXPECT_EQ(l.metadata.at("netcdf.layout"), "cf-contiguous-ragged");
}

namespace {
// A contiguous ragged file with counts {2, 1} and `observations` observations; those past the
// counts hold `tail` (lon) and 0 (lat). The count variable gets `count_fill` as _FillValue.
std::string write_ragged(TempDir& dir, const std::string& name, size_t observations,
                         std::optional<float> tail, const std::vector<int>& counts = {2, 1},
                         std::optional<int> count_fill = std::nullopt) {
  const std::string path = dir.file(name);
  int nc, traj, obs, count, lon, lat;
  EXPECT_EQ(nc_create(path.c_str(), NC_CLOBBER, &nc), NC_NOERR);
  nc_def_dim(nc, "trajectory", counts.size(), &traj);
  nc_def_dim(nc, "obs", observations, &obs);
  nc_def_var(nc, "rowSize", NC_INT, 1, &traj, &count);
  nc_put_att_text(nc, count, "sample_dimension", 3, "obs");
  if (count_fill) nc_put_att_int(nc, count, "_FillValue", NC_INT, 1, &*count_fill);
  nc_def_var(nc, "lon", NC_FLOAT, 1, &obs, &lon);
  nc_def_var(nc, "lat", NC_FLOAT, 1, &obs, &lat);
  nc_enddef(nc);
  nc_put_var_int(nc, count, counts.data());
  std::vector<float> lons = {1, 2, 3}, lats(observations, 0.0f);
  if (tail) lons.resize(observations, *tail);
  const size_t start = 0, extent = lons.size();
  nc_put_vara_float(nc, lon, &start, &extent, lons.data());  // unwritten: the default fill
  nc_put_var_float(nc, lat, lats.data());
  EXPECT_EQ(nc_close(nc), NC_NOERR);
  return path;
}
}  // namespace

TEST(NetCdf, RaggedObservationsPastTheCountsMustBeMissing) {
  // CF 9.3: the sample dimension may be larger than the counts need, the space past them
  // pre-filled with missing values. Data there is an inconsistency, not to be dropped silently.
  TempDir dir;
  const std::string data = write_ragged(dir, "data.nc", 5, 4.0f);
  const std::string error = read_error(data);
  EXPECT_NE(error.find("variable rowSize"), std::string::npos) << error;
  EXPECT_NE(error.find("sum to 3"), std::string::npos) << error;
  EXPECT_NE(error.find("obs has 5"), std::string::npos) << error;

  for (const std::string& path : {write_ragged(dir, "unwritten.nc", 5, std::nullopt),
                                  write_ragged(dir, "nan.nc", 5, float(NAN))}) {
    const LineSet l = read_line_set(path);
    EXPECT_EQ(l.line_offsets, (std::vector<uint64_t>{0, 2, 3})) << path;
    EXPECT_EQ(l.positions, (std::vector<float>{1, 0, 0, 2, 0, 0, 3, 0, 0})) << path;
    EXPECT_EQ(l.metadata.at("netcdf.unused_observations"), "2") << path;
  }
  const LineSet exact = read_line_set(write_ragged(dir, "exact.nc", 3, std::nullopt));
  EXPECT_EQ(exact.line_offsets, (std::vector<uint64_t>{0, 2, 3}));
  EXPECT_EQ(exact.metadata.count("netcdf.unused_observations"), 0u);
}

TEST(NetCdf, RaggedCountsThatAreMissingAreZero) {
  // CF 9.3.3: a feature not yet written has count 0 or a missing value.
  TempDir dir;
  const LineSet l = read_line_set(write_ragged(dir, "missing.nc", 6, std::nullopt, {2, -1, 1}, -1));
  EXPECT_EQ(l.line_offsets, (std::vector<uint64_t>{0, 2, 3}));
  EXPECT_EQ(l.metadata.at("netcdf.unused_observations"), "3");
}

// A file none of whose observations is a position, some outside a valid range, had read as no
// line and "no problems". The usual cause: a valid range meant in unpacked units but stored in
// the packed type, which CF 8.1 compares with the packed values. Now it is an error naming the
// variables, the counts and, for a packed range, what it means unpacked. (Fill values alone are
// a file not written yet: no line, StreamReaderContent.NoLines.)
TEST(NetCdf, NoPositionAtAllIsAnErrorThatSaysWhy) {
  TempDir dir;
  const auto write = [&](const std::string& name, bool packed_range, short second_lon) {
    const std::string path = dir.file(name);
    int nc, d[2], lon, lat;
    ok(nc_create(path.c_str(), NC_CLOBBER, &nc));
    ok(nc_def_dim(nc, "trajectory", 2, &d[0]));
    ok(nc_def_dim(nc, "obs", 3, &d[1]));
    ok(nc_def_var(nc, "lon", NC_SHORT, 2, d, &lon));
    ok(nc_def_var(nc, "lat", NC_SHORT, 2, d, &lat));
    const double scale = 0.01;
    const short range[] = {0, 100}, fill = -1;
    ok(nc_put_att_double(nc, lon, "scale_factor", NC_DOUBLE, 1, &scale));
    if (packed_range) ok(nc_put_att_short(nc, lon, "valid_range", NC_SHORT, 2, range));
    ok(nc_put_att_short(nc, lat, "_FillValue", NC_SHORT, 1, &fill));
    ok(nc_enddef(nc));
    // Longitudes 10 to 60 degrees packed by 0.01: past the packed range [0, 100] (the second
    // trajectory's as `second_lon` says).
    const short lons[] = {1000, 2000, 3000, second_lon, second_lon, second_lon};
    const short lats[] = {1, 2, 3, -1, -1, -1};
    ok(nc_put_var_short(nc, lon, lons));
    ok(nc_put_var_short(nc, lat, lats));
    ok(nc_close(nc));
    return path;
  };
  const auto message_of = [](const std::string& path) -> std::string {
    try {
      read_line_set(path);
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), path);
      return e.what();
    }
    return "(no error)";
  };
  const std::string range = message_of(write("range.nc", true, 4000));
  EXPECT_NE(range.find(": positions: "), std::string::npos) << range;
  EXPECT_NE(range.find("none of the file's 6 observations is a position"), std::string::npos)
      << range;
  EXPECT_NE(range.find("'lon' 6 outside the valid range [0, 100] of the stored values"),
            std::string::npos)
      << range;
  EXPECT_NE(range.find("[0, 1] unpacked"), std::string::npos) << range;
  // The second trajectory's longitudes in range, its latitudes the fill: each variable's count.
  const std::string both = message_of(write("both.nc", true, 50));
  EXPECT_NE(both.find("'lon' 3 outside the valid range [0, 100]"), std::string::npos) << both;
  EXPECT_NE(both.find("; 'lat' 3 equal to its _FillValue or missing_value"), std::string::npos)
      << both;

  // A file not written yet: every position the fill, which lies outside the valid range as CF
  // 2.5.1 recommends, reads as no line (a reviewer found the fill counted as outside the range,
  // and the file refused).
  {
    const std::string path = dir.file("unwritten.nc");
    int nc, d[2], lon, lat;
    ok(nc_create(path.c_str(), NC_CLOBBER, &nc));
    ok(nc_def_dim(nc, "trajectory", 2, &d[0]));
    ok(nc_def_dim(nc, "obs", 3, &d[1]));
    ok(nc_def_var(nc, "lon", NC_FLOAT, 2, d, &lon));
    ok(nc_def_var(nc, "lat", NC_FLOAT, 2, d, &lat));
    const float fill = -999, valid[] = {-90, 90};
    ok(nc_put_att_float(nc, lon, "_FillValue", NC_FLOAT, 1, &fill));
    ok(nc_put_att_float(nc, lon, "valid_range", NC_FLOAT, 2, valid));
    ok(nc_put_att_float(nc, lat, "valid_max", NC_FLOAT, 1, &valid[1]));  // the library's fill
    ok(nc_enddef(nc));
    ok(nc_close(nc));
    EXPECT_EQ(read_line_set(path).line_count(), 0u);
  }

  // Without the range the longitudes are positions, and the latitudes' fill makes the second
  // trajectory a gap: one line, no error.
  const LineSet l = read_line_set(write("fill.nc", false, 4000));
  EXPECT_EQ(l.line_offsets, (std::vector<uint64_t>{0, 3}));
}
