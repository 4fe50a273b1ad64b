// Streamed readers (lines/line_reader.hpp): every batch split gives the line set the whole read
// gives, and malformed files fail with the same message however small the batches.

#include <gtest/gtest.h>
#include <netcdf.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <map>
#include <optional>

#include "core/error.hpp"
#include "formats/registry.hpp"
#include "lines/line_reader.hpp"
#include "test_util.hpp"

using namespace linebake;
using linebake::test::read_text;
using linebake::test::TempDir;
using linebake::test::write_bytes;
using linebake::test::write_text;

namespace {

const uint64_t kBatchSizes[] = {
    1, 2, 3, 7, uint64_t{1} << 20, std::numeric_limits<uint64_t>::max()};

// ---------------------------------------------------------------------------------------------
// Checks

// Reads `path` whole, then batch by batch at every size of kBatchSizes: the header is known
// before the first batch, batches of more than one line respect max_points, lines_read() counts
// the lines handed out, the batches together are the whole read, and the header's metadata with
// what the reader counted on the way (counts_read) is the whole read's, whatever the batches.
void expect_streams_like_whole(const std::string& path) {
  SCOPED_TRACE(path);
  const LineSet whole = read_line_set(path);
  std::map<std::string, std::string> header_metadata = whole.metadata;
  header_metadata.erase("source");
  for (uint64_t max_points : kBatchSizes) {
    SCOPED_TRACE("max_points " + std::to_string(max_points));
    const std::unique_ptr<LineReader> reader = open_line_reader(path);
    EXPECT_TRUE(reader->streams());
    const LineSet& header = reader->header();
    for (const auto& [key, value] : header.metadata) EXPECT_EQ(header_metadata[key], value) << key;
    ASSERT_EQ(header.attributes.size(), whole.attributes.size());
    for (size_t a = 0; a < header.attributes.size(); ++a) {
      EXPECT_EQ(header.attributes[a].name, whole.attributes[a].name);
      EXPECT_TRUE(header.attributes[a].values.empty());
    }
    ASSERT_EQ(header.line_attributes.size(), whole.line_attributes.size());
    for (size_t a = 0; a < header.line_attributes.size(); ++a)
      EXPECT_EQ(header.line_attributes[a].name, whole.line_attributes[a].name);

    LineSet all = header_of(header);
    LineSet batch;
    uint64_t lines = 0, batches = 0;
    while (reader->next(batch, max_points)) {
      ++batches;
      ASSERT_GT(batch.line_count(), 0u);
      ASSERT_EQ(batch.line_offsets.front(), 0u);
      ASSERT_EQ(batch.line_offsets.back(), batch.point_count());
      for (const Attribute& a : batch.attributes) ASSERT_EQ(a.values.size(), batch.point_count());
      for (const Attribute& a : batch.line_attributes)
        ASSERT_EQ(a.values.size(), batch.line_count());
      if (batch.line_count() > 1) {
        EXPECT_LE(batch.point_count(), max_points);
      }
      lines += batch.line_count();
      EXPECT_EQ(reader->lines_read(), lines);
      append_lines(all, batch);
    }
    EXPECT_EQ(batch.line_count(), 0u);
    EXPECT_FALSE(reader->next(batch, max_points));  // stays at the end
    EXPECT_TRUE(all.same_data(whole));
    std::map<std::string, std::string> metadata = header.metadata;
    add_counts_read(metadata, reader->counts_read());
    EXPECT_EQ(metadata, header_metadata);
    EXPECT_EQ(reader->lines_read(), whole.line_count());
    if (max_points == 1) {  // one point per batch: every line that has points comes alone
      uint64_t nonempty = 0;
      for (size_t l = 0; l < whole.line_count(); ++l) nonempty += whole.line_size(l) > 0;
      EXPECT_GE(batches, nonempty);
    }
  }
}

struct Failure {
  std::string message;  // empty: no InputError
  uint64_t batches = 0;
};

Failure read_whole(const std::string& path) {
  try {
    read_line_set(path);
  } catch (const InputError& e) {
    return {e.what(), 0};
  }
  return {};
}

Failure read_streamed(const std::string& path, uint64_t max_points) {
  Failure f;
  try {
    const std::unique_ptr<LineReader> reader = open_line_reader(path);
    LineSet batch;
    while (reader->next(batch, max_points)) ++f.batches;
  } catch (const InputError& e) {
    f.message = e.what();
  }
  return f;
}

// The whole read fails with a message naming the file and holding `expected`; streamed in small
// batches, the read fails with the very same message, after `min_batches` batches or more.
void expect_same_failure(const std::string& path, const std::string& expected,
                         uint64_t min_batches = 0) {
  SCOPED_TRACE(path);
  const Failure whole = read_whole(path);
  ASSERT_FALSE(whole.message.empty()) << "expected an error mentioning '" << expected << "'";
  EXPECT_NE(whole.message.find(path), std::string::npos) << whole.message;
  EXPECT_NE(whole.message.find(expected), std::string::npos)
      << "expected '" << expected << "' in: " << whole.message;
  for (uint64_t max_points : {1, 2, 3}) {
    const Failure streamed = read_streamed(path, max_points);
    EXPECT_EQ(streamed.message, whole.message) << "max_points " << max_points;
    EXPECT_GE(streamed.batches, min_batches) << "max_points " << max_points;
  }
}

// ---------------------------------------------------------------------------------------------
// File builders

using test::Bytes;

using Point = std::array<double, 3>;
using Polyline = std::vector<Point>;

// Lines of the given sizes with distinct, not round, coordinates.
std::vector<Polyline> polylines(const std::vector<size_t>& sizes) {
  std::vector<Polyline> lines;
  for (size_t l = 0; l < sizes.size(); ++l) {
    Polyline line;
    for (size_t i = 0; i < sizes[l]; ++i)
      line.push_back({double(l) + 0.1 * double(i), -1.0 / double(i + 3), 1e3 * double(l)});
    lines.push_back(line);
  }
  return lines;
}

struct TckOptions {
  bool big = false;
  bool doubles = false;
  std::optional<int64_t> count;  // the header's count entry, if any
  bool close_last = true;        // a NaN triplet after the last line
  bool finished = true;          // the Inf triplet at the end
};

std::vector<unsigned char> tck_bytes(const std::vector<Polyline>& lines, const TckOptions& o) {
  const std::string type = std::string(o.doubles ? "Float64" : "Float32") + (o.big ? "BE" : "LE");
  std::string header = "mrtrix tracks\ndatatype: " + type + "\nstep_size: 0.5\n";
  if (o.count) header += "count: " + std::to_string(*o.count) + "\n";
  header += "file: . 256\nEND\n";
  header.resize(256, ' ');
  Bytes b(o.big);
  b.data.assign(header.begin(), header.end());
  auto put = [&](double x, double y, double z) {
    for (double v : {x, y, z})
      o.doubles ? (void)b.put<double>(v) : (void)b.put<float>(static_cast<float>(v));
  };
  for (size_t l = 0; l < lines.size(); ++l) {
    for (const Point& p : lines[l]) put(p[0], p[1], p[2]);
    if (o.close_last || l + 1 < lines.size()) put(NAN, NAN, NAN);
  }
  if (o.finished) put(INFINITY, INFINITY, INFINITY);
  return b.data;
}

struct TrkOptions {
  bool big = false;
  std::vector<std::string> scalars;     // names ("" for an unnamed one)
  std::vector<std::string> properties;  // names ("" for an unnamed one)
  bool write_count = true;              // n_count = the line count, else 0 (read to the end)
  // n_scalars and n_properties: the columns of each point and line (-1: one a name).
  int scalar_columns = -1;
  int property_columns = -1;
};

// A name slot as nibabel writes a multi-component scalar or property: the name, a NUL, the count.
std::string counted_name(const std::string& name, int components) {
  return name + std::string(1, '\0') + std::to_string(components);
}

// Scalars of point i of line l are l + i / 8 + s, properties l * 10 + p.
std::vector<unsigned char> trk_bytes(const std::vector<Polyline>& lines, const TrkOptions& o) {
  const size_t scalars = o.scalar_columns < 0 ? o.scalars.size() : size_t(o.scalar_columns);
  const size_t properties =
      o.property_columns < 0 ? o.properties.size() : size_t(o.property_columns);
  Bytes b(o.big);
  b.text("TRACK", 6);
  b.put<int16_t>(10).put<int16_t>(20).put<int16_t>(30);
  b.put<float>(1.5f).put<float>(1.25f).put<float>(2.0f);
  b.put<float>(0).put<float>(0).put<float>(0);
  b.put<int16_t>(static_cast<int16_t>(scalars));
  for (size_t i = 0; i < 10; ++i) b.text(i < o.scalars.size() ? o.scalars[i] : "", 20);
  b.put<int16_t>(static_cast<int16_t>(properties));
  for (size_t i = 0; i < 10; ++i) b.text(i < o.properties.size() ? o.properties[i] : "", 20);
  for (int i = 0; i < 16; ++i) b.put<float>(i % 5 == 0 ? 2.0f : 0.5f * float(i));
  b.text("", 444).text("RAS", 4).text("", 4);
  for (int i = 0; i < 6; ++i) b.put<float>(0);
  b.text("", 2).text("", 6);
  b.put<int32_t>(o.write_count ? static_cast<int32_t>(lines.size()) : 0);
  b.put<int32_t>(2).put<int32_t>(1000);
  EXPECT_EQ(b.data.size(), 1000u);
  for (size_t l = 0; l < lines.size(); ++l) {
    b.put<int32_t>(static_cast<int32_t>(lines[l].size()));
    for (size_t i = 0; i < lines[l].size(); ++i) {
      for (double v : lines[l][i]) b.put<float>(static_cast<float>(v));
      for (size_t s = 0; s < scalars; ++s) b.put<float>(float(l) + float(i) / 8.0f + float(s));
    }
    for (size_t p = 0; p < properties; ++p) b.put<float>(float(l) * 10.0f + float(p));
  }
  return b.data;
}

void nc_ok(int status) {
  ASSERT_EQ(status, NC_NOERR) << nc_strerror(status);
}

// Lagranto style (1 x trajectory x time) or CF multidimensional ((1 x 1 x) trajectory x obs):
// `x` holds lines x points values; invalid values cut lines (-999 is lon's fill value).
void write_multidimensional(const std::string& path, bool cf, size_t lines, size_t points,
                            const std::vector<double>& x) {
  int nc, d[4], lon, lat, p, t, u;
  nc_ok(nc_create(path.c_str(), NC_CLOBBER | (cf ? NC_NETCDF4 : 0), &nc));
  int ndims = 3;
  if (cf) {
    nc_ok(nc_put_att_text(nc, NC_GLOBAL, "featureType", 10, "trajectory"));
    nc_ok(nc_def_dim(nc, "member", 1, &d[0]));
    nc_ok(nc_def_dim(nc, "run", 1, &d[1]));
    nc_ok(nc_def_dim(nc, "trajectory", lines, &d[2]));
    nc_ok(nc_def_dim(nc, "obs", points, &d[3]));
    ndims = 4;
  } else {
    nc_ok(nc_def_dim(nc, "ensemble", 1, &d[0]));
    nc_ok(nc_def_dim(nc, "trajectory", lines, &d[1]));
    nc_ok(nc_def_dim(nc, "time", points, &d[2]));
  }
  nc_ok(nc_def_var(nc, "lon", NC_DOUBLE, ndims, d, &lon));
  nc_ok(nc_def_var(nc, "lat", NC_FLOAT, ndims, d, &lat));
  nc_ok(nc_def_var(nc, "p", NC_FLOAT, ndims, d, &p));
  nc_ok(nc_def_var(nc, "T", NC_FLOAT, ndims, d, &t));
  nc_ok(nc_def_var(nc, "QV", NC_INT, ndims, d, &u));
  const double fill = -999.0;
  nc_ok(nc_put_att_double(nc, lon, "_FillValue", NC_DOUBLE, 1, &fill));
  const int qv_fill = -1;
  nc_ok(nc_put_att_int(nc, u, "missing_value", NC_INT, 1, &qv_fill));
  nc_ok(nc_enddef(nc));
  std::vector<double> y(x.size()), z(x.size()), temperature(x.size());
  std::vector<int> qv(x.size());
  for (size_t i = 0; i < x.size(); ++i) {
    y[i] = 45.0 + 1.0 / double(i + 1);
    z[i] = 900.0 - double(i) * 7.5;
    temperature[i] = 280.0 - 0.3 * double(i);
    qv[i] = i % 4 == 3 ? -1 : int(i);  // fills become NaN attribute values
  }
  nc_ok(nc_put_var_double(nc, lon, x.data()));
  nc_ok(nc_put_var_double(nc, lat, y.data()));
  nc_ok(nc_put_var_double(nc, p, z.data()));
  nc_ok(nc_put_var_double(nc, t, temperature.data()));
  nc_ok(nc_put_var_int(nc, u, qv.data()));
  nc_ok(nc_close(nc));
}

// CF contiguous ragged arrays: per-line counts, then observations back to back; no z variable
// when !with_z.
void write_ragged(const std::string& path, const std::vector<int>& counts,
                  const std::vector<double>& x, bool with_z) {
  int nc, traj, obs, count, lon, lat, alt, speed;
  nc_ok(nc_create(path.c_str(), NC_CLOBBER, &nc));
  nc_ok(nc_put_att_text(nc, NC_GLOBAL, "featureType", 10, "trajectory"));
  nc_ok(nc_def_dim(nc, "trajectory", counts.size(), &traj));
  nc_ok(nc_def_dim(nc, "obs", x.size(), &obs));
  nc_ok(nc_def_var(nc, "n", NC_INT, 1, &traj, &count));
  nc_ok(nc_put_att_text(nc, count, "sample_dimension", 3, "obs"));
  nc_ok(nc_def_var(nc, "a", NC_DOUBLE, 1, &obs, &lon));
  nc_ok(nc_put_att_text(nc, lon, "axis", 1, "X"));
  nc_ok(nc_def_var(nc, "lat", NC_FLOAT, 1, &obs, &lat));
  if (with_z) nc_ok(nc_def_var(nc, "depth", NC_FLOAT, 1, &obs, &alt));
  nc_ok(nc_def_var(nc, "speed", NC_FLOAT, 1, &obs, &speed));
  const float fill = 9999.0f;
  nc_ok(nc_put_att_float(nc, speed, "_FillValue", NC_FLOAT, 1, &fill));
  nc_ok(nc_enddef(nc));
  nc_ok(nc_put_var_int(nc, count, counts.data()));
  std::vector<double> y(x.size()), z(x.size()), s(x.size());
  for (size_t i = 0; i < x.size(); ++i) {
    y[i] = -10.0 + double(i) / 3.0;
    z[i] = double(i % 5);
    s[i] = i % 6 == 5 ? 9999.0 : 0.5 + double(i);
  }
  nc_ok(nc_put_var_double(nc, lon, x.data()));
  nc_ok(nc_put_var_double(nc, lat, y.data()));
  if (with_z) nc_ok(nc_put_var_double(nc, alt, z.data()));
  nc_ok(nc_put_var_double(nc, speed, s.data()));
  nc_ok(nc_close(nc));
}

// x values 0.25, 1.25, ... for lines x points, with `cuts` (flat index, value) applied.
std::vector<double> grid_x(size_t lines, size_t points,
                           const std::vector<std::pair<size_t, double>>& cuts) {
  std::vector<double> x(lines * points);
  for (size_t i = 0; i < x.size(); ++i) x[i] = 0.25 + double(i);
  for (const auto& [at, value] : cuts) x[at] = value;
  return x;
}

// ---------------------------------------------------------------------------------------------
// The files read both ways

struct Case {
  const char* name;
  std::function<std::string(const TempDir&)> write;  // writes the file, returns its path
  friend void PrintTo(const Case& c, std::ostream* os) { *os << c.name; }
};

std::vector<Case> cases() {
  std::vector<Case> list;
  // MRtrix .tck in every datatype; lines of 1 to 12 points.
  const std::vector<size_t> tck_sizes = {2, 3, 1, 12, 5, 1, 1, 8, 4};
  for (bool big : {false, true})
    for (bool doubles : {false, true}) {
      static const char* names[2][2] = {{"tck_float32le", "tck_float64le"},
                                        {"tck_float32be", "tck_float64be"}};
      list.push_back({names[big][doubles], [=](const TempDir& dir) {
                        const std::string path = dir.file("a.tck");
                        TckOptions o;
                        o.big = big;
                        o.doubles = doubles;
                        o.count = int64_t(tck_sizes.size());
                        write_bytes(path, tck_bytes(polylines(tck_sizes), o));
                        return path;
                      }});
    }
  // Empty streamlines (NaN right after NaN, and first), no count entry.
  list.push_back({"tck_empty_streamlines_no_count", [](const TempDir& dir) {
                    const std::string path = dir.file("a.tck");
                    write_bytes(path, tck_bytes(polylines({0, 3, 0, 0, 2, 9, 0, 1}), {}));
                    return path;
                  }});
  list.push_back({"tck_one_long_streamline", [](const TempDir& dir) {
                    const std::string path = dir.file("a.tck");
                    TckOptions o;
                    o.count = 1;
                    write_bytes(path, tck_bytes(polylines({40}), o));
                    return path;
                  }});

  // TrackVis .trk.
  const std::vector<size_t> trk_sizes = {2, 3, 1, 11, 5, 1, 6, 2};
  for (bool big : {false, true})
    list.push_back({big ? "trk_big_endian_scalars_properties" : "trk_little_scalars_properties",
                    [=](const TempDir& dir) {
                      const std::string path = dir.file("a.trk");
                      TrkOptions o;
                      o.big = big;
                      o.scalars = {"fa", "md", "curvature"};
                      o.properties = {"length", "cluster"};
                      write_bytes(path, trk_bytes(polylines(trk_sizes), o));
                      return path;
                    }});
  list.push_back({"trk_no_count_read_to_end", [=](const TempDir& dir) {
                    const std::string path = dir.file("a.trk");
                    TrkOptions o;
                    o.write_count = false;
                    o.scalars = {"", "named"};  // the first becomes scalar_0
                    o.properties = {""};        // property_0
                    write_bytes(path, trk_bytes(polylines(trk_sizes), o));
                    return path;
                  }});
  list.push_back({"trk_nibabel_multi_component_names", [=](const TempDir& dir) {
                    const std::string path = dir.file("a.trk");
                    TrkOptions o;
                    o.scalars = {counted_name("colors", 3), "fa"};
                    o.scalar_columns = 4;
                    o.properties = {counted_name("pair", 2), "length"};
                    o.property_columns = 3;
                    write_bytes(path, trk_bytes(polylines(trk_sizes), o));
                    return path;
                  }});
  list.push_back({"trk_plain_with_empty_streamlines", [](const TempDir& dir) {
                    const std::string path = dir.file("a.trk");
                    write_bytes(path, trk_bytes(polylines({0, 4, 0, 1, 9}), {}));
                    return path;
                  }});

  // CSV.
  list.push_back({"csv_with_attributes", [](const TempDir& dir) {
                    const std::string path = dir.file("a.csv");
                    std::string text = "line_id,x,y,z,speed,temp\n";
                    const size_t sizes[] = {3, 1, 9, 2, 2, 7, 1, 4};
                    for (size_t l = 0; l < std::size(sizes); ++l)
                      for (size_t i = 0; i < sizes[l]; ++i)
                        text += std::to_string(l) + "," + std::to_string(0.1 * double(i)) + "," +
                                std::to_string(l) + ".5,-" + std::to_string(i) + "e-3," +
                                std::to_string(i * l) + ",nan\n";
                    write_text(path, text);
                    return path;
                  }});
  list.push_back(
      {"csv_unordered_ids_crlf_blank_rows_no_final_newline", [](const TempDir& dir) {
         const std::string path = dir.file("a.csv");
         write_text(path,
                    "line_id, x, y, z\r\n"
                    "7, 0, 0, 0\r\n7, 1, 0, 0\r\n\r\n7, 2, 0, 0\r\n"
                    "-3, 5, 5, 5\r\n"
                    "100, 1e-3, 2.5, -0\r\n100, 1, 1, 1\r\n  \r\n"
                    "6, 0, 1, 2\r\n5, 3, 4, 5\r\n5, 6, 7, 8\r\n5, 9, 10, 11\r\n5, 12, 13, 14\r\n"
                    "8, inf, -inf, 1");
         return path;
       }});
  list.push_back({"csv_ids_in_any_order", [](const TempDir& dir) {
                    const std::string path = dir.file("a.csv");
                    std::string text = "line_id,x,y,z\n";
                    int row = 0;
                    for (int id : {1, 3, 2, 5, 4, 0, 7, -1, 9, 8, 6}) {
                      for (int i = 0; i <= id % 4; ++i, ++row)
                        text += std::to_string(id) + "," + std::to_string(row) + ",0,1\n";
                    }
                    write_text(path, text);
                    return path;
                  }});
  list.push_back({"csv_one_long_line", [](const TempDir& dir) {
                    const std::string path = dir.file("a.csv");
                    std::string text = "line_id,x,y,z,w\n";
                    for (int i = 0; i < 30; ++i)
                      text += "42," + std::to_string(i) + ",1,2," + std::to_string(-i) + "\n";
                    write_text(path, text);
                    return path;
                  }});

  list.push_back({"csv_bom_quotes_float_ids_underflow", [](const TempDir& dir) {
                    // Excel's byte-order mark, R's quoted names, Python's quoted values, pandas'
                    // float ids, values below float32's range.
                    const std::string path = dir.file("a.csv");
                    std::string text =
                        "\xEF\xBB\xBF\"line_id\",\"x\",\"y\",\"z\",\"a, \"\"b\"\"\"\n";
                    const size_t sizes[] = {2, 1, 4, 3};
                    for (size_t l = 0; l < std::size(sizes); ++l)
                      for (size_t i = 0; i < sizes[l]; ++i)
                        text += "\"" + std::to_string(l) + ".0\",\"" + std::to_string(i) +
                                "\", 1 ,\"-2.5\",\"1e-" + std::to_string(40 + 3 * i) + "\"\n";
                    write_text(path, text);
                    return path;
                  }});

  // NetCDF, both multidimensional layouts and contiguous ragged arrays.
  list.push_back({"netcdf_lagranto_fill_values", [](const TempDir& dir) {
                    const std::string path = dir.file("a.nc");
                    // 7 lines x 5 points: line 1 is cut after 2 points, line 3 has an invalid
                    // first point (no line), line 4 ends at a NaN, line 6 at 1e20.
                    write_multidimensional(
                        path, false, 7, 5,
                        grid_x(7, 5, {{7, -999.0}, {15, -999.0}, {22, NAN}, {33, 1e20}}));
                    return path;
                  }});
  list.push_back({"netcdf_cf_multidimensional_4d", [](const TempDir& dir) {
                    const std::string path = dir.file("a.nc");
                    // 9 lines x 4 points; lines 0 and 8 invalid from their first point.
                    write_multidimensional(
                        path, true, 9, 4,
                        grid_x(9, 4, {{0, -999.0}, {6, INFINITY}, {13, -2e25}, {32, NAN}}));
                    return path;
                  }});
  list.push_back({"netcdf_one_point_rows", [](const TempDir& dir) {
                    const std::string path = dir.file("a.nc");
                    write_multidimensional(path, false, 5, 1, grid_x(5, 1, {{2, -999.0}}));
                    return path;
                  }});
  list.push_back({"netcdf_ragged", [](const TempDir& dir) {
                    const std::string path = dir.file("a.nc");
                    const std::vector<int> counts = {2, 0, 3, 10, 1, 0, 4, 1, 6};
                    // Line 3 ends at a NaN after 4 points; line 6 has an invalid first point.
                    std::vector<double> x(27);
                    for (size_t i = 0; i < x.size(); ++i) x[i] = double(i) * 1.5;
                    x[9] = NAN;
                    x[16] = 1e21;
                    write_ragged(path, counts, x, true);
                    return path;
                  }});
  list.push_back({"netcdf_ragged_no_z", [](const TempDir& dir) {
                    const std::string path = dir.file("a.nc");
                    std::vector<double> x(12);
                    for (size_t i = 0; i < x.size(); ++i) x[i] = -double(i);
                    write_ragged(path, {1, 1, 5, 0, 2, 3}, x, false);
                    return path;
                  }});
  return list;
}

class StreamReader : public ::testing::TestWithParam<Case> {};

}  // namespace

