#include "core/h5.hpp"

#include <H5PLpublic.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <mutex>

#include "core/error.hpp"

namespace linebake::h5 {

thread_local int LeaveOpenOnUnwind::depth_ = 0;

void init() {
  static std::once_flag once;
  std::call_once(once, [] {
    // No cleanup at exit: linebake closes its files itself, and HDF5 1.10's atexit cleanup
    // crashes on a file whose close failed (a full disk): HDFFV-11052, fixed only after 1.10.
    // Must come before any other HDF5 call, so main() calls init() first.
    H5dont_atexit();
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    // Debian installs filter plugins here (hdf5-filter-plugin, hdf5-filter-plugin-blosc-serial);
    // HDF5's compiled-in default (/usr/local/hdf5/lib/plugin) is not it. HDF5_PLUGIN_PATH, when
    // set, still comes first.
    for (const char* dir :
         {LINEBAKE_HDF5_PLUGIN_DIR, "/usr/lib/x86_64-linux-gnu/hdf5/serial/plugins",
          "/usr/lib/aarch64-linux-gnu/hdf5/serial/plugins"}) {
      std::error_code ec;
      if (dir[0] && std::filesystem::is_directory(dir, ec)) H5PLappend(dir);
    }
  });
  // HDF5's error printing is a per-thread setting in a thread-safe build: turned off on each
  // thread that reaches HDF5 through here (Python threads baking printed HDF5-DIAG stacks).
  thread_local bool quiet = false;
  if (!quiet) H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr), quiet = true;
}

bool is_hdf5_file(const std::string& path) {
  init();
  return H5Fis_hdf5(path.c_str()) > 0;
}

std::string last_error() {
  // Upward starts at the innermost (most specific) entry: keep the first description.
  std::string message;
  auto innermost = [](unsigned, const H5E_error2_t* e, void* data) -> herr_t {
    auto& out = *static_cast<std::string*>(data);
    if (out.empty() && e->desc && *e->desc) out = e->desc;
    return 0;
  };
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, innermost, &message);
  // A failed write describes itself at length ("file write failed: time = ..., filename = ...,
  // errno = 28, error message = 'No space left on device', buf = ..."): keep the reason.
  const std::string key = "error message = '";
  const size_t at = message.find(key);
  if (at != std::string::npos) {
    const size_t end = message.find('\'', at + key.size());
    message = message.substr(at + key.size(),
                             end == std::string::npos ? std::string::npos : end - at - key.size());
  }
  for (char& c : message)
    if (c == '\n' || c == '\r') c = ' ';
  return message;
}

std::string encode_link_name(const std::string& name) {
  std::string out;
  for (size_t i = 0; i < name.size(); ++i) {
    const char c = name[i];
    if (c == '/' || c == '%' || (i == 0 && c == '.')) {
      char hex[4];
      std::snprintf(hex, sizeof hex, "%%%02X", static_cast<unsigned char>(c));
      out += hex;
    } else {
      out += c;
    }
  }
  return out.empty() ? "%" : out;  // "%" alone: the empty name
}

std::string decode_link_name(const std::string& name) {
  if (name == "%") return "";
  std::string out;
  for (size_t i = 0; i < name.size(); ++i) {
    if (name[i] == '%' && i + 2 < name.size()) {
      out += static_cast<char>(std::stoi(name.substr(i + 1, 2), nullptr, 16));
      i += 2;
    } else {
      out += name[i];
    }
  }
  return out;
}

std::vector<hsize_t> shape_of(hid_t dataset) {
  Handle space(H5Dget_space(dataset), H5Sclose);
  const int rank = H5Sget_simple_extent_ndims(space);
  std::vector<hsize_t> dims(rank > 0 ? static_cast<size_t>(rank) : 0);
  if (rank > 0) H5Sget_simple_extent_dims(space, dims.data(), nullptr);
  return dims;
}

bool path_exists(hid_t location, const std::string& path) {
  if (path == "/") return true;
  for (size_t at = path.find('/', 1); at != std::string::npos; at = path.find('/', at + 1))
    if (H5Lexists(location, path.substr(0, at).c_str(), H5P_DEFAULT) <= 0) return false;
  return H5Lexists(location, path.c_str(), H5P_DEFAULT) > 0;
}

uint64_t max_decoded_bytes(hid_t dataset) {
  const uint64_t stored = H5Dget_storage_size(dataset);
  Handle dcpl(H5Dget_create_plist(dataset), H5Pclose);
  uint64_t ratio = 1;
  const int filters = dcpl.valid() ? H5Pget_nfilters(dcpl) : 0;
  for (int f = 0; f < filters; ++f) {
    unsigned flags = 0, config = 0;
    size_t values = 0;
    const H5Z_filter_t id = H5Pget_filter2(dcpl, static_cast<unsigned>(f), &flags, &values, nullptr,
                                           0, nullptr, &config);
    const uint64_t best = id == H5Z_FILTER_SHUFFLE || id == H5Z_FILTER_FLETCHER32 ? 1
                          : id == H5Z_FILTER_DEFLATE                              ? 1032
                          : id == 32004 /* LZ4 */                                 ? 255
                                                  : uint64_t{1} << 17;
    ratio = std::min<uint64_t>(ratio * best, uint64_t{1} << 17);
  }
  const uint64_t slack = uint64_t{1} << 20;
  return stored > (UINT64_MAX - slack) / ratio ? UINT64_MAX : stored * ratio + slack;
}

