// NetCDF trajectories.
//  - Lagranto / LineVis style: variables shaped (1 x) trajectory x time.
//  - CF discrete sampling geometry, featureType = "trajectory": multidimensional x(trajectory,
//    obs) (orthogonal or incomplete), or contiguous ragged arrays (a count variable whose
//    `sample_dimension` attribute names the observation dimension, observations back to back).
// Positions come from the variables marked axis X/Y/Z, else standard_name longitude/latitude/
// (altitude|height|air_pressure|depth), else the names x/lon/longitude, y/lat/latitude,
// z/p/pressure/alt/altitude/height/level/depth. A missing z is 0. Every other numeric variable of
// the same shape becomes a vertex attribute. A missing value (_FillValue, any missing_value, or
// outside valid_range / valid_min / valid_max: CF 2.5.1), NaN/Inf or |value| >= 1e20 in a
// position is a gap: the line ends there and the positions after it, if any, make a new line
// (as --on-invalid repair splits a line at a non-finite point, and plotting tools draw a NaN as a
// gap); a run of them at the end (incomplete arrays, Lagranto's invalid points) ends it. In an
// attribute it is NaN.
// Packed variables (CF 8.1) are unpacked: value * scale_factor + add_offset, in double; the fill
// value is compared with the packed value. Text attributes may be NC_CHAR or one NC_STRING.
// A ragged sample dimension may be longer than the counts need (CF 9.3: space reserved for later
// features, pre-filled with missing values); a position there is an error, not dropped.

#include <netcdf.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
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
  uint64_t file_bytes = 0;  // what any attribute's characters must fit in
  explicit Nc(const std::string& p) : path(p) {
    check_in_isolation(p, "NetCDF", [&p] { walk_netcdf_metadata(p); }, {}, {"netcdf", p});
    const int status = nc_open(p.c_str(), NC_NOWRITE, &id);
    if (status != NC_NOERR)
      throw InputError(p, "", std::string("cannot open as NetCDF: ") + nc_strerror(status));
    std::error_code error;
    file_bytes = std::filesystem::file_size(p, error);
    if (error) file_bytes = UINT64_MAX;
  }
  ~Nc() {
    if (id >= 0) nc_close(id);
  }
  void check(int status, const std::string& where) const {
    if (status != NC_NOERR) throw InputError(path, where, nc_strerror(status));
  }
};

// A text attribute: NC_CHAR, or a single NC_STRING (h5netcdf, xarray, setncattr_string). "" when
// absent or of another type.
std::string text_attribute(const Nc& nc, int var, const char* name) {
  size_t length = 0;
  nc_type type;
  if (nc_inq_att(nc.id, var, name, &type, &length) != NC_NOERR) return "";
  // Attributes are stored uncompressed: a damaged header can claim more characters than the
  // file holds (fuzz_netcdf: 1.6 GB in a 612-byte file, copied and trimmed for 42 s).
  char variable[NC_MAX_NAME + 1] = {};
  if (type == NC_CHAR && length > nc.file_bytes)
    throw InputError(nc.path,
                     std::string("attribute ") + name +
                         (var != NC_GLOBAL && nc_inq_varname(nc.id, var, variable) == NC_NOERR
                              ? std::string(" of variable ") + variable
                              : std::string()),
                     std::to_string(length) + " characters claimed, more than the file's " +
                         std::to_string(nc.file_bytes) + " bytes: the header is damaged");
  std::string s;
  if (type == NC_CHAR) {
    s.assign(length, '\0');
    if (length > 0 && nc_get_att_text(nc.id, var, name, s.data()) != NC_NOERR) return "";
  } else if (type == NC_STRING && length == 1) {
    char* value = nullptr;
    if (nc_get_att_string(nc.id, var, name, &value) != NC_NOERR) return "";
    if (value) s = value;
    nc_free_string(1, &value);
  }
  s.resize(s.find_last_not_of('\0') + 1);  // npos + 1 = 0: all NULs
  return s;
}

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