TEST_P(StreamReader, BatchesMakeTheWholeRead) {
  TempDir dir;
  expect_streams_like_whole(GetParam().write(dir));
}

INSTANTIATE_TEST_SUITE_P(Formats, StreamReader, ::testing::ValuesIn(cases()),
                         [](const auto& param_info) { return std::string(param_info.param.name); });

// The batches hold what the file says (not only what the whole read says).
TEST(StreamReaderContent, TckTrkCsvNetcdfValues) {
  TempDir dir;
  LineSet batch;

  write_bytes(dir.file("a.tck"), tck_bytes(polylines({2, 0, 3}), {}));
  auto reader = open_line_reader(dir.file("a.tck"));
  EXPECT_EQ(reader->header().metadata.at("tck.step_size"), "0.5");
  ASSERT_TRUE(reader->next(batch, 3));  // 2 points, an empty streamline; 3 more do not fit
  EXPECT_EQ(batch.line_offsets, (std::vector<uint64_t>{0, 2, 2}));
  EXPECT_EQ(batch.positions[3], 0.1f);
  ASSERT_TRUE(reader->next(batch, 3));
  EXPECT_EQ(batch.line_offsets, (std::vector<uint64_t>{0, 3}));
  EXPECT_EQ(batch.positions[8], 2000.0f);
  EXPECT_FALSE(reader->next(batch, 3));

  TrkOptions o;
  o.scalars = {"fa"};
  o.properties = {"", "b"};
  write_bytes(dir.file("a.trk"), trk_bytes(polylines({1, 2}), o));
  reader = open_line_reader(dir.file("a.trk"));
  EXPECT_EQ(reader->header().metadata.at("trk.voxel_order"), "RAS");
  EXPECT_EQ(reader->header().line_attributes[0].name, "property_0");
  ASSERT_TRUE(reader->next(batch, 2));
  EXPECT_EQ(batch.line_offsets, (std::vector<uint64_t>{0, 1}));
  ASSERT_TRUE(reader->next(batch, 2));
  EXPECT_EQ(batch.attributes[0].values, (std::vector<float>{1.0f, 1.125f}));
  EXPECT_EQ(batch.line_attributes[1].values, (std::vector<float>{11.0f}));
  EXPECT_FALSE(reader->next(batch, 2));

  write_text(dir.file("a.csv"), "line_id,x,y,z,v\n3,1,2,3,4\n3,5,6,7,8\n1,0,0,0,9\n");
  reader = open_line_reader(dir.file("a.csv"));
  EXPECT_EQ(reader->header().attributes[0].name, "v");
  ASSERT_TRUE(reader->next(batch, 1));  // the first line, larger than 1 point, alone
  EXPECT_EQ(batch.positions, (std::vector<float>{1, 2, 3, 5, 6, 7}));
  EXPECT_EQ(reader->lines_read(), 1u);
  ASSERT_TRUE(reader->next(batch, 1));
  EXPECT_EQ(batch.attributes[0].values, (std::vector<float>{9}));
  EXPECT_FALSE(reader->next(batch, 1));

  write_ragged(dir.file("a.nc"), {2, 0, 1}, {1, 2, 3}, true);
  reader = open_line_reader(dir.file("a.nc"));
  EXPECT_EQ(reader->header().metadata.at("netcdf.layout"), "cf-contiguous-ragged");
  EXPECT_EQ(reader->header().metadata.at("netcdf.x"), "a");
  EXPECT_EQ(reader->header().metadata.at("netcdf.z"), "depth");
  ASSERT_TRUE(reader->next(batch, 3));
  EXPECT_EQ(batch.line_offsets, (std::vector<uint64_t>{0, 2, 3}));
  EXPECT_EQ(batch.positions, (std::vector<float>{1, -10, 0, 2, float(-10.0 + 1.0 / 3.0), 1, 3,
                                                 float(-10.0 + 2.0 / 3.0), 2}));
  EXPECT_FALSE(reader->next(batch, 3));
}