namespace {

uint64_t shape_bytes(hid_t dataset) {
  Handle type(H5Dget_type(dataset), H5Tclose);
  uint64_t bytes = type.valid() ? H5Tget_size(type) : 1;
  for (hsize_t n : shape_of(dataset))
    bytes = n != 0 && bytes > UINT64_MAX / n ? UINT64_MAX : bytes * n;
  return bytes;
}

std::string damaged_compact_storage(hid_t dataset, hid_t dcpl) {
  if (H5Pget_layout(dcpl) != H5D_COMPACT) return "";
  const uint64_t bytes = shape_bytes(dataset), stored = H5Dget_storage_size(dataset);
  if (stored == bytes) return "";
  return "compact dataset whose shape claims " + std::to_string(bytes) + " bytes, but it stores " +
         std::to_string(stored) + ": the header is damaged";
}

// HDF5's scale-offset and N-bit filters (H5Zscaleoffset.c, H5Znbit.c) keep the chunk's element
// count in parameter 2 and the element size in parameter 4, set from the layout and the type
// when the dataset is made; decoding allocates and fills count x size bytes.
std::string damaged_filter_parameters(hid_t dataset, hid_t dcpl) {
  const int filters = H5Pget_nfilters(dcpl);
  for (int f = 0; f < filters; ++f) {
    unsigned flags = 0, config = 0, values[32] = {};
    size_t count = sizeof values / sizeof values[0];
    const H5Z_filter_t id =
        H5Pget_filter2(dcpl, static_cast<unsigned>(f), &flags, &count, values, 0, nullptr, &config);
    if (id != H5Z_FILTER_SCALEOFFSET && id != H5Z_FILTER_NBIT) continue;
    const std::string filter = id == H5Z_FILTER_NBIT ? "N-bit" : "scale-offset";
    if (count < 5)
      return "its " + filter + " filter has " + std::to_string(count) +
             " parameters, fewer than HDF5 writes: the header is damaged";
    hsize_t chunk[H5S_MAX_RANK] = {};
    const int rank =
        H5Pget_layout(dcpl) == H5D_CHUNKED ? H5Pget_chunk(dcpl, H5S_MAX_RANK, chunk) : -1;
    if (rank < 1) return "its " + filter + " filter has no chunk layout: the header is damaged";
    uint64_t elements = 1;
    for (int i = 0; i < rank; ++i)
      elements =
          chunk[i] != 0 && elements > UINT64_MAX / chunk[i] ? UINT64_MAX : elements * chunk[i];
    Handle type(H5Dget_type(dataset), H5Tclose);
    const uint64_t size = type.valid() ? H5Tget_size(type) : 0;
    if (values[2] != elements || values[4] != size)
      return "its " + filter + " filter's parameters say a chunk holds " +
             std::to_string(values[2]) + " values of " + std::to_string(values[4]) +
             " bytes, but its layout and type say " + std::to_string(elements) + " of " +
             std::to_string(size) + ": the header is damaged";
  }
  return "";
}

}  // namespace

std::string damaged_number_type(hid_t type) {
  const H5T_class_t type_class = H5Tget_class(type);
  if (type_class != H5T_FLOAT && type_class != H5T_INTEGER) return "";
  const size_t bits = 8 * H5Tget_size(type), precision = H5Tget_precision(type);
  const int offset = H5Tget_offset(type);
  std::string wrong;
  if (bits == 0 || precision == 0 || offset < 0 || size_t(offset) + precision > bits)
    wrong = std::to_string(precision) + " bits of precision at bit " + std::to_string(offset);
  if (wrong.empty() && type_class == H5T_FLOAT) {
    size_t sign = 0, exponent = 0, exponent_bits = 0, mantissa = 0, mantissa_bits = 0;
    if (H5Tget_fields(type, &sign, &exponent, &exponent_bits, &mantissa, &mantissa_bits) < 0 ||
        sign >= bits || exponent_bits == 0 || exponent + exponent_bits > bits ||
        mantissa_bits == 0 || mantissa + mantissa_bits > bits)
      wrong = "a sign at bit " + std::to_string(sign) + ", " + std::to_string(exponent_bits) +
              " exponent bits at bit " + std::to_string(exponent) + " and " +
              std::to_string(mantissa_bits) + " mantissa bits at bit " + std::to_string(mantissa);
  }
  if (wrong.empty()) return "";
  return "its " + std::string(type_class == H5T_FLOAT ? "floating-point" : "integer") +
         " type of " + std::to_string(bits / 8) + " bytes says " + wrong +
         ", outside its bytes: the header is damaged";
}

