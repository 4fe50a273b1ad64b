// HDF5, linebake's plain layout (docs/formats.md):
//   /points            N x 3 float32 or float64
//   /line_offsets      L + 1 uint64 (or /line_lengths: L integers)
//   /attributes/<name> N floats (vertex attributes; '/', '%' and a leading '.' as %XX)
//   /line_attributes/<name> L floats
//   root string attributes: linebake_version and the line set's metadata.
// A linebake asset cache holds the same layout under /lines (docs/cache.md) and reads as its line
// set. Lines are read in batches: hyperslabs of the point and attribute datasets.

#include <sys/stat.h>

#include <algorithm>
#include <charconv>
#include <cstring>
#include <functional>
#include <nlohmann/json.hpp>

#include "cache/chunk_reader.hpp"
#include "core/error.hpp"
#include "core/h5.hpp"
#include "core/h5_probe.hpp"
#include "core/hash.hpp"
#include "core/interrupt.hpp"
#include "formats/formats.hpp"
#include "formats/io_util.hpp"

namespace linebake::formats {

namespace {

using h5::Handle;

void write_string_attribute(const std::string& path, hid_t object, const std::string& name,
                            const std::string& value) {
  if (!h5::write_string_attribute(object, name, value))
    throw OutputError(path, "cannot write attribute " + name);
}

void write_dataset(const std::string& path, hid_t location, const std::string& name,
                   hid_t file_type, hid_t memory_type, const void* data,
                   std::vector<hsize_t> dims) {
  Handle space(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr), H5Sclose);
  Handle dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
  H5Pset_obj_track_times(dcpl, false);  // the same input, the same bytes: no write times
  Handle dataset(
      H5Dcreate2(location, name.c_str(), file_type, space, H5P_DEFAULT, dcpl, H5P_DEFAULT),
      H5Dclose);
  if (!dataset.valid())
    throw OutputError(path, "cannot create dataset " + name + ": " + h5::last_error());
  hsize_t total = 1;
  for (hsize_t d : dims) total *= d;
  if (total > 0 && H5Dwrite(dataset, memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0)
    throw OutputError(path, "cannot write dataset " + name + ": " + h5::last_error());
  // The cache's block hash of the stored bytes (docs/cache.md): the reader checks it, so damaged
  // data is an error rather than different lines.
  const std::string hash = BlockHasher().update(data, total * H5Tget_size(memory_type)).hex();
  write_string_attribute(path, dataset, "xxh3_128_blocks", hash);
  throw_if_interrupted();  // between datasets
}

}  // namespace

namespace {

// A root attribute of numbers (h5py: f.attrs["dt"] = 0.25), up to 16 of them, as metadata text:
// "0.25", "1 2 3"; false for anything else (strings are read as strings, larger arrays left).
bool numeric_attribute_text(hid_t file, const std::string& name, std::string& text) {
  Handle attribute(H5Aopen(file, name.c_str(), H5P_DEFAULT), H5Aclose);
  if (!attribute.valid()) return false;
  Handle type(H5Aget_type(attribute), H5Tclose), space(H5Aget_space(attribute), H5Sclose);
  const H5T_class_t kind = H5Tget_class(type);
  const hssize_t count = H5Sget_simple_extent_npoints(space);
  if ((kind != H5T_INTEGER && kind != H5T_FLOAT) || count < 1 || count > 16) return false;
  if (!h5::damaged_number_type(type).empty()) return false;  // converting it reads past it
  std::vector<char> values(size_t(count) * 8);
  const bool is_signed = kind == H5T_INTEGER && H5Tget_sign(type) == H5T_SGN_2;
  const hid_t memory = kind == H5T_FLOAT ? H5T_NATIVE_DOUBLE
                       : is_signed       ? H5T_NATIVE_INT64
                                         : H5T_NATIVE_UINT64;
  if (H5Aread(attribute, memory, values.data()) < 0) return false;
  text.clear();
  for (hssize_t i = 0; i < count; ++i) {
    char digits[32];
    const char* at = values.data() + 8 * i;
    std::to_chars_result r{};
    if (kind == H5T_FLOAT) {
      double v;
      std::memcpy(&v, at, 8);
      r = std::to_chars(digits, digits + sizeof digits, v);  // the shortest that reads back
    } else if (is_signed) {
      int64_t v;
      std::memcpy(&v, at, 8);
      r = std::to_chars(digits, digits + sizeof digits, v);
    } else {
      uint64_t v;
      std::memcpy(&v, at, 8);
      r = std::to_chars(digits, digits + sizeof digits, v);
    }
    text += (i ? " " : "") + std::string(digits, r.ptr);
  }
  return true;
}

// Whether the root attribute `origin` is a frame, as write_hdf5 stores one: three finite
// floating-point numbers. Any other `origin` (text, integers, another count: another tool's grid
// corner or seed point) is kept as metadata "source_origin" (lines/origin.hpp).
bool frame_attribute(hid_t file, const std::string& text) {
  Handle attribute(H5Aopen(file, kOriginKey, H5P_DEFAULT), H5Aclose);
  if (!attribute.valid()) return false;
  Handle type(H5Aget_type(attribute), H5Tclose);
  return H5Tget_class(type) == H5T_FLOAT && parse_origin(text).has_value();
}

class Hdf5Reader : public LineReader {
 public:
  Hdf5Reader(const std::string& path, const ReadOptions& options)
      : path_(path),
        progress_(options.progress),
        memory_limit_(options.memory_limit),
        origin_(options.origin) {
    h5::init();
    if (H5Fis_hdf5(path.c_str()) <= 0)
      throw InputError(path, "", "not an HDF5 file (or unreadable)");
    // What this reader touches, walked first where a crash of libhdf5 cannot take us down.
    h5::probe(path, {"/points", "/line_offsets", "/line_lengths", "/attributes", "/line_attributes",
                     "/lines"});
    file_ = Handle(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
    if (!file_.valid()) throw InputError(path, "", "cannot open HDF5 file");
    if (H5Aexists(file_, "linebake_cache_format") > 0) {
      prefix_ = "/lines";
      std::string metadata;
      Handle group(H5Oopen(file_, "/lines", H5P_DEFAULT), H5Oclose);
      if (!group.valid()) throw InputError(path, "group /lines", "missing");
      if (h5::read_string_attribute(group, "metadata", metadata)) {
        try {
          header_.metadata =
              nlohmann::json::parse(metadata).get<std::map<std::string, std::string>>();
        } catch (const std::exception& e) {
          throw InputError(path, "group /lines", std::string("bad metadata: ") + e.what());
        }
      }
    } else {
      // A line file: its root string attributes are the metadata (as write_hdf5 stores it).
      std::vector<std::string> names;
      H5Aiterate2(
          file_, H5_INDEX_NAME, H5_ITER_INC, nullptr,
          [](hid_t, const char* name, const H5A_info_t*, void* data) -> herr_t {
            static_cast<std::vector<std::string>*>(data)->push_back(name);
            return 0;
          },
          &names);
      for (const std::string& name : names) {
        std::string value;
        if (name != "linebake_version" && (h5::read_string_attribute(file_, name, value) ||
                                           numeric_attribute_text(file_, name, value)))
          header_.metadata[name] = value;
      }
      if (has_origin(header_) && !frame_attribute(file_, header_.metadata.at(kOriginKey)))
        keep_as_source_origin(header_.metadata);
    }
    points_ = open(prefix_ + "/points");
    const std::vector<hsize_t> dims = h5::shape_of(points_.dataset);
    if (dims.size() != 2 || dims[1] != 3)
      throw InputError(path, "dataset " + points_.name, "expected shape N x 3");
    // The points are relative to the file's own origin (lines/origin.hpp): a cache's metadata,
    // a line file's root attribute `origin` (3 float64, as write_hdf5 stores it).
    frame_ = origin_of(header_, path);
    if (has_origin(header_)) set_origin(header_, frame_);  // written as linebake writes it
    // Points float32 does not hold exactly (float64; integers of more than 16 bits, such as
    // millimetres in int32 or int64) are read as double (read_points).
    Handle type(H5Dget_type(points_.dataset), H5Tclose);
    points_as_double_ =
        H5Tget_class(type) == H5T_FLOAT ? H5Tget_size(type) > 4 : H5Tget_size(type) > 2;
    const uint64_t n = dims[0];
    read_offsets(n);
    for (const std::string& name : h5::group_members(file_, prefix_ + "/attributes")) {
      attributes_.push_back(open(prefix_ + "/attributes/" + name, n));
      header_.attributes.push_back({h5::decode_link_name(name), {}});
    }
    for (const std::string& name : h5::group_members(file_, prefix_ + "/line_attributes")) {
      line_attributes_.push_back(open(prefix_ + "/line_attributes/" + name, offsets_.size() - 1));
      header_.line_attributes.push_back({h5::decode_link_name(name), {}});
    }
  }

  bool next(LineSet& batch, uint64_t max_points) override {
    copy_lines(header_, 0, 0, batch);
    const size_t count = offsets_.size() - 1;
    if (lines_read_ >= count) return false;
    const uint64_t first = lines_read_, p0 = offsets_[first];
    size_t end = size_t(std::upper_bound(offsets_.begin() + std::ptrdiff_t(first + 1),
                                         offsets_.end(), saturating_add(p0, max_points)) -
                        offsets_.begin()) -
                 1;
    end = std::max<size_t>(end, first + 1);
    const uint64_t p1 = offsets_[end];
    if (end == first + 1)  // a line that comes alone
      io::check_line_memory(
          path_, first, p1 - p0,
          double(p1 - p0) * double(12 + 4 * attributes_.size() + points_held_as_float64()) + 16.0,
          "dataset " + prefix_ + "/points, rows " + std::to_string(p0) + ".." + std::to_string(p1),
          memory_limit_);
    batch.positions.resize(3 * (p1 - p0));
    read_points(p0, p1 - p0, batch.positions.data());
    batch.line_offsets.resize(end - first + 1);
    for (size_t l = first; l <= end; ++l) batch.line_offsets[l - first] = offsets_[l] - p0;
    for (size_t a = 0; a < attributes_.size(); ++a) {
      batch.attributes[a].values.resize(p1 - p0);
      read(attributes_[a], p0, p1 - p0, batch.attributes[a].values.data());
    }
    for (size_t a = 0; a < line_attributes_.size(); ++a) {
      batch.line_attributes[a].values.resize(end - first);
      read(line_attributes_[a], first, end - first, batch.line_attributes[a].values.data());
    }
    lines_read_ = end;
    if (progress_) progress_(p1, offsets_.back());
    if (lines_read_ == count) {  // every row was read once, in order: check the stored hashes
      verify(points_);
      for (Data& d : attributes_) verify(d);
      for (Data& d : line_attributes_) verify(d);
    }
    return true;
  }

 private:
  // A dataset read front to back; `hash` is set when the file stores one to check it against.
  struct Data {
    std::string name;
    Handle dataset;
    std::string stored_hash;
    std::unique_ptr<BlockHasher> hash;
    std::unique_ptr<Hasher> flat_hash;  // caches before the block hash
  };

  Data open(const std::string& name, uint64_t expected = UINT64_MAX) const {
    Data d;
    d.name = name;
    check_dataset(name);
    // A chunk cache large enough that a chunk cut by one batch is still there for the next.
    Handle dapl(H5Pcreate(H5P_DATASET_ACCESS), H5Pclose);
    H5Pset_chunk_cache(dapl, 521, size_t{16} << 20, 1.0);
    d.dataset = Handle(H5Dopen2(file_, name.c_str(), dapl), H5Dclose);
    if (!d.dataset.valid()) throw InputError(path_, "dataset " + name, "missing");
    h5::check_claimed_size(path_, d.dataset, name);
    hsize_t total = 1;
    for (hsize_t v : h5::shape_of(d.dataset)) total *= v;
    if (expected != UINT64_MAX && total != expected)
      throw InputError(path_, "dataset " + name,
                       std::to_string(total) + " values, expected " + std::to_string(expected));
    Handle type(H5Dget_type(d.dataset), H5Tclose);
    if (H5Tget_class(type) == H5T_ENUM)
      throw InputError(path_, "dataset " + name,
                       "an enumeration (h5py stores bool arrays so), not numbers: store it as "
                       "integers or floats (numpy: .astype('u1'))");
    if (H5Tget_class(type) != H5T_FLOAT && H5Tget_class(type) != H5T_INTEGER)
      throw InputError(path_, "dataset " + name, "not numeric");
    check_filters(d.dataset, name);
    // The cache's hash covers the stored float32 bytes, which are what a float32 read returns.
    if (H5Tget_size(type) == 4 && H5Tget_class(type) == H5T_FLOAT) {
      if (h5::read_string_attribute(d.dataset, "xxh3_128_blocks", d.stored_hash))
        d.hash = std::make_unique<BlockHasher>();
      else if (h5::read_string_attribute(d.dataset, "xxh3_128", d.stored_hash))
        d.flat_hash = std::make_unique<Hasher>();
    }
    return d;
  }

  // Bytes a point's float64 copy takes while it is read (read_points).
  size_t points_held_as_float64() const { return points_as_double_ ? 24 : 0; }

  // Rows of the points relative to the origin asked for, if any: the file's coordinates and its
  // origin added and the new origin subtracted in double, then rounded once. Points float32 does
  // not hold exactly (float64, wide integers) are read as double with or without an origin, so
  // that a finite coordinate past float32's range (from the origin, where there is one) is
  // refused, as the other readers refuse it, instead of becoming an infinity in HDF5's
  // conversion.
  void read_points(uint64_t first, uint64_t count, float* out) {
    const auto refuse = [&](size_t i) {
      return InputError(
          path_, "dataset " + points_.name,
          "row " + std::to_string(first + i / 3) + ": a coordinate outside float32's range" +
              (origin_ ? " from the origin" : "") + " (magnitude above 3.4028235e38)");
    };
    if (!points_as_double_) {
      read(points_, first, count, out);
      if (!origin_) return;
      for (size_t i = 0; i < 3 * count; ++i)
        if (!to_local_in_range(to_world(out[i], frame_[i % 3]), (*origin_)[i % 3], out[i]))
          throw refuse(i);
      return;
    }
    std::vector<double> stored(3 * count);
    read(points_, first, count, H5T_NATIVE_DOUBLE, stored.data());
    for (size_t i = 0; i < stored.size(); ++i)
      if (origin_ ? !to_local_in_range(stored[i] + frame_[i % 3], (*origin_)[i % 3], out[i])
                  : !to_local_in_range(stored[i], 0.0, out[i]))
        throw refuse(i);
  }

  void read(Data& d, uint64_t first, uint64_t count, float* out) {
    read(d, first, count, H5T_NATIVE_FLOAT, out);
  }

  // `count` rows as `memory_type` (NATIVE_FLOAT or NATIVE_DOUBLE); a float32 read is hashed.
  void read(Data& d, uint64_t first, uint64_t count, hid_t memory_type, void* out) {
    if (count == 0) return;
    const std::vector<hsize_t> dims = h5::shape_of(d.dataset);
    const hsize_t columns = dims.size() == 2 ? dims[1] : 1;
    const hsize_t start[2] = {first, 0}, extent[2] = {count, columns};
    Handle file_space(H5Dget_space(d.dataset), H5Sclose);
    H5Sselect_hyperslab(file_space, H5S_SELECT_SET, start, nullptr, extent, nullptr);
    Handle memory_space(H5Screate_simple(int(dims.size()), extent, nullptr), H5Sclose);
    if (!read_direct(d.dataset, memory_type, first, count, out, d.name) &&
        H5Dread(d.dataset, memory_type, memory_space, file_space, H5P_DEFAULT, out) < 0)
      throw InputError(path_, "dataset " + d.name,
                       "cannot read rows " + std::to_string(first) + ".." +
                           std::to_string(first + count) + " (wrong type or corrupt data)");
    if (memory_type != H5T_NATIVE_FLOAT) return;  // hashes cover float32 data only (open)
    if (d.hash) d.hash->update(out, count * columns * sizeof(float));
    if (d.flat_hash) d.flat_hash->update(out, count * columns * sizeof(float));
  }

  // Chunks go through linebake's own decoder (cache/chunk_reader.hpp): a cache's (a cache read as
  // lines) as the cache reader's do, and those of other programs' line files where linebake
  // decodes their filters. False where HDF5 reads the dataset: a contiguous or compact one, or a
  // line file's with another filter.
  bool read_direct(hid_t dataset, hid_t type, uint64_t first, uint64_t count, void* out,
                   const std::string& name) const {
    try {
      if (prefix_.empty()) return read_rows_checked(dataset, type, first, count, out);
      return read_cache_rows_strict(dataset, type, first, count, out);
    } catch (const std::bad_alloc&) {
      throw BudgetExceeded(path_ + ": dataset " + name +
                           ": a chunk needs more memory than this process could allocate "
                           "(ulimit -v, the cgroup's limit, or the machine's memory)");
    } catch (const BudgetExceeded& e) {
      throw BudgetExceeded(path_ + ": dataset " + name + ": " + e.what());
    } catch (const Error& e) {
      throw InputError(path_, "dataset " + name, e.what());
    }
  }

  // A line file edited by another program keeps linebake's hash of the old data: say so.
  std::string checksum_mismatch() const {
    return prefix_.empty() ? "checksum mismatch: the data is corrupt, or was changed by another "
                             "program after linebake wrote it (deleting the dataset's attribute "
                             "xxh3_128_blocks reads it unchecked)"
                           : "checksum mismatch: the data is corrupt";
  }

  void verify(Data& d) const {
    if ((d.hash && d.hash->hex() != d.stored_hash) ||
        (d.flat_hash && d.flat_hash->hex() != d.stored_hash))
      throw InputError(path_, "dataset " + d.name, checksum_mismatch());
  }

  void read_offsets(uint64_t points) {
    const std::string offsets = prefix_ + "/line_offsets", lengths = prefix_ + "/line_lengths";
    if (H5Lexists(file_, offsets.c_str(), H5P_DEFAULT) > 0) {
      offsets_ = read_whole(offsets);
      if (offsets_.empty() && points == 0) offsets_.assign(1, 0);  // no lines, written as []
      if (offsets_.empty() || offsets_.front() != 0 || offsets_.back() != points)
        throw InputError(path_, "dataset " + offsets,
                         "must start at 0 and end at the point count " + std::to_string(points));
      for (size_t i = 1; i < offsets_.size(); ++i)
        if (offsets_[i] < offsets_[i - 1])
          throw InputError(path_, "dataset " + offsets, "decreases at index " + std::to_string(i));
    } else if (prefix_.empty() && H5Lexists(file_, lengths.c_str(), H5P_DEFAULT) > 0) {
      const std::vector<uint64_t> line_lengths = read_whole(lengths);
      offsets_.assign(1, 0);
      // Each length within the points left, so that the running sum can neither wrap past 2^64
      // (lengths near it had made offsets that go back) nor pass the point count.
      for (size_t i = 0; i < line_lengths.size(); ++i) {
        if (line_lengths[i] > points - offsets_.back())
          throw InputError(path_, "dataset " + lengths,
                           "lengths up to index " + std::to_string(i) +
                               " sum past the point count " + std::to_string(points) + " (line " +
                               std::to_string(i) + " has " + std::to_string(line_lengths[i]) + ")");
        offsets_.push_back(offsets_.back() + line_lengths[i]);
      }
      if (offsets_.back() != points)
        throw InputError(path_, "dataset " + lengths,
                         "lengths sum to " + std::to_string(offsets_.back()) +
                             ", not the point count " + std::to_string(points));
    } else {
      throw InputError(path_, "dataset " + offsets, "missing (and no /line_lengths)");
    }
  }

  // A group where a dataset belongs (an attribute's dataset under /attributes, say) is named as
  // such, not as a missing dataset.
  void check_dataset(const std::string& name) const {
    if (H5Lexists(file_, name.c_str(), H5P_DEFAULT) <= 0) return;  // "missing", by the caller
    Handle object(H5Oopen(file_, name.c_str(), H5P_DEFAULT), H5Oclose);
    if (object.valid() && H5Iget_type(object) == H5I_GROUP)
      throw InputError(path_, "group " + name,
                       "a group where a dataset belongs (attributes are datasets of one value a "
                       "point or a line, directly under /attributes or /line_attributes)");
  }

  // A filter this HDF5 cannot decode fails H5Dread with "wrong type or corrupt data": named
  // before, with the filter. Not for a cache's datasets, which linebake decodes itself
  // (read_direct), with or without HDF5's plugins.
  void check_filters(hid_t dataset, const std::string& name) const {
    if (!prefix_.empty()) return;
    Handle dcpl(H5Dget_create_plist(dataset), H5Pclose);
    const int filters = H5Pget_nfilters(dcpl);
    for (int i = 0; i < filters; ++i) {
      unsigned flags = 0, config = 0;
      size_t values = 0;
      char filter_name[256] = {};
      const H5Z_filter_t id = H5Pget_filter2(dcpl, unsigned(i), &flags, &values, nullptr,
                                             sizeof filter_name, filter_name, &config);
      if (id < 0 || H5Zfilter_avail(id) > 0) continue;
      throw InputError(
          path_, "dataset " + name,
          "compressed with HDF5 filter " + std::to_string(id) +
              (filter_name[0] ? std::string(" (") + filter_name + ")" : std::string()) +
              ", which this HDF5 cannot decode (no plugin for it on HDF5_PLUGIN_PATH)" +
              (id == 32000 ? "; LZF is h5py's own filter, known only inside h5py: write the "
                             "dataset with compression='gzip' instead"
                           : ""));
    }
  }

  // Offsets and lengths are counts: integers (HDF5's conversion to uint64 would take a
  // fraction's floor, and a negative value as 0, silently). True when they are signed.
  bool check_counts_type(hid_t dataset, const std::string& name) const {
    Handle type(H5Dget_type(dataset), H5Tclose);
    if (H5Tget_class(type) != H5T_INTEGER)
      throw InputError(path_, "dataset " + name,
                       std::string("holds ") +
                           (H5Tget_class(type) == H5T_FLOAT ? "floating-point" : "non-integer") +
                           " values; offsets and lengths are integers (numpy: .astype('u8'))");
    return H5Tget_sign(type) == H5T_SGN_2;
  }

  std::vector<uint64_t> read_whole(const std::string& name) const {
    check_dataset(name);
    Handle dataset(H5Dopen2(file_, name.c_str(), H5P_DEFAULT), H5Dclose);
    if (!dataset.valid()) throw InputError(path_, "dataset " + name, "missing");
    h5::check_claimed_size(path_, dataset, name);
    check_filters(dataset, name);
    // A line file's signed counts are read as int64 (the same 8 bytes) and checked for negatives.
    const bool is_signed = prefix_.empty() && check_counts_type(dataset, name);
    hsize_t total = 1;
    for (hsize_t d : h5::shape_of(dataset)) total *= d;
    // Each value takes at least a bit of the file: a larger count is a corrupt header.
    struct stat st {};
    if (::stat(path_.c_str(), &st) == 0 && total / 8 > uint64_t(st.st_size) + 1024)
      throw InputError(path_, "dataset " + name,
                       std::to_string(total) + " values cannot fit a file of " +
                           std::to_string(st.st_size) + " bytes");
    std::vector<uint64_t> values;
    try {
      values.resize(total);
    } catch (const std::bad_alloc&) {
      throw BudgetExceeded(path_ + ": dataset " + name + ": needs " +
                           std::to_string(total * sizeof(uint64_t)) +
                           " bytes of memory, more than this process could allocate (ulimit -v, "
                           "the cgroup's limit, or the machine's memory)");
    }
    const hid_t memory_type = is_signed ? H5T_NATIVE_INT64 : H5T_NATIVE_UINT64;
    if (total > 0 && !read_direct(dataset, memory_type, 0, total, values.data(), name) &&
        H5Dread(dataset, memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()) < 0)
      throw InputError(path_, "dataset " + name, "cannot read (wrong type or corrupt data)");
    for (size_t i = 0; is_signed && i < values.size(); ++i)
      if (int64_t(values[i]) < 0)
        throw InputError(path_, "dataset " + name,
                         "value " + std::to_string(int64_t(values[i])) + " at index " +
                             std::to_string(i) + " is negative");
    std::string stored;
    const size_t bytes = values.size() * sizeof(uint64_t);
    if ((h5::read_string_attribute(dataset, "xxh3_128_blocks", stored) &&
         stored != BlockHasher().update(values.data(), bytes).hex()) ||
        (h5::read_string_attribute(dataset, "xxh3_128", stored) &&
         stored != hash_bytes(values.data(), bytes)))
      throw InputError(path_, "dataset " + name, checksum_mismatch());
    return values;
  }

  std::string path_;
  ProgressFn progress_;
  std::optional<uint64_t> memory_limit_;
  std::optional<Origin> origin_;   // asked for
  Origin frame_{0, 0, 0};          // the file's
  bool points_as_double_ = false;  // wider than float32 holds (open)
  Handle file_;
  std::string prefix_;
  std::vector<uint64_t> offsets_;
  Data points_;
  std::vector<Data> attributes_, line_attributes_;
};

}  // namespace

std::unique_ptr<LineReader> open_hdf5(const std::string& path, const ReadOptions& options) {
  return std::make_unique<Hdf5Reader>(path, options);
}

void write_hdf5(const LineSet& lines, const std::string& path, const WriteOptions& options) {
  h5::init();
  Handle fcpl(H5Pcreate(H5P_FILE_CREATE), H5Pclose);
  H5Pset_obj_track_times(fcpl, false);  // nor for the root group
  Handle fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
  H5Pset_fclose_degree(fapl, H5F_CLOSE_STRONG);  // an error path closes everything in the file
  Handle file(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, fcpl, fapl), H5Fclose);
  if (!file.valid()) throw OutputError(path, "cannot create HDF5 file (" + h5::last_error() + ")");
  write_string_attribute(path, file, "linebake_version", LINEBAKE_VERSION);
  // The origin (lines/origin.hpp) as 3 float64, what h5py users read as f.attrs['origin']; the
  // points stay float32 relative to it.
  for (const auto& [key, value] : lines.metadata)
    if (key != kOriginKey) write_string_attribute(path, file, key, value);
  if (has_origin(lines)) {
    const Origin origin = origin_of(lines);
    const hsize_t three = 3;
    Handle space(H5Screate_simple(1, &three, nullptr), H5Sclose);
    Handle attribute(H5Acreate2(file, kOriginKey, H5T_IEEE_F64LE, space, H5P_DEFAULT, H5P_DEFAULT),
                     H5Aclose);
    if (!attribute.valid() || H5Awrite(attribute, H5T_NATIVE_DOUBLE, origin.data()) < 0)
      throw OutputError(path, "cannot write attribute origin: " + h5::last_error());
  }
  write_dataset(path, file, "points", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, lines.positions.data(),
                {lines.point_count(), 3});
  write_dataset(path, file, "line_offsets", H5T_STD_U64LE, H5T_NATIVE_UINT64,
                lines.line_offsets.data(), {lines.line_offsets.size()});
  if (options.progress) options.progress(1, 3);
  auto write_group = [&](const char* group, const std::vector<Attribute>& list) {
    if (list.empty()) return;
    // Creation order is tracked so attributes read back in the order written.
    Handle gcpl(H5Pcreate(H5P_GROUP_CREATE), H5Pclose);
    H5Pset_link_creation_order(gcpl, H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED);
    H5Pset_obj_track_times(gcpl, false);
    Handle g(H5Gcreate2(file, group, H5P_DEFAULT, gcpl, H5P_DEFAULT), H5Gclose);
    if (!g.valid())
      throw OutputError(
          path, std::string("cannot create group ") + group + " (" + h5::last_error() + ")");
    for (const Attribute& a : list)
      write_dataset(path, g, h5::encode_link_name(a.name), H5T_IEEE_F32LE, H5T_NATIVE_FLOAT,
                    a.values.data(), {a.values.size()});
  };
  write_group("attributes", lines.attributes);
  write_group("line_attributes", lines.line_attributes);
  if (H5Fflush(file, H5F_SCOPE_GLOBAL) < 0)
    throw OutputError(path, "write failed: " + h5::last_error());
  if (H5Fclose(file.release()) < 0) throw OutputError(path, "write failed: " + h5::last_error());
  if (options.progress) options.progress(3, 3);
}

}  // namespace linebake::formats