// CSV as other programs write it: Excel's "CSV UTF-8" starts with a byte-order mark; R's
// write.csv quotes the names, Python's csv.QUOTE_ALL every field (RFC 4180, "" a quote inside);
// pandas writes the ids of a float column as "3.0"; a value below float32's range reads as the
// nearest float, as strtof gives it (0 or a denormal).
TEST(StreamReaderContent, CsvAsSpreadsheetsAndDataFrameLibrariesWriteIt) {
  TempDir dir;
  write_text(dir.file("a.csv"),
             "\xEF\xBB\xBFline_id,x,y,z,t\n0,0,0,0,1e-50\n0,1,1,1,-1e-50\n0,2,2,2,1e-40\n");
  LineSet lines = read_line_set(dir.file("a.csv"));
  ASSERT_EQ(lines.attributes.size(), 1u);
  EXPECT_EQ(lines.attributes[0].name, "t");
  EXPECT_EQ(lines.attributes[0].values[0], 0.0f);
  EXPECT_TRUE(std::signbit(lines.attributes[0].values[1]));
  EXPECT_EQ(lines.attributes[0].values[1], 0.0f);
  EXPECT_EQ(lines.attributes[0].values[2], std::strtof("1e-40", nullptr));
  EXPECT_GT(lines.attributes[0].values[2], 0.0f);

  write_text(dir.file("b.csv"),
             "\"line_id\",\"x\",\"y\",\"z\",\"speed, \"\"m/s\"\"\",\"\"\"\"\n"
             "\"7\",\"1.5\",\"2\",\"3\",\"4\",\"5\"\n"
             " \"7\" , 1e-60, 0,0 , \"-6\",inf\n"
             "8.0,0,0,0,0,0\n8.,1,0,0,0,0\n"
             "-3.000,0,0,0,0,0\n"
             "1.2e1,0,0,0,0,0\n12e0,1,0,0,0,0\n1200E-2,2,0,0,0,0\n"
             "1e+16,0,0,0,0,0\n0.0e5,0,0,0,0,0\n");
  lines = read_line_set(dir.file("b.csv"));
  ASSERT_EQ(lines.attributes.size(), 2u);
  EXPECT_EQ(lines.attributes[0].name, "speed, \"m/s\"");
  EXPECT_EQ(lines.attributes[1].name, "\"");
  EXPECT_EQ(lines.line_offsets, (std::vector<uint64_t>{0, 2, 4, 5, 8, 9, 10}));
  EXPECT_EQ(lines.positions[0], 1.5f);
  EXPECT_EQ(lines.positions[3], 0.0f);  // 1e-60
  EXPECT_EQ(lines.attributes[0].values[1], -6.0f);
  EXPECT_EQ(lines.attributes[1].values[1], std::numeric_limits<float>::infinity());

  // Blanks inside quotes are part of a name, not of a number: " 4" reads as 0, 4 does.
  write_text(dir.file("c.csv"), "line_id,x,y,z,\" t \"\n\" 0\",\" 4\",5,6,\"7 \"\n0, 4,5,6,8\n");
  lines = read_line_set(dir.file("c.csv"));
  ASSERT_EQ(lines.attributes.size(), 1u);
  EXPECT_EQ(lines.attributes[0].name, " t ");
  EXPECT_EQ(lines.positions[0], 4.0f);
  EXPECT_EQ(lines.positions[3], 4.0f);
  EXPECT_EQ(lines.attributes[0].values, (std::vector<float>{7, 8}));

  // An attribute named as a position column is an attribute (the CSV writer writes one named x
  // so), and one named twice is renamed as in every format (review finding: both had been
  // refused at the header, the first of them a file linebake itself wrote).
  write_text(dir.file("d.csv"), "line_id,x,y,z,x,t,t\n0,1,2,3,4,5,6\n0,1,2,3,4,5,7\n");
  lines = read_line_set(dir.file("d.csv"));
  ASSERT_EQ(lines.attributes.size(), 3u);
  EXPECT_EQ(lines.attributes[0].name, "x");
  EXPECT_EQ(lines.attributes[0].values, (std::vector<float>{4, 4}));
  EXPECT_EQ(lines.attributes[2].name, "t_2");
  EXPECT_EQ(lines.attributes[2].values, (std::vector<float>{6, 7}));
  LineSet written = lines;
  written.metadata.clear();
  write_line_set(written, dir.file("e.csv"));
  EXPECT_EQ(read_line_set(dir.file("e.csv")).attributes[0].name, "x");
}