struct Variable {
  int id;
  std::string name;
  nc_type type;
  std::vector<int> dims;
  std::vector<size_t> shape;
  // Missing values (CF 2.5.1), as stored (packed units): _FillValue, every missing_value, and
  // values outside valid_range (or valid_min, valid_max).
  std::vector<double> missing;
  double valid_min = -HUGE_VAL, valid_max = HUGE_VAL;
  // Whether the valid range is in unpacked units: given as a type other than the packed data's
  // (a float range of short data), as netCDF-Java reads it; else packed units (CF 8.1).
  bool valid_range_unpacked = false;
  bool outside_valid_range(double raw) const {
    const double v = valid_range_unpacked ? unpack(raw) : raw;
    return v < valid_min || v > valid_max;
  }
  bool is_missing(double raw) const {
    return outside_valid_range(raw) ||
           std::find(missing.begin(), missing.end(), raw) != missing.end();
  }
  // CF 8.1 packing: unpacked = packed * scale + offset.
  bool packed = false;
  double scale = 1.0;
  double offset = 0.0;
  double unpack(double value) const { return packed ? value * scale + offset : value; }
};

// A numeric attribute's values (up to 16), none when absent or text.
std::vector<double> numbers_attribute(const Nc& nc, int var, const char* name) {
  nc_type type;
  size_t length = 0;
  if (nc_inq_att(nc.id, var, name, &type, &length) != NC_NOERR || type == NC_CHAR ||
      type == NC_STRING || type > NC_MAX_ATOMIC_TYPE || length == 0 || length > 16)
    return {};
  std::vector<double> values(length);
  if (nc_get_att_double(nc.id, var, name, values.data()) != NC_NOERR) return {};
  return values;
}

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
    Variable var{v, name, type, std::vector<int>(dims, dims + ndims), {}, {}};
    for (int d : var.dims) {
      size_t length;
      nc.check(nc_inq_dimlen(nc.id, d, &length), "variable " + var.name);
      var.shape.push_back(length);
    }
    const std::vector<double> fill = numbers_attribute(nc, v, "_FillValue");
    const std::vector<double> missing_value = numbers_attribute(nc, v, "missing_value");
    var.missing = fill;
    var.missing.insert(var.missing.end(), missing_value.begin(), missing_value.end());
    if (const std::vector<double> range = numbers_attribute(nc, v, "valid_range");
        range.size() == 2) {
      var.valid_min = range[0], var.valid_max = range[1];
    } else {
      if (const std::vector<double> low = numbers_attribute(nc, v, "valid_min"); low.size() == 1)
        var.valid_min = low[0];
      if (const std::vector<double> high = numbers_attribute(nc, v, "valid_max"); high.size() == 1)
        var.valid_max = high[0];
    }
    list.push_back(std::move(var));
  }
  return list;
}

// A packing attribute (scale_factor, add_offset) of `v`: absent, or one finite number.
std::optional<double> packing_attribute(const Nc& nc, const Variable& v, const char* name) {
  nc_type type;
  size_t length = 0;
  if (nc_inq_att(nc.id, v.id, name, &type, &length) != NC_NOERR) return std::nullopt;
  const std::string where = "variable " + v.name + ", attribute " + name;
  if (type == NC_CHAR || type == NC_STRING || type > NC_MAX_ATOMIC_TYPE)
    throw InputError(nc.path, where, "is not a number (CF packing needs a numeric value)");
  if (length != 1)
    throw InputError(nc.path, where, "has " + std::to_string(length) + " values, not one number");
  double value = 0;
  nc.check(nc_get_att_double(nc.id, v.id, name, &value), where);
  if (!std::isfinite(value))
    throw InputError(nc.path, where, "is not finite (" + std::to_string(value) + ")");
  return value;
}

