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
#include <stdexcept>

#include "core/error.hpp"
#include "core/isolated.hpp"
#include "formats/formats.hpp"
#include "formats/io_util.hpp"

namespace linebake::formats {

void walk_netcdf_metadata(const std::string& path) {
  int id = -1;
  int status = nc_open(path.c_str(), NC_NOWRITE, &id);
  if (status != NC_NOERR)
    throw std::runtime_error(std::string("cannot open as NetCDF: ") + nc_strerror(status));
  auto check = [&](int s, const std::string& where) {
    if (s != NC_NOERR) {
      nc_close(id);
      throw std::runtime_error(where + ": " + nc_strerror(s));
    }
  };
  int dims = 0, vars = 0, globals = 0, unlimited = -1;
  check(nc_inq(id, &dims, &vars, &globals, &unlimited), "the header");
  for (int d = 0; d < dims; ++d) {
    size_t length = 0;
    check(nc_inq_dimlen(id, d, &length), "dimension " + std::to_string(d));
  }
  auto attributes = [&](int var, int count, const std::string& where) {
    for (int a = 0; a < count; ++a) {
      char name[NC_MAX_NAME + 1];
      nc_type type;
      size_t length = 0;
      check(nc_inq_attname(id, var, a, name), where + ", attribute " + std::to_string(a));
      check(nc_inq_att(id, var, name, &type, &length), where + ", attribute " + name);
      size_t size = 0;
      check(nc_inq_type(id, type, nullptr, &size), where + ", attribute " + name);
      if (type == NC_STRING) {
        std::vector<char*> text(length);
        check(nc_get_att_string(id, var, name, text.data()), where + ", attribute " + name);
        nc_free_string(length, text.data());
      } else if (type <= NC_MAX_ATOMIC_TYPE && size > 0 && length <= (size_t{1} << 30) / size) {
        std::vector<char> value(length * size + 1);
        check(nc_get_att(id, var, name, value.data()), where + ", attribute " + name);
      }
    }
  };
  attributes(NC_GLOBAL, globals, "global attributes");
  for (int v = 0; v < vars; ++v) {
    char name[NC_MAX_NAME + 1];
    nc_type type;
    int ndims = 0, natts = 0;
    int var_dims[NC_MAX_VAR_DIMS];
    const std::string where = "variable " + std::to_string(v);
    check(nc_inq_var(id, v, name, &type, &ndims, var_dims, &natts), where);
    attributes(v, natts, std::string("variable ") + name);
  }
  nc_close(id);
}

namespace {

struct Nc {
  std::string path;
  int id = -1;
  explicit Nc(const std::string& p) : path(p) {
    check_in_isolation(p, "NetCDF", [&p] { walk_netcdf_metadata(p); }, {}, {"netcdf", p});
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

// Lines are read in batches: multidimensional arrays as hyperslabs of whole rows (lines of the
// file), contiguous ragged arrays as ranges of observations (the counts are read at open).
class NetcdfReader : public LineReader {
 public:
  NetcdfReader(const std::string& path, const ReadOptions& options)
      : nc_(path), progress_(options.progress), memory_limit_(options.memory_limit) {
    vars_ = variables(nc_);
    const bool cf = lower(text_attribute(nc_, NC_GLOBAL, "featureType")) == "trajectory";

    // Contiguous ragged: a count variable with sample_dimension.
    int sample_dim = -1;
    for (const Variable& v : vars_) {
      const std::string sample = text_attribute(nc_, v.id, "sample_dimension");
      if (sample.empty()) continue;
      counts_ = &v;
      if (nc_inq_dimid(nc_.id, sample.c_str(), &sample_dim) != NC_NOERR)
        throw InputError(path, "variable " + v.name,
                         "sample_dimension '" + sample + "' does not exist");
    }

    // Candidate position/attribute variables and the line layout.
    std::vector<const Variable*> candidates;
    if (counts_) {
      for (const Variable& v : vars_)
        if (v.dims.size() == 1 && v.dims[0] == sample_dim && &v != counts_)
          candidates.push_back(&v);
    } else {
      // The shape every trajectory variable shares: (1 x) lines x points.
      std::vector<size_t> best;
      for (const Variable& v : vars_) {
        std::vector<size_t> s = v.shape;
        while (s.size() > 2 && s.front() == 1) s.erase(s.begin());
        if (s.size() == 2 && s[0] * s[1] > (best.empty() ? 0 : best[0] * best[1])) best = s;
      }
      if (best.empty())
        throw InputError(path, "",
                         std::string("no trajectory variables (expected ") +
                             (cf ? "x(trajectory, obs)" : "(1 x) trajectory x time arrays") +
                             " or a ragged count variable with sample_dimension)");
      line_count_ = best[0];
      row_points_ = best[1];
      for (const Variable& v : vars_) {
        std::vector<size_t> s = v.shape;
        while (s.size() > 2 && s.front() == 1) s.erase(s.begin());
        if (s == best) candidates.push_back(&v);
      }
    }
    for (int axis = 0; axis < 3; ++axis) axes_[axis] = find_axis(nc_, candidates, axis);
    if (!axes_[0] || !axes_[1])
      throw InputError(path, "", "cannot find x/longitude and y/latitude variables");
    for (const Variable* v : candidates)
      if (v != axes_[0] && v != axes_[1] && v != axes_[2]) attribute_vars_.push_back(v);
    for (const Variable* v : attribute_vars_) header_.attributes.push_back({v->name, {}});

    if (counts_) {
      // Observation ranges per line: [offsets_[i], offsets_[i + 1]).
      const std::vector<double> n = read_all(nc_, *counts_);
      size_t total = 1;
      for (size_t s : axes_[0]->shape) total *= s;
      size_t at = 0;
      offsets_.reserve(n.size() + 1);
      offsets_.push_back(0);
      for (size_t i = 0; i < n.size(); ++i) {
        if (!(n[i] >= 0) || at + static_cast<size_t>(n[i]) > total)
          throw InputError(path, "variable " + counts_->name + ", index " + std::to_string(i),
                           "count runs past the " + std::to_string(total) + " observations");
        at += static_cast<size_t>(n[i]);
        offsets_.push_back(at);
      }
      line_count_ = n.size();
    }

    header_.metadata["netcdf.layout"] = counts_ ? "cf-contiguous-ragged"
                                        : cf    ? "cf-multidimensional"
                                                : "lagranto";
    for (int axis = 0; axis < 3; ++axis)
      header_.metadata[std::string("netcdf.") + "xyz"[axis]] =
          axes_[axis] ? axes_[axis]->name : "(none: 0)";
  }

  bool next(LineSet& batch, uint64_t max_points) override {
    copy_lines(header_, 0, 0, batch);
    while (file_line_ < line_count_) {
      if (batch.line_count() > 0 && batch.point_count() >= max_points) break;
      const uint64_t room = max_points - batch.point_count();
      // File lines [file_line_, end) hold at most `room` points together (at least one line).
      size_t end;
      if (counts_) {
        const uint64_t p0 = offsets_[file_line_];
        const uint64_t limit = room > UINT64_MAX - p0 ? UINT64_MAX : p0 + room;
        end = size_t(std::upper_bound(offsets_.begin() + std::ptrdiff_t(file_line_ + 1),
                                      offsets_.end(), limit) -
                     offsets_.begin()) -
              1;
      } else {
        end = file_line_ + size_t(std::min<uint64_t>(room / row_points_, line_count_ - file_line_));
      }
      if (end == file_line_) {
        if (batch.line_count() > 0) break;
        end = file_line_ + 1;  // a line larger than max_points comes alone
      }
      // The rows read in double beside the batch's arrays, which grow by doubling.
      // A trajectory that comes alone: the rows read in double beside the batch's arrays, which
      // grow by doubling.
      if (batch.line_count() == 0 && end == file_line_ + 1) {
        const uint64_t rows = counts_ ? offsets_[end] - offsets_[file_line_] : row_points_;
        io::check_line_memory(nc_.path, lines_read_, rows,
                              8.0 * double(rows) * double(3 + attribute_vars_.size()) +
                                  2.0 * double(rows) * double(12 + 4 * attribute_vars_.size()),
                              "trajectory " + std::to_string(file_line_) + " of the file",
                              memory_limit_);
      }
      read_lines(file_line_, end, batch);
      file_line_ = end;
    }
    if (progress_) progress_(file_line_, line_count_);
    lines_read_ += batch.line_count();
    return batch.line_count() > 0;
  }

 private:
  // Reads file lines [first, end) of every variable and appends their valid points to `batch`.
  void read_lines(size_t first, size_t end, LineSet& batch) {
    const size_t begin_value = counts_ ? offsets_[first] : 0;  // of the values read
    for (int axis = 0; axis < 3; ++axis)
      if (axes_[axis]) read_rows(*axes_[axis], first, end - first, position_values_[axis]);
    attribute_values_.resize(attribute_vars_.size());
    for (size_t a = 0; a < attribute_vars_.size(); ++a)
      read_rows(*attribute_vars_[a], first, end - first, attribute_values_[a]);
    for (size_t line = first; line < end; ++line) {
      const size_t begin = counts_ ? offsets_[line] - begin_value : (line - first) * row_points_;
      const size_t stop = counts_ ? offsets_[line + 1] - begin_value : begin + row_points_;
      const size_t start_points = batch.point_count();
      for (size_t i = begin; i < stop; ++i) {
        bool bad = false;
        for (int axis = 0; axis < 3; ++axis)
          if (axes_[axis] && invalid(position_values_[axis][i], axes_[axis]->fill)) bad = true;
        if (bad) break;  // an invalid value ends the line
        batch.append_point(static_cast<float>(position_values_[0][i]),
                           static_cast<float>(position_values_[1][i]),
                           axes_[2] ? static_cast<float>(position_values_[2][i]) : 0.0f);
        for (size_t a = 0; a < attribute_vars_.size(); ++a) {
          const double v = attribute_values_[a][i];
          batch.attributes[a].values.push_back(
              attribute_vars_[a]->fill && v == *attribute_vars_[a]->fill ? NAN
                                                                         : static_cast<float>(v));
        }
      }
      if (batch.point_count() > start_points) batch.end_line();
    }
  }

  // Values of `v` for file lines [first, first + count): a range of observations (ragged) or of
  // rows of the (1 x) lines x points array.
  void read_rows(const Variable& v, size_t first, size_t count, std::vector<double>& out) {
    std::vector<size_t> start(v.shape.size(), 0), extent(v.shape.size(), 1);
    size_t total = 0;
    if (counts_) {
      start[0] = offsets_[first];
      extent[0] = total = offsets_[first + count] - offsets_[first];
    } else {
      const size_t line_dim = v.shape.size() - 2;
      start[line_dim] = first;
      extent[line_dim] = count;
      extent[line_dim + 1] = row_points_;
      total = count * row_points_;
    }
    out.resize(total);
    if (total == 0) return;
    nc_.check(nc_get_vara_double(nc_.id, v.id, start.data(), extent.data(), out.data()),
              "variable " + v.name);
  }

  Nc nc_;
  ProgressFn progress_;
  std::optional<uint64_t> memory_limit_;
  std::vector<Variable> vars_;
  const Variable* counts_ = nullptr;  // the ragged count variable, if any
  const Variable* axes_[3] = {nullptr, nullptr, nullptr};
  std::vector<const Variable*> attribute_vars_;
  size_t line_count_ = 0;          // lines of the file (some may read as no line)
  size_t row_points_ = 0;          // multidimensional: points per row
  std::vector<uint64_t> offsets_;  // ragged: first observation of each line, and the total
  size_t file_line_ = 0;           // first file line of the next batch
  std::vector<double> position_values_[3];
  std::vector<std::vector<double>> attribute_values_;
};

}  // namespace

std::unique_ptr<LineReader> open_netcdf(const std::string& path, const ReadOptions& options) {
  return std::make_unique<NetcdfReader>(path, options);
}

}  // namespace linebake::formats