// nibabel writes a scalar or property of several components in one name slot, as the name, a
// NUL and the count ("colors\0" "3"), and n_scalars counts every component: such a slot names
// as many columns (as a multi-component VTK array: _x/_y/_z for 3, _0.._k otherwise), and the
// next slot names the column after them.
TEST(StreamReaderContent, TrkNameSlotsCoveringSeveralColumns) {
  TempDir dir;
  auto names = [](const std::vector<Attribute>& attributes) {
    std::vector<std::string> out;
    for (const Attribute& a : attributes) out.push_back(a.name);
    return out;
  };
  using Names = std::vector<std::string>;
  TrkOptions o;
  o.scalars = {counted_name("colors", 3), "fa"};
  o.scalar_columns = 4;
  o.properties = {counted_name("pair", 2), counted_name("one", 1), counted_name("six", 6)};
  o.property_columns = 10;
  write_bytes(dir.file("a.trk"), trk_bytes(polylines({2, 1}), o));
  LineSet lines = read_line_set(dir.file("a.trk"));
  EXPECT_EQ(names(lines.attributes), (Names{"colors_x", "colors_y", "colors_z", "fa"}));
  EXPECT_EQ(names(lines.line_attributes),
            (Names{"pair_0", "pair_1", "one", "six_0", "six_1", "six_2", "six_3", "six_4", "six_5",
                   "property_9"}));
  // Scalar s of point i of line l is l + i / 8 + s: fa is the fourth column.
  EXPECT_EQ(lines.attributes[3].values, (std::vector<float>{3.0f, 3.125f, 4.0f}));
  EXPECT_EQ(lines.attributes[1].values, (std::vector<float>{1.0f, 1.125f, 2.0f}));
  EXPECT_EQ(lines.line_attributes[2].values, (std::vector<float>{2.0f, 12.0f}));

  // Columns past the counted names are unnamed; more than 10 columns where the counts name them.
  o.scalars = {counted_name("dir", 3)};
  o.scalar_columns = 5;
  o.properties = {counted_name("a", 8), counted_name("b", 4)};
  o.property_columns = 12;
  write_bytes(dir.file("b.trk"), trk_bytes(polylines({3}), o));
  lines = read_line_set(dir.file("b.trk"));
  EXPECT_EQ(names(lines.attributes), (Names{"dir_x", "dir_y", "dir_z", "scalar_3", "scalar_4"}));
  ASSERT_EQ(lines.line_attributes.size(), 12u);
  EXPECT_EQ(lines.line_attributes[11].name, "b_3");
  EXPECT_EQ(lines.line_attributes[11].values, (std::vector<float>{11.0f}));

  // Counts that name more columns than there are are bytes left in the slots, not nibabel's (a
  // name "fa12" overwritten by "md" leaves "md\0" "2"): one column a slot, as TrackVis reads them
  // (review finding: such files had been refused).
  o = {};
  o.scalars = {"fa", counted_name("md", 2)};
  o.scalar_columns = 2;
  o.properties = {counted_name("pair", 2)};
  o.property_columns = 1;
  write_bytes(dir.file("c.trk"), trk_bytes(polylines({3}), o));
  lines = read_line_set(dir.file("c.trk"));
  EXPECT_EQ(names(lines.attributes), (Names{"fa", "md"}));
  EXPECT_EQ(names(lines.line_attributes), (Names{"pair"}));
  EXPECT_EQ(lines.attributes[1].values, (std::vector<float>{1.0f, 1.125f, 1.25f}));
}