std::string damaged_storage(hid_t dataset) {
  Handle number(H5Dget_type(dataset), H5Tclose);
  const std::string type = number.valid() ? damaged_number_type(number) : "";
  if (!type.empty()) return type;
  Handle dcpl(H5Dget_create_plist(dataset), H5Pclose);
  if (!dcpl.valid()) return "";
  const std::string compact = damaged_compact_storage(dataset, dcpl);
  return compact.empty() ? damaged_filter_parameters(dataset, dcpl) : compact;
}

void check_claimed_size(const std::string& path, hid_t dataset, const std::string& name) {
  const std::string damaged = damaged_storage(dataset);
  if (!damaged.empty()) throw InputError(path, "dataset " + name, damaged);
  // Nothing stored to compare with: data never written (all fill value), a virtual dataset or
  // one in external files. Their readers size batches, not the whole shape.
  Handle dcpl(H5Dget_create_plist(dataset), H5Pclose);
  H5D_space_status_t status = H5D_SPACE_STATUS_ERROR;
  if (!dcpl.valid() || H5Pget_layout(dcpl) == H5D_VIRTUAL || H5Pget_external_count(dcpl) > 0 ||
      H5Dget_space_status(dataset, &status) < 0 || status == H5D_SPACE_STATUS_NOT_ALLOCATED)
    return;
  const uint64_t bytes = shape_bytes(dataset);
  const uint64_t most = max_decoded_bytes(dataset);
  if (bytes > most)
    throw InputError(path, "dataset " + name,
                     "its shape claims " + std::to_string(bytes) + " bytes, but it stores only " +
                         std::to_string(H5Dget_storage_size(dataset)) + " (at most " +
                         std::to_string(most) + " decoded): the header is damaged");
}

std::vector<std::string> group_members(hid_t location, const std::string& group) {
  std::vector<std::string> names;
  if (H5Lexists(location, group.c_str(), H5P_DEFAULT) <= 0) return names;
  Handle g(H5Gopen2(location, group.c_str(), H5P_DEFAULT), H5Gclose);
  if (!g.valid()) return names;
  auto collect = [](hid_t, const char* name, const H5L_info_t*, void* data) -> herr_t {
    static_cast<std::vector<std::string>*>(data)->push_back(name);
    return 0;
  };
  if (H5Literate(g, H5_INDEX_CRT_ORDER, H5_ITER_INC, nullptr, collect, &names) < 0) {
    names.clear();
    H5Literate(g, H5_INDEX_NAME, H5_ITER_INC, nullptr, collect, &names);
  }
  return names;
}

bool write_string_attribute(hid_t object, const std::string& name, const std::string& value) {
  Handle type(H5Tcopy(H5T_C_S1), H5Tclose);
  H5Tset_size(type, value.empty() ? 1 : value.size());
  H5Tset_strpad(type, H5T_STR_NULLPAD);
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  Handle attribute(H5Acreate2(object, name.c_str(), type, space, H5P_DEFAULT, H5P_DEFAULT),
                   H5Aclose);
  return attribute.valid() && H5Awrite(attribute, type, value.c_str()) >= 0;
}

bool read_string_attribute(hid_t object, const std::string& name, std::string& value) {
  if (H5Aexists(object, name.c_str()) <= 0) return false;
  Handle attribute(H5Aopen(object, name.c_str(), H5P_DEFAULT), H5Aclose);
  Handle type(H5Aget_type(attribute), H5Tclose);
  if (!type.valid() || H5Tget_class(type) != H5T_STRING) return false;
  // One string only: an array attribute would be read past the buffer.
  Handle space(H5Aget_space(attribute), H5Sclose);
  if (!space.valid() || H5Sget_simple_extent_npoints(space) != 1) return false;
  if (H5Tis_variable_str(type) > 0) {
    // h5py's default for a Python str: HDF5 allocates the string, H5Dvlen_reclaim frees it.
    Handle memory(H5Tcopy(H5T_C_S1), H5Tclose);
    H5Tset_size(memory, H5T_VARIABLE);
    H5Tset_cset(memory, H5Tget_cset(type));
    char* text = nullptr;
    if (H5Aread(attribute, memory, &text) < 0) return false;
    value = text ? text : "";
    H5Dvlen_reclaim(memory, space, H5P_DEFAULT, &text);
    return true;
  }
  const size_t size = H5Tget_size(type);
  std::string buffer(size, '\0');
  if (H5Aread(attribute, type, buffer.data()) < 0) return false;
  value = buffer.substr(0, buffer.find('\0'));
  return true;
}

}  // namespace linebake::h5