void read_packing(const Nc& nc, Variable& v) {
  const std::optional<double> scale = packing_attribute(nc, v, "scale_factor");
  const std::optional<double> offset = packing_attribute(nc, v, "add_offset");
  v.packed = scale || offset;
  v.scale = scale.value_or(1.0);
  v.offset = offset.value_or(0.0);
  for (const char* name : {"valid_range", "valid_min", "valid_max"}) {
    nc_type type;
    size_t length = 0;
    if (v.packed && nc_inq_att(nc.id, v.id, name, &type, &length) == NC_NOERR && type != v.type)
      v.valid_range_unpacked = true;
  }
}

template <typename T>
double stored_as(const unsigned char* bytes) {
  T value;
  std::memcpy(&value, bytes, sizeof value);
  return static_cast<double>(value);
}

// The value the netCDF library gives data never written (_FillValue, else the default fill of
// the type); none for variables without fill or of types that are not numbers.
std::optional<double> library_fill(const Nc& nc, const Variable& v) {
  if (v.type < NC_BYTE || v.type > NC_UINT64 || v.type == NC_CHAR || v.type == NC_STRING)
    return std::nullopt;
  alignas(8) unsigned char bytes[8] = {};
  int no_fill = 0;
  if (nc_inq_var_fill(nc.id, v.id, &no_fill, bytes) != NC_NOERR || no_fill) return std::nullopt;
  switch (v.type) {
    case NC_BYTE:
      return stored_as<signed char>(bytes);
    case NC_UBYTE:
      return stored_as<unsigned char>(bytes);
    case NC_SHORT:
      return stored_as<short>(bytes);
    case NC_USHORT:
      return stored_as<unsigned short>(bytes);
    case NC_INT:
      return stored_as<int>(bytes);
    case NC_UINT:
      return stored_as<unsigned int>(bytes);
    case NC_INT64:
      return stored_as<long long>(bytes);
    case NC_UINT64:
      return stored_as<unsigned long long>(bytes);
    case NC_FLOAT:
      return stored_as<float>(bytes);
    case NC_DOUBLE:
      return stored_as<double>(bytes);
    default:
      return std::nullopt;
  }
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

// A number for messages, as short as it reads exactly enough (9 significant digits).
std::string number_text(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.9g", value);
  return text;
}

// Whether the stored (packed) value `raw` of position variable `v` is no position: a missing
// value (compared packed, CF 8.1), or NaN/Inf or |value| >= 1e20 once unpacked.
bool invalid(const Variable& v, double raw) {
  if (v.is_missing(raw)) return true;
  const double value = v.unpack(raw);
  return !std::isfinite(value) || std::fabs(value) >= 1e20;
}

// Lines are read in batches: multidimensional arrays as hyperslabs of whole rows (lines of the
// file), contiguous ragged arrays as ranges of observations (the counts are read at open).
class NetcdfReader : public LineReader {
 public:
  NetcdfReader(const std::string& path, const ReadOptions& options)
      : nc_(path),
        progress_(options.progress),
        memory_limit_(options.memory_limit),
        origin_(options.origin.value_or(Origin{0, 0, 0})) {
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
    // Packing of the variables read (only these: a bad scale_factor elsewhere does not matter).
    for (Variable& v : vars_)
      if (&v == axes_[0] || &v == axes_[1] || &v == axes_[2] ||
          std::find(attribute_vars_.begin(), attribute_vars_.end(), &v) != attribute_vars_.end())
        read_packing(nc_, v);

    if (counts_) {
      // Observation ranges per line: [offsets_[i], offsets_[i + 1]).
      const std::vector<double> n = read_all(nc_, *counts_);
      size_t total = 1;
      for (size_t s : axes_[0]->shape) total *= s;
      size_t at = 0;
      offsets_.reserve(n.size() + 1);
      offsets_.push_back(0);
      // CF 9.3.3: a feature not written yet has count 0 or a missing value: one the count
      // variable names, or the type's default fill where that cannot be a count (the signed
      // types' are negative: an int count never written); an unsigned type's is a real count
      // (a ubyte count of 255 points).
      const std::optional<double> unwritten = library_fill(nc_, *counts_);
      for (size_t i = 0; i < n.size(); ++i) {
        const double count =
            counts_->is_missing(n[i]) || (unwritten && *unwritten < 0 && n[i] == *unwritten) ? 0.0
                                                                                             : n[i];
        if (!(count >= 0) || count > double(total - at))
          throw InputError(path, "variable " + counts_->name + ", index " + std::to_string(i),
                           "count runs past the " + std::to_string(total) + " observations");
        at += static_cast<size_t>(count);
        offsets_.push_back(at);
      }
      line_count_ = n.size();
      check_unused_observations(sample_dim);
    }

    header_.metadata["netcdf.layout"] = counts_ ? "cf-contiguous-ragged"
                                        : cf    ? "cf-multidimensional"
                                                : "lagranto";
    for (int axis = 0; axis < 3; ++axis)
      header_.metadata[std::string("netcdf.") + "xyz"[axis]] =
          axes_[axis] ? axes_[axis]->name : "(none: 0)";
  }

  // Observations whose position is missing (an incomplete array's padding too), trajectories
  // split at them and the lines more they make, trajectories with no position at all.
  std::map<std::string, uint64_t> counts_read() const override {
    std::map<std::string, uint64_t> counts;
    uint64_t missing = 0;
    for (const MissingCounts& c : missing_) missing += c.total();
    if (missing > 0) counts["netcdf.missing_observations"] = missing;
    if (split_trajectories_ > 0) {
      counts["netcdf.split_trajectories"] = split_trajectories_;
      counts["netcdf.lines_from_splits"] = lines_from_splits_;
    }
    if (trajectories_without_position_ > 0)
      counts["netcdf.trajectories_without_position"] = trajectories_without_position_;
    return counts;
  }

  bool next(LineSet& batch, uint64_t max_points) override {
    copy_lines(header_, 0, 0, batch);
    if (serve_pending(batch, max_points)) {
      lines_read_ += batch.line_count();
      return true;
    }
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
      // A trajectory that comes alone: the rows read in double beside its lines' arrays, which
      // grow by doubling, and their copy into the batch. Its gaps may make it several lines,
      // which come as batches of their own within max_points.
      if (batch.line_count() == 0 && end == file_line_ + 1) {
        const uint64_t rows = counts_ ? offsets_[end] - offsets_[file_line_] : row_points_;
        io::check_line_memory(nc_.path, lines_read_, rows,
                              8.0 * double(rows) * double(3 + attribute_vars_.size()) +
                                  3.0 * double(rows) * double(12 + 4 * attribute_vars_.size()),
                              "trajectory " + std::to_string(file_line_) + " of the file",
                              memory_limit_);
        copy_lines(header_, 0, 0, pending_);
        read_lines(file_line_, end, pending_);
        file_line_ = end;
        if (serve_pending(batch, max_points)) break;
        continue;
      }
      read_lines(file_line_, end, batch);
      file_line_ = end;
    }
    if (progress_) progress_(file_line_, line_count_);
    lines_read_ += batch.line_count();
    if (batch.line_count() == 0) refuse_all_missing();
    return batch.line_count() > 0;
  }

 private:
  // Why positions were missing, by the first axis that ruled each out: a missing value
  // (_FillValue, missing_value), outside the valid range, or not finite (|value| >= 1e20 too).
  struct MissingCounts {
    uint64_t missing_value = 0, outside_range = 0, not_finite = 0;
    uint64_t total() const { return missing_value + outside_range + not_finite; }
  };

  void count_missing(int axis, double raw) {
    const Variable& v = *axes_[axis];
    MissingCounts& c = missing_[axis];
    // A fill value lies outside the valid range as CF 2.5.1 recommends, and the library's
    // default fills are past 1e20: a file not written yet counts as missing values and
    // non-finite positions, not as a range that cut data out.
    const double value = v.unpack(raw);
    if (std::find(v.missing.begin(), v.missing.end(), raw) != v.missing.end())
      ++c.missing_value;
    else if (!std::isfinite(value) || std::fabs(value) >= 1e20)
      ++c.not_finite;
    else
      ++c.outside_range;
  }

  // A file with observations none of which is a position, some ruled out by a valid range,
  // would read as no line at all: said as an error, with each position variable's reasons
  // (counted by the first axis that ruled an observation out), rather than an empty line set.
  // The usual cause is a valid range meant in unpacked units but stored in the packed type,
  // which CF 8.1 compares with the packed values.
  void refuse_all_missing() const {
    if (observations_ == 0 || lines_read_ > 0) return;
    // Fill values alone are a file not written yet (CF 9.3.3 lets a writer reserve its space):
    // no line, as a header without lines is.
    bool range_cut = false;
    for (const MissingCounts& c : missing_) range_cut = range_cut || c.outside_range > 0;
    if (!range_cut) return;
    std::string why;
    for (int axis = 0; axis < 3; ++axis) {
      const MissingCounts& c = missing_[axis];
      if (c.total() == 0) continue;
      const Variable& v = *axes_[axis];
      std::string reasons;
      const auto add = [&](uint64_t n, const std::string& what) {
        if (n > 0) reasons += (reasons.empty() ? "" : ", ") + std::to_string(n) + " " + what;
      };
      add(c.missing_value, "equal to its _FillValue or missing_value");
      std::string range = "[" + number_text(v.valid_min) + ", " + number_text(v.valid_max) + "]";
      if (v.packed && !v.valid_range_unpacked)
        range += " of the stored values, [" + number_text(v.unpack(v.valid_min)) + ", " +
                 number_text(v.unpack(v.valid_max)) +
                 "] unpacked (CF 8.1 compares a valid range of the packed type with the packed "
                 "values)";
      add(c.outside_range, "outside the valid range " + range);
      add(c.not_finite, "not finite or of magnitude 1e20 or more");
      why += (why.empty() ? "" : "; ") + ("'" + v.name + "' ") + reasons;
    }
    throw InputError(nc_.path, "positions",
                     "none of the file's " + std::to_string(observations_) +
                         " observations is a position (CF 2.5.1 missing values): " + why);
  }

  // Lines of a trajectory read alone that are still to come: into `batch` (empty), as many as
  // max_points holds (one at least). False when none are left.
  bool serve_pending(LineSet& batch, uint64_t max_points) {
    const size_t lines = pending_.line_count();
    if (pending_line_ >= lines) return false;
    size_t end = pending_line_ + 1;
    const uint64_t first = pending_.line_offsets[pending_line_];
    while (end < lines && pending_.line_offsets[end + 1] - first <= max_points) ++end;
    copy_lines(pending_, pending_line_, end, batch);
    pending_line_ = end;
    if (pending_line_ == lines) {
      copy_lines(header_, 0, 0, pending_);
      pending_line_ = 0;
    }
    return true;
  }

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
      size_t start_points = batch.point_count();
      uint64_t made = 0;  // lines this trajectory makes
      for (size_t i = begin; i < stop; ++i) {
        bool bad = false;
        for (int axis = 0; axis < 3; ++axis)
          if (axes_[axis] && invalid(*axes_[axis], position_values_[axis][i])) {
            if (!bad) count_missing(axis, position_values_[axis][i]);
            bad = true;
          }
        ++observations_;
        if (bad) {  // a gap: the positions after it make the next line
          if (batch.point_count() > start_points) {
            batch.end_line();
            ++made;
          }
          start_points = batch.point_count();
          continue;
        }
        // Unpacked in double, the origin (lines/origin.hpp) subtracted, then rounded.
        batch.append_point(
            to_local(axes_[0]->unpack(position_values_[0][i]), origin_[0]),
            to_local(axes_[1]->unpack(position_values_[1][i]), origin_[1]),
            to_local(axes_[2] ? axes_[2]->unpack(position_values_[2][i]) : 0.0, origin_[2]));
        for (size_t a = 0; a < attribute_vars_.size(); ++a) {
          const Variable& var = *attribute_vars_[a];
          const double v = attribute_values_[a][i];  // packed: the fill is compared as stored
          batch.attributes[a].values.push_back(
              var.is_missing(v) ? NAN : static_cast<float>(var.unpack(v)));
        }
      }
      if (batch.point_count() > start_points) {
        batch.end_line();
        ++made;
      }
      if (made > 1) {
        ++split_trajectories_;
        lines_from_splits_ += made - 1;
      }
      if (made == 0) ++trajectories_without_position_;
    }
  }

  // Ragged: the observations past the counts (offsets_.back()) are space CF lets a writer reserve
  // for later features, pre-filled with missing values (CF 9.3). A position there would be data
  // the counts leave out: an error rather than lines dropped silently. Read in chunks.
  void check_unused_observations(int sample_dim) {
    const uint64_t used = offsets_.back();
    size_t total = 1;
    for (size_t s : axes_[0]->shape) total *= s;
    if (used >= total) return;
    std::optional<double> fills[3];
    for (int axis = 0; axis < 3; ++axis)
      if (axes_[axis]) fills[axis] = library_fill(nc_, *axes_[axis]);
    constexpr size_t chunk = size_t{1} << 16;
    std::vector<double> values[3];
    for (size_t at = used; at < total; at += chunk) {
      size_t start = at, extent = std::min(chunk, total - at);
      for (int axis = 0; axis < 3; ++axis) {
        if (!axes_[axis]) continue;
        values[axis].resize(extent);
        nc_.check(nc_get_vara_double(nc_.id, axes_[axis]->id, &start, &extent, values[axis].data()),
                  "variable " + axes_[axis]->name);
      }
      for (size_t i = 0; i < extent; ++i) {
        bool missing = false;
        for (int axis = 0; axis < 3; ++axis)
          if (axes_[axis] && (invalid(*axes_[axis], values[axis][i]) ||
                              (fills[axis] && values[axis][i] == *fills[axis])))
            missing = true;
        if (missing) continue;
        char dim_name[NC_MAX_NAME + 1] = "";
        nc_inq_dimname(nc_.id, sample_dim, dim_name);
        throw InputError(nc_.path, "variable " + counts_->name,
                         "the counts sum to " + std::to_string(used) + " observations but " +
                             "dimension " + dim_name + " has " + std::to_string(total) +
                             ", and observation " + std::to_string(at + i) +
                             " past the counts holds a position (CF allows only missing " +
                             "values in unused observations)");
      }
    }
    header_.metadata["netcdf.unused_observations"] = std::to_string(total - used);
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
  Origin origin_;
  std::vector<Variable> vars_;
  const Variable* counts_ = nullptr;  // the ragged count variable, if any
  const Variable* axes_[3] = {nullptr, nullptr, nullptr};
  std::vector<const Variable*> attribute_vars_;
  size_t line_count_ = 0;          // lines of the file (some may read as no line)
  size_t row_points_ = 0;          // multidimensional: points per row
  std::vector<uint64_t> offsets_;  // ragged: first observation of each line, and the total
  size_t file_line_ = 0;           // first file line of the next batch
  LineSet pending_;                // lines of a trajectory read alone, from pending_line_ on
  size_t pending_line_ = 0;
  std::vector<double> position_values_[3];
  std::vector<std::vector<double>> attribute_values_;
  uint64_t observations_ = 0;  // read so far, missing positions included
  MissingCounts missing_[3];   // positions missing, by the first axis that ruled them out
  uint64_t split_trajectories_ = 0, lines_from_splits_ = 0, trajectories_without_position_ = 0;
};

}  // namespace

std::unique_ptr<LineReader> open_netcdf(const std::string& path, const ReadOptions& options) {
  return std::make_unique<NetcdfReader>(path, options);
}

}  // namespace linebake::formats