// A line larger than a batch comes alone, whole: a streaming reader checks what it will hold
// against ReadOptions::memory_limit before reading it (the growing .tck and .csv lines every
// 65,536 points), so an input whose single line does not fit is refused at that line, naming it,
// not read into memory. Lines of 3, 100,000 and 2 points (1.2 MB of positions in the long one)
// under a limit of 1 MB: the first batch reads, the second is refused; under 64 MB, every point.
TEST(StreamReaderContent, ALineLargerThanTheMemoryLimitIsRefusedBeforeItIsRead) {
  TempDir dir;
  const std::vector<size_t> sizes = {3, 100000, 2};
  const std::vector<Polyline> lines = polylines(sizes);
  LineSet set;
  for (const Polyline& line : lines) {
    for (const Point& p : line) set.append_point(float(p[0]), float(p[1]), float(p[2]));
    set.end_line();
  }
  write_line_set(set, dir.file("a.binlines"));
  write_line_set(set, dir.file("a.h5"));
  write_bytes(dir.file("a.tck"), tck_bytes(lines, {}));
  write_bytes(dir.file("a.trk"), trk_bytes(lines, {}));
  std::string text = "line_id,x,y,z\n";
  for (size_t l = 0; l < lines.size(); ++l)
    for (const Point& p : lines[l])
      text += std::to_string(l) + "," + std::to_string(p[0]) + ",0,1\n";
  write_text(dir.file("a.csv"), text);
  std::vector<double> x;
  for (const Polyline& line : lines)
    for (const Point& p : line) x.push_back(p[0]);
  write_ragged(dir.file("a.nc"), {3, 100000, 2}, x, true);
  for (const char* name : {"a.binlines", "a.h5", "a.tck", "a.trk", "a.csv", "a.nc"}) {
    SCOPED_TRACE(name);
    ReadOptions read;
    read.memory_limit = 1000000;
    auto reader = open_line_reader(dir.file(name), read);
    LineSet batch;
    ASSERT_TRUE(reader->next(batch, 16));
    EXPECT_EQ(batch.line_offsets, (std::vector<uint64_t>{0, 3}));
    try {
      reader->next(batch, 16);
      ADD_FAILURE() << "the 100,000-point line was read under a limit of 1 MB";
    } catch (const BudgetExceeded& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find(dir.file(name) + ": line 1 ("), std::string::npos) << message;
      EXPECT_NE(message.find("976.56 KiB"), std::string::npos) << message;
    }
    read.memory_limit = uint64_t{64} << 20;
    reader = open_line_reader(dir.file(name), read);
    uint64_t points = 0;
    while (reader->next(batch, 16)) points += batch.point_count();
    EXPECT_EQ(points, 100005u);
  }
}

