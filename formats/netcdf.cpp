// NetCDF trajectories.
//  - Lagranto / LineVis style: variables shaped (1 x) trajectory x time.
//  - CF discrete sampling geometry, featureType = "trajectory": multidimensional x(trajectory,
//    obs) (orthogonal or incomplete), or contiguous ragged arrays (a count variable whose
//    `sample_dimension` attribute names the observation dimension, observations back to back).
// Positions come from the variables marked axis X/Y/Z, else standard_name longitude/latitude/
// (altitude|height|air_pressure|depth), else the names x/lon/longitude, y/lat/latitude,
// z/p/pressure/alt/altitude/height/level/depth. A missing z is 0. Every other numeric variable of
// the same shape becomes a vertex attribute. A fill value (_FillValue or missing_value), NaN/Inf
// or |value| >= 1e20 in a position ends the line there (incomplete arrays, Lagranto's invalid
// points).

#include <netcdf.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <optional>

#include "core/error.hpp"
#include "formats/formats.hpp"

namespace linebake::formats {

namespace {

struct Nc {
  std::string path;
  int id = -1;
  explicit Nc(const std::string& p) : path(p) {
    const int status = nc_open(p.c_str(), NC_NOWRITE, &id);
    if (status != NC_NOERR)
      throw InputError(p, "", std::string("cannot open as NetCDF: ") + nc_strerror(status));
  }
  ~Nc() {
    if (id >= 0) nc_close(id);
  }
  void check(int status, const std::string& where) const {
    if (status != NC_NOERR) throw InputError(path, where, nc_strerror(status));
  }
};

std::string text_attribute(const Nc& nc, int var, const char* name) {
  size_t length = 0;
  nc_type type;
  if (nc_inq_att(nc.id, var, name, &type, &length) != NC_NOERR || type != NC_CHAR) return "";
  std::string s(length, '\0');
  nc_get_att_text(nc.id, var, name, s.data());
  while (!s.empty() && s.back() == '\0') s.pop_back();
  return s;
}

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

struct Variable {
  int id;
  std::string name;
  std::vector<int> dims;
  std::vector<size_t> shape;
  std::optional<double> fill;
};

std::vector<Variable> variables(const Nc& nc) {
  int count = 0;
  nc.check(nc_inq_nvars(nc.id, &count), "variables");
  std::vector<Variable> list;
  for (int v = 0; v < count; ++v) {
    char name[NC_MAX_NAME + 1];
    nc_type type;
    int ndims, natts;
    int dims[NC_MAX_VAR_DIMS];
    nc.check(nc_inq_var(nc.id, v, name, &type, &ndims, dims, &natts),
             "variable " + std::to_string(v));
    if (type == NC_CHAR || type == NC_STRING) continue;
    Variable var{v, name, std::vector<int>(dims, dims + ndims), {}, std::nullopt};
    for (int d : var.dims) {
      size_t length;
      nc.check(nc_inq_dimlen(nc.id, d, &length), "variable " + var.name);
      var.shape.push_back(length);
    }
    double fill;
    if (nc_get_att_double(nc.id, v, "_FillValue", &fill) == NC_NOERR)
      var.fill = fill;
    else if (nc_get_att_double(nc.id, v, "missing_value", &fill) == NC_NOERR)
      var.fill = fill;
    list.push_back(std::move(var));
  }
  return list;
}

// Which variable is axis 0/1/2 among the candidates.
const Variable* find_axis(const Nc& nc, const std::vector<const Variable*>& candidates, int axis) {
  static const char* axis_names[] = {"X", "Y", "Z"};
  static const std::vector<std::vector<std::string>> standard = {
      {"longitude", "projection_x_coordinate"},
      {"latitude", "projection_y_coordinate"},
      {"altitude", "height", "air_pressure", "depth", "projection_z_coordinate"}};
  static const std::vector<std::vector<std::string>> names = {
      {"x", "lon", "longitude"},
      {"y", "lat", "latitude"},
      {"z", "p", "pressure", "pres", "alt", "altitude", "height", "level", "depth"}};
  for (const Variable* v : candidates)
    if (text_attribute(nc, v->id, "axis") == axis_names[axis]) return v;
  for (const Variable* v : candidates)
    for (const std::string& s : standard[axis])
      if (lower(text_attribute(nc, v->id, "standard_name")) == s) return v;
  for (const std::string& s : names[axis])
    for (const Variable* v : candidates)
      if (lower(v->name) == s) return v;
  return nullptr;
}

std::vector<double> read_all(const Nc& nc, const Variable& v) {
  size_t total = 1;
  for (size_t s : v.shape) total *= s;
  std::vector<double> values(total);
  nc.check(nc_get_var_double(nc.id, v.id, values.data()), "variable " + v.name);
  return values;
}

bool invalid(double value, const std::optional<double>& fill) {
  return !std::isfinite(value) || std::fabs(value) >= 1e20 || (fill && value == *fill);
}

}  // namespace

LineSet read_netcdf(const std::string& path, const ReadOptions& options) {
  Nc nc(path);
  const std::vector<Variable> vars = variables(nc);
  const bool cf = lower(text_attribute(nc, NC_GLOBAL, "featureType")) == "trajectory";

  // Contiguous ragged: a count variable with sample_dimension.
  const Variable* counts = nullptr;
  int sample_dim = -1;
  for (const Variable& v : vars) {
    const std::string sample = text_attribute(nc, v.id, "sample_dimension");
    if (sample.empty()) continue;
    counts = &v;
    if (nc_inq_dimid(nc.id, sample.c_str(), &sample_dim) != NC_NOERR)
      throw InputError(path, "variable " + v.name,
                       "sample_dimension '" + sample + "' does not exist");
  }

  // Candidate position/attribute variables and the line layout.
  std::vector<const Variable*> candidates;
  size_t line_count = 0, max_points = 0;
  if (counts) {
    for (const Variable& v : vars)
      if (v.dims.size() == 1 && v.dims[0] == sample_dim && &v != counts) candidates.push_back(&v);
    line_count = counts->shape.empty() ? 1 : counts->shape[0];
  } else {
    // The shape every trajectory variable shares: (1 x) lines x points.
    std::vector<size_t> best;
    for (const Variable& v : vars) {
      std::vector<size_t> s = v.shape;
      while (s.size() > 2 && s.front() == 1) s.erase(s.begin());
      if (s.size() == 2 && s[0] * s[1] > (best.empty() ? 0 : best[0] * best[1])) best = s;
    }
    if (best.empty())
      throw InputError(path, "",
                       std::string("no trajectory variables (expected ") +
                           (cf ? "x(trajectory, obs)" : "(1 x) trajectory x time arrays") +
                           " or a ragged count variable with sample_dimension)");
    line_count = best[0];
    max_points = best[1];
    for (const Variable& v : vars) {
      std::vector<size_t> s = v.shape;
      while (s.size() > 2 && s.front() == 1) s.erase(s.begin());
      if (s == best) candidates.push_back(&v);
    }
  }
  const Variable* axes[3];
  for (int axis = 0; axis < 3; ++axis) axes[axis] = find_axis(nc, candidates, axis);
  if (!axes[0] || !axes[1])
    throw InputError(path, "", "cannot find x/longitude and y/latitude variables");

  std::vector<std::vector<double>> position_values(3);
  for (int axis = 0; axis < 3; ++axis)
    if (axes[axis]) position_values[axis] = read_all(nc, *axes[axis]);
  std::vector<const Variable*> attribute_vars;
  for (const Variable* v : candidates)
    if (v != axes[0] && v != axes[1] && v != axes[2]) attribute_vars.push_back(v);
  std::vector<std::vector<double>> attribute_values;
  for (const Variable* v : attribute_vars) attribute_values.push_back(read_all(nc, *v));
  if (options.progress) options.progress(1, 2);

  // Observation ranges per line.
  std::vector<std::pair<size_t, size_t>> ranges;  // [begin, end) into the flat arrays
  if (counts) {
    std::vector<double> n = read_all(nc, *counts);
    size_t at = 0;
    const size_t total = position_values[0].size();
    for (size_t i = 0; i < n.size(); ++i) {
      if (!(n[i] >= 0) || at + static_cast<size_t>(n[i]) > total)
        throw InputError(path, "variable " + counts->name + ", index " + std::to_string(i),
                         "count runs past the " + std::to_string(total) + " observations");
      ranges.emplace_back(at, at + static_cast<size_t>(n[i]));
      at += static_cast<size_t>(n[i]);
    }
  } else {
    for (size_t i = 0; i < line_count; ++i)
      ranges.emplace_back(i * max_points, (i + 1) * max_points);
  }

  LineSet lines;
  lines.attributes.resize(attribute_vars.size());
  for (size_t a = 0; a < attribute_vars.size(); ++a)
    lines.attributes[a].name = attribute_vars[a]->name;
  for (const auto& [begin, end] : ranges) {
    const size_t first = lines.point_count();
    for (size_t i = begin; i < end; ++i) {
      bool bad = false;
      for (int axis = 0; axis < 3; ++axis)
        if (axes[axis] && invalid(position_values[axis][i], axes[axis]->fill)) bad = true;
      if (bad) break;  // an invalid value ends the line
      lines.append_point(static_cast<float>(position_values[0][i]),
                         static_cast<float>(position_values[1][i]),
                         axes[2] ? static_cast<float>(position_values[2][i]) : 0.0f);
      for (size_t a = 0; a < attribute_vars.size(); ++a) {
        const double v = attribute_values[a][i];
        lines.attributes[a].values.push_back(
            attribute_vars[a]->fill && v == *attribute_vars[a]->fill ? NAN : static_cast<float>(v));
      }
    }
    if (lines.point_count() > first) lines.end_line();
  }
  lines.metadata["netcdf.layout"] = counts ? "cf-contiguous-ragged"
                                    : cf   ? "cf-multidimensional"
                                           : "lagranto";
  for (int axis = 0; axis < 3; ++axis)
    lines.metadata[std::string("netcdf.") + "xyz"[axis]] =
        axes[axis] ? axes[axis]->name : "(none: 0)";
  if (options.progress) options.progress(2, 2);
  return lines;
}

}  // namespace linebake::formats
