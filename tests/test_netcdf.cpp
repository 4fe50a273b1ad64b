// NetCDF trajectories in the three layouts, written with the netCDF C library.

#include <gtest/gtest.h>
#include <netcdf.h>

#include "core/error.hpp"
#include "formats/registry.hpp"
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
  const float lons[] = {10, 11, 12, 20, -999, 22};  // line 1 ends after its first point
  const float lats[] = {45, 46, 47, 50, 51, 52};
  const float ps[] = {900, 850, 800, 700, 650, 600};
  const float ts[] = {280, 279, 278, 260, 259, 258};
  ok(nc_put_var_float(nc, lon, lons));
  ok(nc_put_var_float(nc, lat, lats));
  ok(nc_put_var_float(nc, p, ps));
  ok(nc_put_var_float(nc, t, ts));
  ok(nc_close(nc));

  const LineSet l = read_line_set(path);
  EXPECT_EQ(l.line_offsets, (std::vector<uint64_t>{0, 3, 4}));
  EXPECT_EQ(l.positions, (std::vector<float>{10, 45, 900, 11, 46, 850, 12, 47, 800, 20, 50, 700}));
  ASSERT_EQ(l.attributes.size(), 1u);
  EXPECT_EQ(l.attributes[0].name, "T");
  EXPECT_EQ(l.attributes[0].values, (std::vector<float>{280, 279, 278, 260}));
  EXPECT_EQ(l.metadata.at("netcdf.layout"), "lagranto");
}

TEST(NetCdf, CfMultidimensionalWithAxisAttributes) {
  TempDir dir;
  const std::string path = dir.file("cf.nc");
  int nc, d[2], a, b, c;
  ok(nc_create(path.c_str(), NC_CLOBBER | NC_NETCDF4, &nc));
  ok(nc_put_att_text(nc, NC_GLOBAL, "featureType", 10, "trajectory"));
  ok(nc_def_dim(nc, "trajectory", 2, &d[0]));
  ok(nc_def_dim(nc, "obs", 2, &d[1]));
  // Names that say nothing: the axis attributes decide (and the order in the file is z, x, y).
  ok(nc_def_var(nc, "c", NC_DOUBLE, 2, d, &c));
  ok(nc_put_att_text(nc, c, "axis", 1, "Z"));
  ok(nc_def_var(nc, "a", NC_DOUBLE, 2, d, &a));
  ok(nc_put_att_text(nc, a, "axis", 1, "X"));
  ok(nc_def_var(nc, "b", NC_DOUBLE, 2, d, &b));
  ok(nc_put_att_text(nc, b, "axis", 1, "Y"));
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