// An attribute name that is not UTF-8 (a .binlines v2 name in Latin-1) is refused when the file
// is opened, naming it: caches keep names in JSON, whose replacement character made two such
// names one and lost their statistics.
TEST(StreamReaderContent, AnAttributeNameThatIsNotUtf8IsRefused) {
  TempDir dir;
  LineSet lines;
  lines.attributes.push_back(
      {"sp\xff"
       "eed",
       {0, 1}});
  lines.append_point(0, 0, 0);
  lines.append_point(1, 0, 0);
  lines.end_line();
  write_line_set(lines, dir.file("latin1.binlines"));
  try {
    open_line_reader(dir.file("latin1.binlines"));
    FAIL() << "opened";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where(),
              "attribute sp\xff"
              "eed");
    EXPECT_NE(std::string(e.what()).find("its name is not UTF-8 text"), std::string::npos);
  }
  lines.attributes[0].name =
      "sp\xc3\xa9"
      "ed";  // "spéed" in UTF-8 reads
  write_line_set(lines, dir.file("utf8.binlines"));
  EXPECT_EQ(open_line_reader(dir.file("utf8.binlines"))->header().attributes[0].name,
            lines.attributes[0].name);
}

TEST(StreamReaderContent, Utf8IsCheckedAsRfc3629Says) {
  EXPECT_TRUE(valid_utf8(""));
  EXPECT_TRUE(valid_utf8("ascii"));
  EXPECT_TRUE(valid_utf8("\xc3\xa9\xe2\x82\xac\xf0\x9f\x98\x80"));  // é, €, an emoji
  EXPECT_FALSE(valid_utf8("\xff"));
  EXPECT_FALSE(valid_utf8("\xc3"));              // cut short
  EXPECT_FALSE(valid_utf8("\xc0\xaf"));          // an overlong '/'
  EXPECT_FALSE(valid_utf8("\xed\xa0\x80"));      // a surrogate, U+D800
  EXPECT_FALSE(valid_utf8("\xf4\x90\x80\x80"));  // past U+10FFFF
  EXPECT_FALSE(valid_utf8("\xc3\x28"));          // a continuation byte missing
}

// A file with a header and no lines (nibabel writes such .tck and .trk files): no batch, and
// read_line_set's empty line set.
TEST(StreamReaderContent, NoLines) {
  TempDir dir;
  write_text(dir.file("a.csv"), "line_id,x,y,z\n\n");
  write_bytes(dir.file("a.tck"), tck_bytes({}, {}));
  write_bytes(dir.file("a.trk"), trk_bytes({}, {}));
  write_multidimensional(dir.file("a.nc"), false, 2, 2,
                         grid_x(2, 2, {{0, NAN}, {1, -999.0}, {2, -999.0}, {3, NAN}}));
  for (const char* name : {"a.csv", "a.tck", "a.trk", "a.nc"}) {
    SCOPED_TRACE(name);
    auto reader = open_line_reader(dir.file(name));
    LineSet batch;
    EXPECT_FALSE(reader->next(batch, 1));
    EXPECT_EQ(batch.line_count(), 0u);
    EXPECT_EQ(reader->lines_read(), 0u);
    const LineSet whole = read_line_set(dir.file(name));
    EXPECT_EQ(whole.line_count(), 0u);
    EXPECT_EQ(whole.point_count(), 0u);
  }
}

