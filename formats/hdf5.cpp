// HDF5, linebake's plain layout (docs/formats.md):
//   /points            N x 3 float32 or float64
//   /line_offsets      L + 1 uint64 (or /line_lengths: L integers)
//   /attributes/<name> N floats (vertex attributes; '/', '%' and a leading '.' as %XX)
//   /line_attributes/<name> L floats
//   root string attributes: linebake_version and the line set's metadata.

#include <functional>

#include "core/error.hpp"
#include "core/h5.hpp"
#include "formats/formats.hpp"

namespace linebake::formats {

namespace {

using h5::Handle;

template <typename T>
std::vector<T> read_dataset(const std::string& path, hid_t file, const std::string& name,
                            hid_t memory_type, size_t expected_elements) {
  Handle dataset(H5Dopen2(file, name.c_str(), H5P_DEFAULT), H5Dclose);
  if (!dataset.valid()) throw InputError(path, "dataset " + name, "missing");
  hsize_t total = 1;
  for (hsize_t d : h5::shape_of(dataset)) total *= d;
  if (expected_elements != SIZE_MAX && total != expected_elements)
    throw InputError(
        path, "dataset " + name,
        std::to_string(total) + " values, expected " + std::to_string(expected_elements));
  std::vector<T> values(total);
  if (total > 0 && H5Dread(dataset, memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()) < 0)
    throw InputError(path, "dataset " + name, "cannot read (wrong type or corrupt data)");
  return values;
}

void write_string_attribute(const std::string& path, hid_t object, const std::string& name,
                            const std::string& value) {
  if (!h5::write_string_attribute(object, name, value))
    throw OutputError(path, "cannot write attribute " + name);
}

void write_dataset(const std::string& path, hid_t location, const std::string& name,
                   hid_t file_type, hid_t memory_type, const void* data,
                   std::vector<hsize_t> dims) {
  Handle space(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr), H5Sclose);
  Handle dataset(
      H5Dcreate2(location, name.c_str(), file_type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
      H5Dclose);
  if (!dataset.valid()) throw OutputError(path, "cannot create dataset " + name);
  hsize_t total = 1;
  for (hsize_t d : dims) total *= d;
  if (total > 0 && H5Dwrite(dataset, memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0)
    throw OutputError(path, "cannot write dataset " + name);
}

}  // namespace

LineSet read_hdf5(const std::string& path, const ReadOptions& options) {
  h5::init();
  if (H5Fis_hdf5(path.c_str()) <= 0) throw InputError(path, "", "not an HDF5 file (or unreadable)");
  Handle file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!file.valid()) throw InputError(path, "", "cannot open HDF5 file");

  LineSet lines;
  {
    Handle dataset(H5Dopen2(file, "/points", H5P_DEFAULT), H5Dclose);
    if (!dataset.valid()) throw InputError(path, "dataset /points", "missing");
    const std::vector<hsize_t> dims = h5::shape_of(dataset);
    if (dims.size() != 2 || dims[1] != 3)
      throw InputError(path, "dataset /points", "expected shape N x 3");
  }
  lines.positions = read_dataset<float>(path, file, "/points", H5T_NATIVE_FLOAT, SIZE_MAX);
  const size_t n = lines.point_count();
  if (options.progress) options.progress(1, 3);
  if (H5Lexists(file, "/line_offsets", H5P_DEFAULT) > 0) {
    lines.line_offsets =
        read_dataset<uint64_t>(path, file, "/line_offsets", H5T_NATIVE_UINT64, SIZE_MAX);
    if (lines.line_offsets.empty() || lines.line_offsets.front() != 0 ||
        lines.line_offsets.back() != n)
      throw InputError(path, "dataset /line_offsets",
                       "must start at 0 and end at the point count " + std::to_string(n));
    for (size_t i = 1; i < lines.line_offsets.size(); ++i)
      if (lines.line_offsets[i] < lines.line_offsets[i - 1])
        throw InputError(path, "dataset /line_offsets", "decreases at index " + std::to_string(i));
  } else if (H5Lexists(file, "/line_lengths", H5P_DEFAULT) > 0) {
    const auto lengths =
        read_dataset<uint64_t>(path, file, "/line_lengths", H5T_NATIVE_UINT64, SIZE_MAX);
    lines.line_offsets.assign(1, 0);
    for (uint64_t length : lengths)
      lines.line_offsets.push_back(lines.line_offsets.back() + length);
    if (lines.line_offsets.back() != n)
      throw InputError(path, "dataset /line_lengths",
                       "lengths sum to " + std::to_string(lines.line_offsets.back()) +
                           ", not the point count " + std::to_string(n));
  } else {
    throw InputError(path, "dataset /line_offsets", "missing (and no /line_lengths)");
  }
  for (const std::string& name : h5::group_members(file, "/attributes"))
    lines.attributes.push_back(
        {h5::decode_link_name(name),
         read_dataset<float>(path, file, "/attributes/" + name, H5T_NATIVE_FLOAT, n)});
  for (const std::string& name : h5::group_members(file, "/line_attributes"))
    lines.line_attributes.push_back(
        {h5::decode_link_name(name), read_dataset<float>(path, file, "/line_attributes/" + name,
                                                         H5T_NATIVE_FLOAT, lines.line_count())});
  if (options.progress) options.progress(3, 3);
  return lines;
}

void write_hdf5(const LineSet& lines, const std::string& path, const WriteOptions& options) {
  h5::init();
  Handle fcpl(H5Pcreate(H5P_FILE_CREATE), H5Pclose);
  Handle file(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, fcpl, H5P_DEFAULT), H5Fclose);
  if (!file.valid()) throw OutputError(path, "cannot create HDF5 file");
  write_string_attribute(path, file, "linebake_version", LINEBAKE_VERSION);
  for (const auto& [key, value] : lines.metadata) write_string_attribute(path, file, key, value);
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
    Handle g(H5Gcreate2(file, group, H5P_DEFAULT, gcpl, H5P_DEFAULT), H5Gclose);
    if (!g.valid()) throw OutputError(path, std::string("cannot create group ") + group);
    for (const Attribute& a : list)
      write_dataset(path, g, h5::encode_link_name(a.name), H5T_IEEE_F32LE, H5T_NATIVE_FLOAT,
                    a.values.data(), {a.values.size()});
  };
  write_group("attributes", lines.attributes);
  write_group("line_attributes", lines.line_attributes);
  if (H5Fflush(file, H5F_SCOPE_GLOBAL) < 0) throw OutputError(path, "flush failed");
  if (options.progress) options.progress(3, 3);
}

}  // namespace linebake::formats