// A text reader's buffer starts at the file's size (at least 4 KiB, at most 1 MiB) and grows for
// a longer line: an OBJ polyline of 200,000 indices is one 1.3 MB line; a small OBJ and CSV
// without a final newline end within their first buffer.
TEST(StreamReaderContent, TextLinesLongerThanTheReadBuffer) {
  TempDir dir;
  const int n = 200000;
  std::string text;
  for (int i = 0; i < n; ++i) text += "v " + std::to_string(i) + " 0 " + std::to_string(-i) + "\n";
  text += "l";
  for (int i = 1; i <= n; ++i) text += " " + std::to_string(i);
  text += "\n";
  ASSERT_GT(text.size() - text.rfind('l'), size_t(1) << 20);
  write_text(dir.file("long.obj"), text);
  const LineSet whole = read_line_set(dir.file("long.obj"));
  ASSERT_EQ(whole.line_count(), 1u);
  ASSERT_EQ(whole.point_count(), size_t(n));
  EXPECT_EQ(whole.positions[3 * (n - 1)], float(n - 1));
  EXPECT_EQ(whole.positions[3 * (n - 1) + 2], -float(n - 1));

  write_text(dir.file("small.obj"), "v 0 0 0\nv 1 2 3\nl 1 2");  // no final newline
  write_text(dir.file("small.csv"), "line_id,x,y,z\n0,0,0,0\n0,1,2,3");
  for (const char* name : {"small.obj", "small.csv"}) {
    SCOPED_TRACE(name);
    const LineSet small = read_line_set(dir.file(name));
    ASSERT_EQ(small.point_count(), 2u);
    EXPECT_EQ(small.positions[5], 3.0f);
  }
}

// ---------------------------------------------------------------------------------------------
// Malformed files fail the same way streamed in small batches

TEST(StreamReaderMalformed, Tck) {
  TempDir dir;
  const auto lines = polylines({2, 3, 1, 4});
  TckOptions o;
  o.count = 7;  // the header disagrees with the data: found at the end
  write_bytes(dir.file("count.tck"), tck_bytes(lines, o));
  expect_same_failure(dir.file("count.tck"), "header: count says 7 streamlines, the data holds 4",
                      2);
  o = {};
  o.finished = false;
  write_bytes(dir.file("unfinished.tck"), tck_bytes(lines, o));
  expect_same_failure(dir.file("unfinished.tck"),
                      "file ends without the Inf end-of-file triplet (truncated?)", 2);
  o = {};
  o.close_last = false;
  write_bytes(dir.file("open.tck"), tck_bytes(lines, o));
  expect_same_failure(dir.file("open.tck"), "the last streamline is not closed by a NaN triplet",
                      2);
  auto bytes = tck_bytes(lines, {});
  bytes.resize(bytes.size() - 14);  // in the middle of a triplet
  write_bytes(dir.file("cut.tck"), bytes);
  expect_same_failure(dir.file("cut.tck"), "file truncated while reading point", 2);
  write_text(dir.file("type.tck"), "mrtrix tracks\ndatatype: Int16LE\nfile: . 40\nEND\n");
  expect_same_failure(dir.file("type.tck"), "header: unsupported datatype 'Int16LE'");
  write_text(dir.file("end.tck"), "mrtrix tracks\ndatatype: Float32LE\nfile: . 40\n");
  expect_same_failure(dir.file("end.tck"), "header: no END line");
}

TEST(StreamReaderMalformed, Trk) {
  TempDir dir;
  TrkOptions o;
  o.scalars = {"fa"};
  o.properties = {"length"};
  const auto lines = polylines({2, 3, 1, 4});
  auto bytes = trk_bytes(lines, o);
  bytes.insert(bytes.end(), {1, 2, 3, 4, 5});
  write_bytes(dir.file("trailing.trk"), bytes);
  expect_same_failure(dir.file("trailing.trk"),
                      ": unexpected 5 bytes after 4 streamlines (n_count)", 2);
  bytes = trk_bytes(lines, o);
  bytes.resize(bytes.size() - 6);
  write_bytes(dir.file("cut.trk"), bytes);
  expect_same_failure(dir.file("cut.trk"), "streamline 3 claims 4 points, more than the file holds",
                      2);
  bytes = trk_bytes(lines, o);
  const size_t third = 1000 + (4 + 2 * 16 + 4) + (4 + 3 * 16 + 4);
  const int32_t negative = -2;
  std::memcpy(bytes.data() + third, &negative, 4);
  write_bytes(dir.file("negative.trk"), bytes);
  expect_same_failure(
      dir.file("negative.trk"),
      "byte offset " + std::to_string(third) + ": negative point count in streamline 2",
      1);  // found while filling the batch after the first
  bytes = trk_bytes(lines, o);
  bytes[996] = 7;
  write_bytes(dir.file("hdr.trk"), bytes);
  expect_same_failure(dir.file("hdr.trk"), "byte offset 996: hdr_size is");

  o = {};
  o.scalar_columns = 11;  // more than 10 without names that count them
  write_bytes(dir.file("eleven.trk"), trk_bytes(lines, o));
  expect_same_failure(dir.file("eleven.trk"), "byte offset 36: n_scalars must be 0..10, got 11");

  // A file shorter than the header: the magic decides whether it is a TrackVis file cut short.
  write_bytes(dir.file("tck.trk"), tck_bytes(polylines({2, 3}), {}));
  expect_same_failure(dir.file("tck.trk"),
                      "byte offset 0: not a TrackVis file (no TRACK magic); it starts as an "
                      "MRtrix .tck file does");
  write_text(dir.file("text.trk"), "hello");
  expect_same_failure(dir.file("text.trk"), "byte offset 0: not a TrackVis file (no TRACK magic)");
  bytes = trk_bytes(lines, o);
  bytes.resize(600);
  write_bytes(dir.file("short.trk"), bytes);
  expect_same_failure(dir.file("short.trk"),
                      "byte offset 0: file truncated while reading the 1000-byte header");
}

TEST(StreamReaderMalformed, Csv) {
  TempDir dir;
  std::string rows = "line_id,x,y,z,a\n";
  for (int l = 0; l < 4; ++l)
    for (int i = 0; i < 3; ++i) rows += std::to_string(l) + ",0,0,0,1\n";
  write_text(dir.file("order.csv"), rows + "9,0,0,0,1\n2,1,1,1,1\n");
  expect_same_failure(dir.file("order.csv"), "line 15: rows of line 2 are not consecutive", 3);
  // Line 3 comes back after ids around it (1, 2, 4, 5, 6) were read in another order.
  write_text(dir.file("back.csv"),
             "line_id,x,y,z\n1,0,0,0\n3,0,0,0\n2,0,0,0\n5,0,0,0\n4,0,0,0\n6,0,0,0\n3,1,1,1\n");
  expect_same_failure(dir.file("back.csv"), "line 8: rows of line 3 are not consecutive", 1);
  write_text(dir.file("coordinate.csv"), rows + "4,1,abc,1,1\n");
  expect_same_failure(dir.file("coordinate.csv"), "line 14: bad coordinate 'abc'", 3);
  write_text(dir.file("columns.csv"), rows + "4,1,1,1\n");
  expect_same_failure(dir.file("columns.csv"), "line 14: 4 columns, the header has 5", 3);
  write_text(dir.file("value.csv"), rows + "4,1,1,1,x\n");
  expect_same_failure(dir.file("value.csv"), "line 14: bad value 'x'", 3);
  write_text(dir.file("id.csv"), rows + "four,1,1,1,1\n");
  expect_same_failure(dir.file("id.csv"), "line 14: bad line_id 'four'", 3);
  write_text(dir.file("header.csv"), "line_id,x,z,y\n0,0,0,0\n");
  expect_same_failure(dir.file("header.csv"), "line 1: header column 3 is 'z', expected 'y'");

  // Past float32's range: refused as such (below it, the nearest float reads).
  write_text(dir.file("large.csv"), rows + "4,1,1,1,1e40\n");
  expect_same_failure(dir.file("large.csv"),
                      "line 14: value '1e40' is outside float32's range (magnitude above "
                      "3.4028235e38)",
                      3);
  write_text(dir.file("large_coordinate.csv"), rows + "4,1,-1e400,1,1\n");
  expect_same_failure(dir.file("large_coordinate.csv"),
                      "line 14: coordinate '-1e400' is outside float32's range", 3);
  write_text(dir.file("shifted.csv"),
             rows + "4,1,1,1,100000000000000000000000000000000000000000000000000e-5\n");
  expect_same_failure(dir.file("shifted.csv"), "line 14: value '1000", 3);
  // A line id that is not an integer.
  write_text(dir.file("half.csv"), rows + "0.5,1,1,1,1\n");
  expect_same_failure(dir.file("half.csv"), "line 14: line_id '0.5' is not an integer", 3);
  write_text(dir.file("small_id.csv"), rows + "25e-1,1,1,1,1\n");
  expect_same_failure(dir.file("small_id.csv"), "line 14: line_id '25e-1' is not an integer", 3);
  write_text(dir.file("huge_id.csv"), rows + "1e30,1,1,1,1\n");
  expect_same_failure(dir.file("huge_id.csv"), "line 14: bad line_id '1e30'", 3);
  write_text(dir.file("nan_id.csv"), rows + "nan,1,1,1,1\n");
  expect_same_failure(dir.file("nan_id.csv"), "line 14: bad line_id 'nan'", 3);
  // Header names: none empty (an attribute named twice is renamed, one named x is read: the
  // test of names below).
  write_text(dir.file("unnamed.csv"), "line_id,x,y,z,\n0,1,1,1,\n");
  expect_same_failure(dir.file("unnamed.csv"),
                      "line 1: header column 5 has no name (a comma at the end of the header?)");
  write_text(dir.file("unnamed_quoted.csv"), "line_id,x,y,z,\"\",a\n0,1,1,1,1,1\n");
  expect_same_failure(dir.file("unnamed_quoted.csv"), "line 1: header column 5 has no name");
  // Quotes: a field closed on its line, nothing after its closing quote.
  write_text(dir.file("open.csv"), rows + "4,1,1,1,\"1\n2\"\n");
  expect_same_failure(dir.file("open.csv"),
                      "line 14: column 5: the quoted field is not closed on its line (a line "
                      "break inside quotes is not supported)",
                      3);
  write_text(dir.file("after.csv"), rows + "4,\"1\"2,1,1,1\n");
  expect_same_failure(dir.file("after.csv"), "line 14: column 2: text after the closing quote", 3);
  write_text(dir.file("quoted_bad.csv"), rows + "4,1,1,1,\"1,5\"\n");
  expect_same_failure(dir.file("quoted_bad.csv"), "line 14: bad value '1,5'", 3);
}

TEST(StreamReaderMalformed, Netcdf) {
  TempDir dir;
  // The third line's count runs past the 5 observations.
  write_ragged(dir.file("counts.nc"), {2, 1, 4, 1}, {0, 1, 2, 3, 4}, true);
  expect_same_failure(dir.file("counts.nc"),
                      "variable n, index 2: count runs past the 5 observations");
  write_ragged(dir.file("negative.nc"), {2, -1}, {0, 1, 2}, true);
  expect_same_failure(dir.file("negative.nc"), "variable n, index 1: count runs past");
  int nc, d;
  nc_ok(nc_create(dir.file("none.nc").c_str(), NC_CLOBBER, &nc));
  nc_ok(nc_def_dim(nc, "n", 3, &d));
  int v;
  nc_ok(nc_def_var(nc, "lon", NC_FLOAT, 1, &d, &v));
  nc_ok(nc_close(nc));
  expect_same_failure(dir.file("none.nc"), "no trajectory variables");
  write_text(dir.file("text.nc"), "not netcdf");
  expect_same_failure(dir.file("text.nc"), "cannot open as NetCDF");
}

// NetCDF-4 data is read by HDF5 under libnetcdf, and HDF5 1.10.8 trusts a compact dataset's
// stored size when it reads one (tests/test_isolated.cpp,
// H5Probe.ACompactDatasetMustStoreItsShape). A NetCDF-4 variable damaged that way is refused
// already when libnetcdf opens the file, in the isolated walk: a clean error naming the file, even
// for a variable the reader does not read.
TEST(StreamReaderMalformed, NetcdfCompactVariableWithoutItsData) {
  TempDir dir;
  const std::string path = dir.file("a.nc");
  write_multidimensional(path, true, 2, 3, grid_x(2, 3, {}));
  {
    int nc, k, extra;
    nc_ok(nc_open(path.c_str(), NC_WRITE, &nc));
    nc_ok(nc_redef(nc));
    nc_ok(nc_def_dim(nc, "k", 3, &k));
    nc_ok(nc_def_var(nc, "extra", NC_FLOAT, 1, &k, &extra));
    nc_ok(nc_def_var_chunking(nc, extra, NC_COMPACT, nullptr));
    nc_ok(nc_enddef(nc));
    const float values[3] = {101.5f, 202.5f, 303.5f};
    nc_ok(nc_put_var_float(nc, extra, values));
    nc_ok(nc_close(nc));
  }
  EXPECT_EQ(read_line_set(path).line_count(), 2u);
  std::string bytes = read_text(path);
  const float first[2] = {101.5f, 202.5f};
  const size_t data = bytes.find(std::string(reinterpret_cast<const char*>(first), 8));
  ASSERT_NE(data, std::string::npos);
  ASSERT_GE(data, 4u);
  // The layout message: version 3, class 0 (compact), 12 bytes, then the data.
  ASSERT_EQ(bytes.substr(data - 4, 4), std::string("\x03\x00\x0c\x00", 4));
  bytes[data - 2] = 0;
  write_text(path, bytes);
  try {
    (void)read_line_set(path);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), path);
    EXPECT_NE(std::string(e.what()).find("cannot open as NetCDF"), std::string::npos) << e.what();
  }
}
